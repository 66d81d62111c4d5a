"""/flex/shape serialized in place (flex_model.ros.conversions.ShapeMarkers.serialized):
the bytes the model node publishes are the MarkerArray rclpy would send for the same
stamp and centre lines (every field equal after deserializing; only CDR padding bytes,
which rclpy leaves unset, may differ), for planar and 3-D lines and any link count."""
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import MarkerArray

from flex_model.ros.conversions import ShapeMarkers


@pytest.mark.parametrize("links, points, dim", [(2, 15, 3), (3, 7, 2), (1, 2, 3)])
def test_serialized_shape_is_the_message_rclpy_sends(links, points, dim):
    rng = np.random.default_rng(links * 100 + points)
    shapes_msg = ShapeMarkers(links, points, "robot1/base_link")
    for _ in range(4):  # the template is patched again and again
        shapes = [rng.normal(size=(points, dim)) for _ in range(links)]
        t = float(rng.uniform(0.0, 1e5))
        raw = shapes_msg.serialized(t, shapes)
        ref = serialize_message(shapes_msg.update(t, shapes))
        assert len(raw) == len(ref)
        got = deserialize_message(raw, MarkerArray)
        assert got == deserialize_message(ref, MarkerArray)
        m = got.markers[-1]  # the last chord: first and last point of the last line
        assert (m.points[1].x, m.points[1].y) == (shapes[-1][-1, 0], shapes[-1][-1, 1])
        sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (sec, nsec)
