"""Messages of the model node built from core outputs (standard message types only)."""
from __future__ import annotations

import math
from array import array

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped, PoseWithCovarianceStamped, TransformStamped
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import ColorRGBA, Header
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from .cdr_messages import CdrTemplate
from ..trajectory import JointTrajectoryData


def stamp(t: float) -> Time:
    """builtin_interfaces/Time of a simulation time t (s), rounded to the nanosecond."""
    return set_time(Time(), t)


def set_time(msg: Time, t: float) -> Time:
    """Write the simulation time t (s) into a Time message in place."""
    msg.sec, msg.nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return msg


def _doubles(values) -> array:
    """A float64[] field value: array.array('d') is stored as is by the message setters."""
    return array("d", np.asarray(values, dtype=float).tobytes())


def joint_state(t, names, position, velocity, effort) -> JointState:
    msg = JointState(name=list(names))
    fill_joint_state(msg, t, position, velocity, effort)
    return msg


def fill_joint_state(msg: JointState, t, position, velocity, effort=None) -> JointState:
    """Update a JointState in place (its names stay)."""
    set_time(msg.header.stamp, t)
    msg.position, msg.velocity = _doubles(position), _doubles(velocity)
    if effort is not None:
        msg.effort = _doubles(effort)
    return msg


def deflection_names(link_names) -> list[str]:
    return [f"{n}/{q}" for n in link_names for q in ("tip_deflection", "tip_rotation")]


def deflection_state(t, link_names, deflection, rotation, d_rate, r_rate) -> JointState:
    """link<i>/tip_deflection (m) and link<i>/tip_rotation (rad) with their rates."""
    msg = JointState(name=deflection_names(link_names))
    fill_deflection_state(msg, t, deflection, rotation, d_rate, r_rate)
    return msg


def fill_deflection_state(msg: JointState, t, deflection, rotation, d_rate, r_rate):
    """Update a deflection JointState in place: per link (deflection, rotation)."""
    return fill_joint_state(msg, t, np.column_stack([deflection, rotation]).ravel(),
                            np.column_stack([d_rate, r_rate]).ravel())


def fill_tip_pose(msg: PoseStamped, t, x, y, phi, rotation=None) -> PoseStamped:
    """The tip pose (x, y, phi in the arm's plane) in place; with ``rotation``
    (flex_model.urdf.plane_rotation) in the base frame (:func:`tip_pose_values`)."""
    set_time(msg.header.stamp, t)
    p, o = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z, o.x, o.y, o.z, o.w = tip_pose_values(x, y, phi, rotation)
    return msg


class ShapeMarkers:
    """The /flex/shape MarkerArray, built once and updated in place: the deflected centre
    line of every link (LINE_STRIP) and its rigid chord (thin); ``labels`` name the
    links' namespaces (default link1, link2, ...), ``widths`` the line's and chord's (m)."""

    def __init__(self, n_links: int, points: int, frame="base_link", ns="flex",
                 labels=None, widths=(0.02, 0.005)):
        self.msg = MarkerArray()
        labels = labels or [f"link{i + 1}" for i in range(n_links)]
        for i in range(n_links):
            for k, (n, width, color) in enumerate(
                    ((points, widths[0], ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0)),
                     (2, widths[1], ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.8)))):
                m = Marker(header=Header(frame_id=frame), ns=f"{ns}/{labels[i]}",
                           id=2 * i + k, type=Marker.LINE_STRIP, action=Marker.ADD,
                           color=color)
                m.scale.x = width
                m.pose.orientation.w = 1.0
                m.points = [Point() for _ in range(n)]
                self.msg.markers.append(m)

        # the serialized message (flex_model.ros.cdr_messages), built here: at 10,000 points
        # per link it takes about 1 s, which a realtime tick must not wait for
        self._raw = CdrTemplate(
            self.msg, [f"markers[{j}].header.stamp" for j in range(len(self.msg.markers))],
            [f"markers[{j}].points" for j in range(len(self.msg.markers))])

    def update(self, t, shapes) -> MarkerArray:
        """Stamp t and the centre lines ``shapes`` (list of (points, 2) or (points, 3)
        arrays, m); the message object, the reference of :meth:`serialized` (which the
        node publishes)."""
        markers = self.msg.markers
        for i, line in enumerate(shapes):
            pts3 = np.column_stack([line, np.zeros(len(line))]) if line.shape[1] == 2 \
                else line
            xyz = pts3.tolist()
            for m, pts in ((markers[2 * i], xyz), (markers[2 * i + 1], (xyz[0], xyz[-1]))):
                set_time(m.header.stamp, t)
                for p, (x, y, z) in zip(m.points, pts):
                    p.x, p.y, p.z = x, y, z
        return self.msg

    def serialized(self, t, shapes) -> bytes:
        """The message of :meth:`update` (stamp t, centre lines ``shapes``) serialized
        (CDR), written straight into a serialized copy of the message
        (:class:`flex_model.ros.cdr_messages.CdrTemplate`): what rclpy would send, without
        converting 4 markers of Point objects on every publication (0.2-0.3 ms of the 1 ms
        realtime tick; Publisher.publish takes bytes)."""
        values = []
        for line in shapes:  # per link: the centre line, then its chord (first, last)
            pts3 = np.zeros((len(line), 3))
            pts3[:, :line.shape[1]] = line
            values += [pts3.ravel(), pts3[0], pts3[-1]]
        return self._raw.fill(t, np.concatenate(values))


