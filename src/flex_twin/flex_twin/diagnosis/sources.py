"""A recording from any source a user has: a CSV file (:mod:`.recording`) or a rosbag2
directory / .mcap file of the suite's topics (:mod:`.ros_recording`, needs rclpy)."""
from __future__ import annotations

from pathlib import Path

from .recording import Recording, RecordingError, load_csv
from .ros_recording import load_bag


def load_recording(path, n_joints: int, link_topic: str | None = None,
                   gravity=None) -> Recording:
    """A CSV file, or a rosbag2 directory / .mcap file (needs rclpy) whose link-side
    encoders are on ``link_topic`` (default ``ros_recording.LINK_TOPIC``); ``gravity``
    (the arm's) turns a bag's base-frame tip pose into the plane (a bag with one and no
    ``gravity`` is refused: the plane is not known)."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or directory")
    if path.is_dir() or path.suffix == ".mcap":
        return load_bag(path, n_joints, link_topic, gravity)
    return load_csv(path, n_joints)
