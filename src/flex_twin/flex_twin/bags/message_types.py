"""Message types of the bags: the standard packages accepted, their classes and the rosbags
Jazzy typestore (definitions, RIHS01 hashes), the QoS and CDR conversions.

``rosidl_runtime_py`` is not in the pip wheels, so :func:`get_message` resolves
``pkg/msg/Name`` with importlib as it does. rclpy is imported lazily (inside functions).
"""
from __future__ import annotations

import importlib
from functools import lru_cache

STANDARD_PACKAGES = ("sensor_msgs", "std_msgs", "geometry_msgs", "trajectory_msgs",
                     "nav_msgs", "visualization_msgs", "rosgraph_msgs", "std_srvs",
                     "builtin_interfaces")


class BagError(ValueError):
    """A bag that cannot be written or read as asked (the message names path/topic/value)."""


def get_message(type_str: str):
    """The rclpy message class of ``pkg/msg/Name`` (a standard package only)."""
    parts = type_str.split("/")
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise BagError(f"message type {type_str!r}: expected 'package/msg/Name'")
    if parts[0] not in STANDARD_PACKAGES:
        raise BagError(f"message type {type_str!r}: package {parts[0]!r} is not one of the "
                       f"standard packages {', '.join(STANDARD_PACKAGES)}")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError):
        raise BagError(f"message type {type_str!r}: not found in the installed "
                       f"{parts[0]} package") from None


def type_string(msg_or_class) -> str:
    """``pkg/msg/Name`` of an rclpy message object or class."""
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


@lru_cache(maxsize=1)
def jazzy_typestore():
    """The rosbags typestore of ROS 2 Jazzy (message definitions and type hashes)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def qos_to_rosbags(qos):
    """rclpy ``QoSProfile`` -> ``rosbags.interfaces.Qos`` (same enum values as rmw)."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    def t(duration):
        ns = int(duration.nanoseconds)
        return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)
    return Qos(QosHistory(int(qos.history)), int(qos.depth),
               QosReliability(int(qos.reliability)), QosDurability(int(qos.durability)),
               t(qos.deadline), t(qos.lifespan), QosLiveliness(int(qos.liveliness)),
               t(qos.liveliness_lease_duration), bool(qos.avoid_ros_namespace_conventions))


def exact_cdr(data: bytes, type_str: str) -> bytes:
    """``data`` cut to the end of its CDR payload.

    ``rclpy.serialization.serialize_message`` (rmw_fastrtps) returns a buffer of the
    *estimated* size, which exceeds the payload (by 8 bytes for a JointState with empty
    sequences; the surplus bytes are uninitialised). rclpy and rosbag2 ignore the surplus,
    the ``rosbags`` reader rejects more than 3 trailing bytes. The payload end is found by
    decoding with the rosbags Jazzy typestore, which also checks the bytes fit the type.
    """
    msgdef = jazzy_typestore().get_msgdef(type_str)
    decode = msgdef.deserialize_cdr_le if data[1] else msgdef.deserialize_cdr_be
    try:
        _, end = decode(memoryview(data)[4:], 0, msgdef.cls, jazzy_typestore())
    except Exception as exc:  # struct.error, ValueError, ... : bytes do not fit the type
        raise BagError(f"CDR bytes do not decode as {type_str}: {exc}") from exc
    return data[:4 + end]