def joint_state_cdr(names, n_values: int, effort: bool = True) -> CdrTemplate:
    """A sensor_msgs/JointState of ``names`` as a CDR template: stamp; position, velocity
    (``n_values`` each) and, with ``effort``, effort, in that order (the bytes of
    :func:`fill_joint_state`)."""
    zeros = [0.0] * n_values
    msg = JointState(name=list(names), position=zeros, velocity=zeros,
                     effort=zeros if effort else [])
    return CdrTemplate(msg, ["header.stamp"],
                       ["position", "velocity"] + (["effort"] if effort else []))


def tip_pose_cdr(frame: str) -> CdrTemplate:
    """The tip pose (PoseStamped in ``frame``) as a CDR template: stamp; position x, y, z
    and orientation x, y, z, w, in that order (:func:`tip_pose_values`)."""
    return CdrTemplate(PoseStamped(header=Header(frame_id=frame)), ["header.stamp"],
                       ["pose.position.x", "pose.position.y", "pose.position.z",
                        "pose.orientation.x", "pose.orientation.y", "pose.orientation.z",
                        "pose.orientation.w"])


def tip_pose_values(x, y, phi, rotation=None) -> list[float]:
    """The values of :func:`tip_pose_cdr` (what :func:`fill_tip_pose` writes): the tip at
    (x, y) turned by phi about z in the arm's plane; with ``rotation`` (R, the plane's axes
    in the base frame, flex_model.urdf.plane_rotation) in the base frame: position
    R (x, y, 0), orientation R Rz(phi) (the quaternion product q_R q_z(phi))."""
    s, c = math.sin(phi / 2), math.cos(phi / 2)
    if rotation is None:
        return [float(x), float(y), 0.0, 0.0, 0.0, s, c]
    from ..urdf import quaternion_from_matrix
    r = rotation
    qx, qy, qz, qw = quaternion_from_matrix(r)
    return [float(r[0, 0] * x + r[0, 1] * y), float(r[1, 0] * x + r[1, 1] * y),
            float(r[2, 0] * x + r[2, 1] * y),
            qx * c + qy * s, qy * c - qx * s, qz * c + qw * s, qw * c - qz * s]


def tip_pose_cov_cdr(frame: str) -> CdrTemplate:
    """The estimated tip pose (PoseWithCovarianceStamped in ``frame``) as a CDR template:
    stamp; position x, y, z, orientation x, y, z, w (:func:`tip_pose_values`), then the
    6 x 6 covariance row-major (x, y, z, rotations about x, y, z)."""
    return CdrTemplate(PoseWithCovarianceStamped(header=Header(frame_id=frame)),
                       ["header.stamp"], ["pose.pose.position", "pose.pose.orientation",
                                          "pose.covariance"])


