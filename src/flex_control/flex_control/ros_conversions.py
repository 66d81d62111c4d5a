"""Message <-> array conversions of the controller node, with the input checks.

Every function raises ``ValueError`` naming the message field, the value and what is
allowed; the node logs the message and drops the input, so nothing malformed reaches the
controller. rclpy delivers a JointState whose arrays have mismatched lengths as it is, so
lengths and finiteness are checked here.
"""
from __future__ import annotations

from array import array

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flex_model.ros.conversions import finite_field
from flex_model.ros.conversions import trajectory_from_msg  # noqa: F401 (the node's import)


def joint_state_arrays(msg: JointState, joint_names) -> tuple[np.ndarray, np.ndarray | None]:
    """(positions, velocities) of ``joint_names`` (rad, rad/s) from a JointState; the
    velocities are None if the message has none (an empty ``velocity``)."""
    names = list(msg.name)
    n = len(names)
    for field in ("position", "velocity"):
        got = len(getattr(msg, field))
        if got != n and not (field == "velocity" and got == 0):
            raise ValueError(f"JointState.{field}: got {got} values for {n} names; expected "
                             f"one per name" + (" (or none)" if field == "velocity" else ""))
    try:
        idx = [names.index(j) for j in joint_names]
    except ValueError:
        missing = [j for j in joint_names if j not in names]
        raise ValueError(f"JointState.name: got {names}; expected to contain "
                         f"{list(joint_names)} (missing {missing})") from None
    pos = finite_field("JointState.position", np.asarray(msg.position, float)[idx])
    if not len(msg.velocity):
        return pos, None
    vel = finite_field("JointState.velocity", np.asarray(msg.velocity, float)[idx])
    return pos, vel


def stamp_seconds(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def deflection_array(msg: JointState, n: int) -> np.ndarray:
    """Link tip deflections (m) of links 1..n from the model's /flex/deflections
    JointState: the positions named ``link<i>/tip_deflection`` (the message also carries
    ``link<i>/tip_rotation``, and the rates as velocities)."""
    names = list(msg.name)
    if len(msg.position) != len(names):
        raise ValueError(f"deflections.position: got {len(msg.position)} values for "
                         f"{len(names)} names; expected one per name")
    want = [f"link{i + 1}/tip_deflection" for i in range(n)]
    missing = [w for w in want if w not in names]
    if missing:
        raise ValueError(f"deflections.name: got {names}; expected to contain {want} "
                         f"(missing {missing})")
    return finite_field("deflections.position",
                        np.asarray(msg.position, float)[[names.index(w) for w in want]])


def commands_msg(tau, msg: Float64MultiArray | None = None) -> Float64MultiArray:
    """Joint torques (N m) as the effort controller's Float64MultiArray (joint order),
    written into ``msg`` if given (float64[] takes an array.array('d') as it is)."""
    msg = Float64MultiArray() if msg is None else msg
    msg.data = array("d", np.asarray(tau, dtype=float).tobytes())
    return msg