def planar_tip_covariance(cov_xy_phi, rotation=None) -> np.ndarray:
    """The 6 x 6 pose covariance (x, y, z, rx, ry, rz) of a planar tip whose (x, y, phi)
    in the arm's plane has the 3 x 3 covariance ``cov_xy_phi``; with ``rotation`` (R,
    flex_model.urdf.plane_rotation) in the base frame: the position block R C R^T, the
    rotation about the plane's normal R e_z (first-order, as the mean in
    :func:`tip_pose_values`)."""
    c = np.asarray(cov_xy_phi, float)
    t = np.zeros((6, 3))  # d(position, rotation vector) / d(x, y, phi)
    t[0, 0] = t[1, 1] = t[5, 2] = 1.0
    if rotation is not None:
        r = np.asarray(rotation, float)
        t[:3, :2], t[3:, 2] = r[:, :2], r[:, 2]
    return t @ c @ t.T


class PlanarOutputs:
    """What the model node publishes of a planar arm's (q, v), simulated or estimated:
    flex/deflections' names and values (per link deflection, rotation, then their rates,
    as :meth:`flex_model.stepper.Stepper.deflections`, index and selection matrices built
    once), the tip angle phi (:meth:`FlexArmModel.tip_pose`) and, for an estimate, the
    tip pose turned by the plane's ``rotation`` into the base frame (tip_pose_values) with
    its 6 x 6 covariance from the state's (first order: J P_qq J^T, J the tip Jacobian and
    phi's row, planar_tip_covariance)."""

    def __init__(self, model, rotation):
        n = model.n_links
        self.model, self.nq, self.rotation = model, model.nq, rotation
        self.names = deflection_names([lk.name for lk in model.arm.links])
        self.tip_index = np.array([model.tip_deflection_index(i) for i in range(n)])
        self.tip_rotation = model.tip_rotation_matrix()
        self.last_alpha = model.alpha_index(n - 1)
        self.values = np.empty(4 * n)
        self.jacobian = np.empty((3, model.nq))

    def deflections(self, q, v) -> np.ndarray:
        n, out, r = len(self.tip_index), self.values, self.tip_rotation
        out[0:2 * n:2], out[1:2 * n:2] = q[self.tip_index], r @ q
        out[2 * n::2], out[2 * n + 1::2] = v[self.tip_index], r @ v
        return out

    def phi(self, q) -> float:
        return float(q[self.last_alpha] + self.tip_rotation[-1] @ q)

    def tip_values(self, q, state_cov, out) -> np.ndarray:
        """``out`` (43) = position, orientation (x, y, z, w), covariance row-major."""
        x, y = self.model.link_origins(q)[-1]
        j = self.jacobian
        j[:2], j[2] = self.model.tip_jacobian(q), self.tip_rotation[-1]
        j[2, self.last_alpha] += 1.0
        out[:7] = tip_pose_values(x, y, self.phi(q), self.rotation)
        out[7:] = planar_tip_covariance(j @ state_cov[:self.nq, :self.nq] @ j.T,
                                        self.rotation).ravel()
        return out


def clock_cdr() -> CdrTemplate:
    """rosgraph_msgs/Clock as a CDR template (its one stamp)."""
    from rosgraph_msgs.msg import Clock
    return CdrTemplate(Clock(), ["clock"])


def imu_cdr(frame: str) -> CdrTemplate:
    """The tip accelerometer (Imu in ``frame``) as a CDR template: stamp; orientation x,
    y, z, w, angular velocity z, linear acceleration x, y, in that order
    (:func:`imu_values`)."""
    return CdrTemplate(Imu(header=Header(frame_id=frame)), ["header.stamp"],
                       ["orientation", "angular_velocity.z", "linear_acceleration.x",
                        "linear_acceleration.y"])


def imu_values(specific_force, angular_rate, orientation) -> list[float]:
    """The values of :func:`imu_cdr`: what :func:`imu` writes with an orientation."""
    fx, fy = (float(v) for v in specific_force)
    return [*(float(v) for v in orientation), float(angular_rate), fx, fy]


class Transforms:
    """geometry_msgs/TransformStamped of a list of ``flex_model.urdf.Transform`` (same
    parent/child order every time), built once and updated in place (/tf, /tf_static)."""

    def __init__(self, transforms):
        self.msgs = []
        for tr in transforms:
            m = TransformStamped()
            m.header.frame_id, m.child_frame_id = tr.parent, tr.child
            self.msgs.append(m)
        self.update(0.0, transforms)

    def update(self, t, transforms) -> list:
        for m, tr in zip(self.msgs, transforms):
            set_time(m.header.stamp, t)
            tl, r = m.transform.translation, m.transform.rotation
            tl.x, tl.y, tl.z = (float(v) for v in tr.translation)
            r.x, r.y, r.z, r.w = (float(v) for v in tr.rotation)
        return self.msgs


def transforms_cdr(tf_type, pairs) -> CdrTemplate:
    """A ``tf_type`` (tf2_msgs/TFMessage) of TransformStamped with these (parent, child)
    frames as a CDR template: every stamp; per transform translation x, y, z and rotation
    x, y, z, w, in order (the rows of flex_model.urdf.ArmTransforms.values)."""
    msgs = []
    for parent, child in pairs:
        m = TransformStamped(child_frame_id=child)
        m.header.frame_id = parent
        m.transform.rotation.w = 1.0
        msgs.append(m)
    return CdrTemplate(tf_type(transforms=msgs),
                       [f"transforms[{k}].header.stamp" for k in range(len(msgs))],
                       ["transforms"])


def imu(t, specific_force, angular_rate, phi, frame="tip", orientation=None) -> Imu:
    """Tip accelerometer: linear_acceleration = specific force in the tip frame (m/s^2),
    angular_velocity about its z (the joint axes); orientation: the quaternion (x, y, z,
    w) of the tip frame in the base frame, default a rotation phi about z."""
    msg = Imu(header=Header(stamp=stamp(t), frame_id=frame))
    msg.linear_acceleration.x, msg.linear_acceleration.y = (float(v) for v in specific_force)
    msg.angular_velocity.z = float(angular_rate)
    if orientation is None:
        msg.orientation.z, msg.orientation.w = math.sin(phi / 2), math.cos(phi / 2)
    else:
        o = msg.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in orientation)
    return msg


def finite_array(values, length: int, what: str, hint: str = "") -> np.ndarray:
    """Checked copy of a received array: raises ValueError naming the problem (``hint``
    says what the values are, e.g. the joint order)."""
    arr = np.asarray(values, dtype=float)
    if arr.shape != (length,):
        raise ValueError(f"{what}: got {arr.size} values; expected {length}"
                         + (f" ({hint})" if hint else ""))
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what}: got non-finite values {_plain(arr)}; expected finite "
                         "numbers")
    return arr


def _plain(arr) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in np.asarray(arr, float).tolist()) + "]"


def within_limit(arr, limit: float, what: str, names, parameter: str, unit: str) -> None:
    """Raise ValueError naming the first value beyond +-limit (a plausibility limit)."""
    bad = np.flatnonzero(np.abs(arr) > limit)
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"{what}: {names[k]} = {arr[k]:.6g} {unit} is beyond {parameter} = "
                         f"{limit:.6g} {unit} (a plausibility limit; raise {parameter} if "
                         "intended)")


_LEVELS = {"ok": DiagnosticStatus.OK, "warn": DiagnosticStatus.WARN,
           "error": DiagnosticStatus.ERROR}


def check_payload(items, limit) -> None:
    """Each (value, name, unit) of a payload (its mass, then an inertia) >= 0 and within
    its plausibility limit (``limit("max_payload_mass")``, ``limit("max_payload_inertia")``);
    else ValueError naming it."""
    for (value, name, unit), key in zip(items, ("max_payload_mass", "max_payload_inertia")):
        if value < 0:
            raise ValueError(f"payload {name}: got {value:.6g} {unit}; expected >= 0")
        if value > limit(key):
            raise ValueError(f"payload {name}: got {value:.6g} {unit}; expected at most "
                             f"{key} = {limit(key):.6g} {unit} (a plausibility limit; "
                             f"raise {key} if intended)")


def diagnostic_status(name: str, hardware_id: str, level: str, message: str,
                      **values) -> DiagnosticStatus:
    """A diagnostic_msgs/DiagnosticStatus (level ok | warn | error) with string values."""
    return DiagnosticStatus(level=_LEVELS[level], name=name, message=message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


def finite_field(field: str, values) -> np.ndarray:
    """``values`` as a float array, or a ValueError naming the first non-finite entry."""
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise ValueError(f"{field}[{bad}]: got {float(arr[bad]):.6g}; expected finite values")
    return arr


def trajectory_from_msg(msg: JointTrajectory, joint_names) -> JointTrajectoryData:
    """A JointTrajectory as :class:`JointTrajectoryData` in the order of ``joint_names``.

    The message's joint names must be the same set (any order); empty velocities,
    accelerations or efforts of a point mean zeros; times must increase.
    """
    names = list(msg.joint_names)
    want = list(joint_names)
    if sorted(names) != sorted(want) or len(set(names)) != len(names):
        raise ValueError(f"JointTrajectory.joint_names: got {names}; expected the joints "
                         f"{want} (any order)")
    if not msg.points:
        raise ValueError("JointTrajectory.points: got 0 points; expected at least 1")
    idx = [names.index(j) for j in want]
    n = len(want)
    fast = _trajectory_arrays(msg.points, n, idx)
    if fast is not None:  # well-formed: vectorized (point by point, 7501 points took 1.6 s)
        t, arrays = fast
    else:  # find and name the first problem, point by point
        t, arrays = _trajectory_arrays_checked(msg.points, n, idx)
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"JointTrajectory.points.time_from_start: got {t.tolist()} s; "
                         "expected strictly increasing times")
    return JointTrajectoryData(joint_names=want, t=t, positions=arrays["positions"],
                               velocities=arrays["velocities"],
                               accelerations=arrays["accelerations"], efforts=arrays["effort"])


_FIELDS = ("positions", "velocities", "accelerations", "effort")


def _trajectory_arrays(points, n: int, idx):
    """(times, {field: (points, n) array in joint order}) of well-formed points (every
    field with n values, or, except positions, none on every point; all finite), else
    None."""
    m = len(points)
    t = np.fromiter((p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                     for p in points), float, m)
    arrays = {}
    for field in _FIELDS:
        values = [getattr(p, field) for p in points]
        lengths = set(map(len, values))
        if lengths == {n}:
            arr = np.frombuffer(b"".join(array("d", v) if not isinstance(v, array) else v
                                         for v in values), dtype=float).reshape(m, n)[:, idx]
            if not np.all(np.isfinite(arr)):
                return None
        elif lengths == {0} and field != "positions":
            arr = np.zeros((m, n))
        else:
            return None
        arrays[field] = np.ascontiguousarray(arr)
    return t, arrays


def _trajectory_arrays_checked(points, n: int, idx):
    """As :func:`_trajectory_arrays`, point by point, raising ValueError at the first
    problem (its point, field and index)."""
    t = np.empty(len(points))
    arrays = {k: np.zeros((len(points), n)) for k in _FIELDS}
    for k, p in enumerate(points):
        t[k] = p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
        for field in arrays:
            values = getattr(p, field)
            if field == "positions" and len(values) != n:
                raise ValueError(f"JointTrajectory.points[{k}].positions: got {len(values)} "
                                 f"values; expected {n}")
            if len(values) not in (0, n):
                raise ValueError(f"JointTrajectory.points[{k}].{field}: got {len(values)} "
                                 f"values; expected 0 or {n}")
            if len(values):
                arrays[field][k] = finite_field(f"JointTrajectory.points[{k}].{field}",
                                                np.asarray(values, float)[idx])
    return t, arrays
