"""ObserverNode: the model node in observer mode (issue 45): the twin follows a real arm.

Started as the model node with ``mode: observer`` (``model_node`` dispatches here, as it
dispatches a spatial arm to :mod:`flex_model.ros.spatial_node`; ``flex-twin observe``;
``flex-twin up`` with ``mode: observer`` in the flex_model section). It does not integrate
open loop: every sample of the real arm's joint_states runs one step of the state estimator
(:class:`flex_model.estimation.Estimator`, a Kalman filter on the flexible model) inside
the subscription callback, and the estimate goes out at once from messages serialized at
start (flex_model.ros.cdr_messages: only stamps and numbers are written per sample). No timer
is in the hot path (one 1 s wall-clock timer publishes the filter's health).

A planar arm (FlexArmModel) or a spatial one (issue 25: SpatialArmModel, loaded as the
spatial node loads it; flex/deflections then in its layout, tip v, w and twist per flexible
link, :mod:`flex_model.ros.spatial`). Topic names are relative (a namespace moves them);
/diagnostics stays global.

Subscriptions (reliable, depth ``queue_depth``: a burst of samples is queued, not lost):
    joint_states (``input_topic``)  sensor_msgs/JointState  the real arm: position (joint
                        angles, rad) and velocity (rates) feed the joint_angle and
                        joint_rate measurements, effort (joint torques, or motor voltages
                        when the arm has a motor effect) is the model's input with
                        ``input: effort``; joints matched by name (any order, any extras)
    flex/gauges (``gauge_topic``)   sensor_msgs/JointState  the measurements that are not
                        on joint_states (tip deflection w<i>, tip acceleration ...): name =
                        their names in ``measure``, position = the readings; each is paired
                        with the joint_states sample of its stamp (within half a sample
                        period; send it before that sample); a sample without one is
                        corrected with the other readings (NaN: not measured)
    effort_controller/commands      std_msgs/Float64MultiArray  the input with ``input:
                        command`` (held until the next one)
Publications (stamps: the joint_states sample's):
    flex/estimate/joint_states  sensor_msgs/JointState  estimated joint angles, rates, the
                        input used
    flex/deflections    sensor_msgs/JointState  as the simulating model node:
                        link<i>/tip_deflection (m), tip_rotation (rad) and their rates
                        (spatial: as the spatial node)
    flex/estimate/tip_pose  geometry_msgs/PoseWithCovarianceStamped  the tip in
                        ``frame_id`` (z up, as flex/tip_pose of the model node) with the
                        6 x 6 covariance (x, y, z, rotation about x, y, z; planar: the
                        plane's (x, y, phi) block turned into the base frame); while
                        subscribed
    /diagnostics        diagnostic_msgs/DiagnosticArray  every second (wall time): the
                        filter's health over the last ``nis_window`` samples (NIS mean,
                        fraction inside the chi-square 95 % bound, samples, dropped, late,
                        predicted-over gaps, the adapted parameters' current values and
                        stds: param/<name>, param_std/<name>); OK when consistent, WARN
                        when the NIS mean leaves its 99 % band or fewer than 90 % lie inside
                        the 95 % bound, or when inputs were dropped since the last report

Bad messages (wrong lengths, unknown joint names, non-finite values, a stamp not after the
previous sample's: late) are dropped with the reason logged at most once a second per
reason (main.ReasonLog) and counted; the node keeps running. A gap of k > 1 sample
periods is predicted over (k - 1 steps without measurements, counted as missed); a gap
longer than ``max_gap`` restarts the filter at the next sample's joint angles, as the
first sample after configure or activate does (at rest, the links in static balance:
:func:`flex_model.estimation.recording.initial_q`, as ``estimate_recording`` starts).

Parameters (:data:`PARAMETERS`): arm, vars_per_link, kinematics (as the model node), mode
(observer), measure (comma-separated names, as ``flex-twin estimate --measure``), measure_std
(per measurement, or one for all; 0: the estimator's default), input (effort | command),
adapt (comma-separated parameters adapted online), adapt_horizon and adapt_block (the
horizon fit of the joint frictions, EstimatorSettings), sample_period (s: the arm's sample period,
the filter's step), initial_joint_angles_deg, input_topic, gauge_topic, queue_depth,
max_gap, nis_window, frame_id, frame_prefix, parameter_services, qos_event_warnings.
The plumbing is the model node's (main.ModelPlumbing: lifecycle, the shared parameters,
joint_states and flex/deflections as CDR templates, /diagnostics every second; the outputs
of a state, conversions.PlanarOutputs and spatial.SpatialOutputs): configure builds the
filter, activate takes samples, deactivate refuses them (counted as dropped), cleanup
releases the filter. Its own: the filter, the gauges, the health, the tip pose with its
covariance.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import replace

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.lifecycle import LifecycleNode
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from . import conversions as conv
from . import spatial as sr
from .. import urdf
from .cdr_messages import read_joint_state, read_joint_state_names
from ..dynamics import FlexArmModel
from ..estimation.measurements import DEFAULT_STD, NAME_PATTERN
from ..estimation.recording import initial_q
from .main import (FLOAT_MAX, INT_MAX, MODEL_PARAMETERS, ModelPlumbing, Param, ParameterError,
                   ReasonLog, fmt, lean_node, planar_arm_parameter, positive,
                   read_parameters, run_node)


def _names(v):
    return None if all(s.strip() for s in v.split(",")) else \
        "comma-separated names without empty ones (e.g. q1,v1)"


#: the observer's parameters (name, default, description, changeable at run time, check)
PARAMETERS = (
    Param("arm", "thesis_example1_motors", "arm preset name or arm YAML path: the model of "
          "the real arm", check=lambda v: None if v else "a preset name or a YAML path"),
    MODEL_PARAMETERS["vars_per_link"], MODEL_PARAMETERS["kinematics"],
    Param("mode", "observer", "observer (this node); realtime | lockstep simulate "
          "(flex_model.ros.model_node)", check=lambda v: None if v == "observer" else
          "observer (realtime and lockstep are the simulating model node's)"),
    Param("measure", "q", "measurements, comma-separated, as flex-twin estimate --measure "
          "(q: every joint angle; q1, v1: joint 1's angle, rate, from joint_states; the "
          "others, e.g. w1 link 1's tip deflection, from gauge_topic in this order)",
          check=_names),
    Param("measure_std", [0.0], "noise standard deviation per measurement, or one for all "
          "(SI units; 0: the estimator's default)",
          check=lambda v: None if v and all(x >= 0 for x in v) else "numbers >= 0"),
    Param("input", "effort", "effort: joint_states' effort is the model's input (torques, "
          "or voltages of motor joints); command: the last effort_controller/commands",
          check=lambda v: None if v in ("effort", "command") else "effort or command"),
    Param("adapt", "", "parameters adapted online, comma-separated (e.g. "
          "coulomb_friction:0,payload_mass; empty: none)"),
    Param("adapt_horizon", 0.0, "s: fit the adapted joint frictions by least squares on "
          "the momentum balance of the last adapt_horizon s (0: random walks; "
          "EstimatorSettings.adapt_horizon)",
          check=lambda v: None if v >= 0 else "a number >= 0 s (0: off)"),
    Param("adapt_block", 0.05, "s: the horizon fit's block, one fit per block "
          "(EstimatorSettings.adapt_block)", check=lambda v: None if v > 0 else
          "a number > 0 s, at most adapt_horizon"),
    Param("sample_period", 1e-3, "the real arm's sample period (s): one filter step per "
          "joint_states sample", check=lambda v: None if 0 < v <= 0.1 else "in (0, 0.1] s"),
    Param("initial_joint_angles_deg", [0.0], "the filter's initial joint angles (deg), "
          "until the first sample (one per joint or one for all)"),
    Param("input_topic", "joint_states", "the real arm's sensor_msgs/JointState",
          check=lambda v: None if v else "a topic name"),
    Param("gauge_topic", "flex/gauges", "sensor_msgs/JointState of the measurements not on "
          "joint_states (name: their names in measure; position: the readings), paired with "
          "the joint_states sample of the same stamp",
          check=lambda v: None if v else "a topic name"),
    Param("queue_depth", 1000, "depth of the reliable input subscriptions (samples queued "
          "while a step runs)", check=lambda v: None if v >= 1 else "an integer >= 1"),
    Param("max_gap", 0.1, "s: a longer gap between samples restarts the filter at the next "
          "sample; shorter ones are predicted over", check=positive),
    Param("nis_window", 1000, "samples of the NIS statistics on /diagnostics",
          check=lambda v: None if v >= 10 else "an integer >= 10"),
    *(MODEL_PARAMETERS[k] for k in ("frame_id", "frame_prefix", "parameter_services",
                                    "qos_event_warnings")),
)

#: wall time (s) one joint_states callback goes on taking the samples queued behind its
#: own (no executor wait set rebuilt per sample) before it returns to the executor
DRAIN_SLICE = 0.02

RANGES = {"vars_per_link": (0, INT_MAX, 2), "sample_period": (0.0, 0.1),
          "queue_depth": (1, INT_MAX), "max_gap": (0.0, FLOAT_MAX),
          "nis_window": (10, INT_MAX), "adapt_horizon": (0.0, FLOAT_MAX),
          "adapt_block": (0.0, FLOAT_MAX)}


#: measurement names (the recording channels of flex-twin estimate --measure: q<i>, v<i>,
#: w<i> tip deflection, tip_x, tip_y): prefix -> (kind, default std, SI)
NAMED_KINDS = {k: (kind, DEFAULT_STD[kind]) for k, kind in (
    ("q", "joint_angle"), ("v", "joint_rate"), ("m", "motor_angle"), ("w", "tip_deflection"))}
#: names without an index: (kind, component, default std)
NAMED_COMPONENTS = {name: (kind, c, DEFAULT_STD[kind]) for name, kind, c in (
    ("ax", "tip_acceleration", 0), ("ay", "tip_acceleration", 1), ("tip_x", "tip_position", 0),
    ("tip_y", "tip_position", 1), ("tip_z", "tip_position", 2))}


#: measurement kinds read by an arm file's sensor kind (flex_model.sensors)
SENSOR_KINDS = {"joint_angle": "joint_encoder", "motor_angle": "motor_encoder",
                "tip_deflection": "tip_deflection"}


def _with_sensor(m, arm):
    """``m`` with the noise, resolution and delay of the arm's sensor of its kind and
    joint or link (flex_model.sensors), where the arm file has one with noise or a
    resolution."""
    targets = list(arm.joint_names) if m.kind != "tip_deflection" else [
        lk.name for lk in arm.links]
    for s in getattr(arm, "sensors", ()):
        if s.kind == SENSOR_KINDS.get(m.kind) and s.target == targets[m.index] and \
                (s.noise > 0 or s.resolution > 0):
            return replace(m, std=s.noise, quantum=s.resolution, delay=s.delay)
    return m


#: the component of a spatial tip deflection's suffix (w<i>y, w<i>z, w<i>t; w<i>: y)
_SUFFIX = {"": 0, "y": 0, "z": 1, "t": 2}


def measurements_named(model, names, stds=(0.0,)) -> list:
    """The Measurements of ``names`` (the recording channels' names): q<i>, v<i>, m<i>
    joint i's angle, rate, motor angle (q, v alone: every joint's), w<i> link i's tip
    deflection (spatial: w<i>y, w<i>z its v, w, w<i>t its twist), ax, ay the tip's
    specific force, tip_x, tip_y, tip_z its position.
    Noise, resolution (the quantum) and delay are those of the arm file's sensor of that
    joint or link where it has one, else the default of the kind (:data:`NAMED_KINDS`);
    ``stds`` one per measurement or one for all overrides the std (0: keep it);
    ValueError naming a bad one."""
    from ..estimation import Measurement
    out, count = [], model.n_links
    for name in names:
        if name in NAMED_COMPONENTS:
            kind, comp, std = NAMED_COMPONENTS[name]
            out.append(Measurement(name=name, kind=kind, component=comp, std=std))
            continue
        match = NAME_PATTERN.match(name)
        if not match or not (match[2] or name in ("q", "v")) or \
                (match[3] and match[1] != "w"):
            raise ValueError(f"got {name!r}; expected q<i>, v<i>, m<i> (joint i), w<i> "
                             "(link i; spatial also w<i>y, w<i>z, w<i>t), q, v (every "
                             "joint), ax, ay, tip_x, tip_y or tip_z")
        kind, std = NAMED_KINDS[match[1]]
        idx = [int(match[2]) - 1] if match[2] else range(count)
        if not all(0 <= i < count for i in idx):
            raise ValueError(f"got {name!r}; the arm has {count} joints and links (1..{count})")
        out += [_with_sensor(Measurement(
            name=f"{match[1]}{i + 1}{match[3]}", kind=kind, index=i, std=std,
            component=_SUFFIX[match[3]]), model.arm) for i in idx]
    if len(stds) not in (1, len(out)):
        raise ValueError(f"measure_std: got {fmt(stds)}; expected one per measurement "
                         f"({len(out)}) or one for all")
    return [replace(m, std=float(std)) if std > 0 else m
            for m, std in zip(out, np.broadcast_to(np.asarray(stds, float), (len(out),)))]


class NisWindow:
    """The normalized innovation squared of the last ``size`` samples: mean (per
    measured component, so 1 when consistent) and the fraction inside the chi-square 95 %
    bound of its degrees of freedom (the bound per dof count cached)."""

    def __init__(self, size: int):
        self.nis, self.dof = deque(maxlen=size), deque(maxlen=size)
        self.inside = deque(maxlen=size)
        self._bound = {}

    def add(self, nis: float, dof: int) -> None:
        if dof <= 0 or not math.isfinite(nis):
            return
        bound = self._bound.get(dof)
        if bound is None:
            from scipy.stats import chi2
            bound = self._bound[dof] = float(chi2.ppf(0.95, dof))
        self.nis.append(nis)
        self.dof.append(dof)
        self.inside.append(nis <= bound)

    def summary(self) -> dict:
        """nis_mean (NIS / dof, 1 if consistent), nis_95_fraction, samples, and the 99 %
        band of nis_mean for this many dof (chi-square of the summed dof / dof)."""
        from scipy.stats import chi2
        n, dof = len(self.nis), float(sum(self.dof))
        if n == 0:
            return {"samples": 0}
        lo, hi = chi2.ppf([0.005, 0.995], dof) / dof
        return {"samples": n, "nis_mean": float(sum(self.nis)) / dof,
                "nis_95_fraction": float(sum(self.inside)) / n,
                "nis_band": (float(lo), float(hi))}


class ObserverNode(ModelPlumbing, LifecycleNode):
    """The flexible model as an observer of a real arm (module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("flex_model", **kwargs)
        self._start_lifecycle(PARAMETERS, None)

    # ------------------------------------------------------------- lifecycle
    def _configure(self) -> None:
        from ..estimation import Estimator
        p = self.p = read_parameters(self, PARAMETERS, RANGES)
        self.model, self.outputs = self._model(p)
        n = self.model.n_links
        self.names = list(self.model.arm.joint_names)
        self.measurements, self.sources = self._measurements(p)
        self.n_gauges = sum(1 for s in self.sources if s[0] == "gauge")
        settings = self._settings(p)
        try:
            self.estimator = Estimator(self.model, self.measurements, settings)
        except ValueError as exc:
            raise ParameterError(f"parameter measure/adapt: {exc}") from None
        angles = p["initial_joint_angles_deg"]
        if len(angles) not in (1, n):
            raise ParameterError(f"parameter initial_joint_angles_deg: got {fmt(angles)}; "
                                 f"expected {n} angles (deg) or one for every joint")
        self.theta0 = np.radians(np.broadcast_to(np.asarray(angles, float), (n,)))
        self._reset_filter(self.theta0)
        self.cdr_tip = conv.tip_pose_cov_cdr(p["frame_prefix"] + p["frame_id"])
        self._js_values = np.empty(3 * n)
        self._tip_values = np.empty(7 + 36)
        self._y = np.full(len(self.measurements), np.nan)
        self._index = {}  # tuple of joint_states names -> their positions in joint order
        self.u = np.zeros(n)
        self.gauges = deque(maxlen=int(p["queue_depth"]))  # (stamp, values in gauge order)
        self._gauge_index = {}  # serialized gauge names -> (positions, their gauge slots)
        self.counts = dict.fromkeys(("samples", "dropped", "late", "missed", "restarts",
                                     "gauge_dropped", "gauge_late"), 0)
        self.reported = dict(self.counts)
        self.nis = NisWindow(int(p["nis_window"]))
        self.drops = ReasonLog(self)
        qos = QoSProfile(depth=int(p["queue_depth"]), history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)
        self._state_publishers("flex/estimate/joint_states", self.outputs.names, qos)
        self.pub_tip = self.create_publisher(PoseWithCovarianceStamped,
                                             "flex/estimate/tip_pose", qos)
        self._diagnostics()
        # raw: the samples are read from their bytes (cdr_messages.read_joint_state)
        self.sub_js = self.create_subscription(JointState, p["input_topic"],
                                               self.on_joint_state, qos, raw=True)
        self.sub_gauge = None
        if any(s[0] == "gauge" for s in self.sources):
            self.sub_gauge = self.create_subscription(JointState, p["gauge_topic"],
                                                      self.on_gauge, qos, raw=True)
        self._needed = {"position": True, "effort": p["input"] == "effort",
                        "velocity": any(s[0] == "velocity" for s in self.sources)}
        if p["input"] == "command":
            self.create_subscription(Float64MultiArray, "effort_controller/commands",
                                     self.on_command, qos)
        lean_node(self, p["parameter_services"], p["qos_event_warnings"])
        self.get_logger().info(
            f"observer of arm {self.model.arm.name} ({self.model.nq} coordinates), measuring "
            f"{', '.join(m.name for m in self.measurements)} every "
            f"{p['sample_period'] * 1e3:g} ms from {self.resolve_topic_name(p['input_topic'])}"
            f", input {p['input']}" + (f", adapting {p['adapt']}" if p["adapt"] else "") +
            (f" (horizon fit {p['adapt_horizon']:g} s)" if p["adapt_horizon"] else ""))

    @staticmethod
    def _model(p):
        """(model, outputs) of the ``arm`` parameter: a planar FlexArmModel, or a spatial
        arm's SpatialArmModel (issue 25; loaded as the spatial node loads it)."""
        from ..spatial.description import is_spatial_arm
        if is_spatial_arm(p["arm"]):
            from ..spatial.dynamics import SpatialArmModel
            from .spatial_node import load_arm_parameter
            model = SpatialArmModel(load_arm_parameter(p["arm"], False))
            return model, sr.SpatialOutputs(model)
        model = FlexArmModel(planar_arm_parameter(p))
        return model, conv.PlanarOutputs(model, urdf.plane_rotation(model.gravity))

    def _cleanup(self) -> None:
        self.estimator = self.model = None

    def _measurements(self, p):
        """The estimator's measurements named by ``measure`` (:func:`measurements_named`)
        and where each comes from: ("position" | "velocity", joint index) on
        joint_states, else ("gauge", k), the k-th value on gauge_topic."""
        names = [s.strip() for s in p["measure"].split(",")]
        try:
            found = measurements_named(self.model, names, p["measure_std"])
        except ValueError as exc:
            raise ParameterError(f"parameter measure: {exc}") from None
        sources, k = [], 0
        for m in found:
            if m.kind in ("joint_angle", "joint_rate"):
                sources.append(("position" if m.kind == "joint_angle" else "velocity",
                                m.index))
            else:
                sources.append(("gauge", k))
                k += 1
        return found, sources

    @staticmethod
    def _settings(p):
        """EstimatorSettings of the parameters (its checks: ParameterError naming the
        field, e.g. ``parameter adapt_block: got 5; expected ...``)."""
        from ..estimation import EstimatorSettings
        adapt = tuple(s.strip() for s in p["adapt"].split(",") if s.strip())
        try:
            return EstimatorSettings(sample_period=p["sample_period"], adapt=adapt,
                                     adapt_horizon=p["adapt_horizon"],
                                     adapt_block=p["adapt_block"])
        except ValueError as exc:
            raise ParameterError(f"parameter {exc}") from None

    def _reset_filter(self, theta) -> None:
        """The filter at rest at the joint angles ``theta`` (rad), links straight."""
        self.estimator.reset(self.estimator.plant.q_from_joint_angles(theta),
                             np.zeros(self.model.nq))
        self.last_t = None

    def _activate(self) -> None:
        self.get_logger().info("observing: each joint_states sample is one filter step")

    def _deactivate(self) -> None:
        self.last_t = None  # the next sample after activate: predicted from there on

    # ------------------------------------------------------------- inputs
    def _drop(self, topic: str, why: str, counter: str = "dropped") -> None:
        self.counts[counter] += 1
        self.drops.warning(f"dropped {topic}: {why}")

    def _joint_index(self, key, data) -> np.ndarray:
        """Positions of the model's joints in a sample's name list (cached per serialized
        list ``key``); ValueError naming a missing joint."""
        idx = self._index.get(key)
        if idx is None:
            names = read_joint_state_names(data)
            missing = [j for j in self.names if j not in names]
            if missing:
                raise ValueError(f"name: got {names}; the joints {missing} of the arm "
                                 "are missing")
            idx = self._index[key] = np.array([names.index(j) for j in self.names])
        return idx

    def on_joint_state(self, data: bytes) -> None:
        """Samples of the real arm (serialized: a raw subscription, no message objects):
        this one and those queued behind it, each one filter step with its estimate
        published, for up to DRAIN_SLICE s; then back to the executor."""
        self.on_sample(data)
        sub, gauge = self.sub_js, self.sub_gauge
        end = time.monotonic() + DRAIN_SLICE
        with sub.handle:
            while self.active and time.monotonic() < end:
                while gauge is not None:  # the gauge readings sent before the sample
                    with gauge.handle:
                        got = gauge.handle.take_message(gauge.msg_type, True)
                    if got is None:
                        break
                    self.on_gauge(got[0])
                got = sub.handle.take_message(sub.msg_type, True)
                if got is None:
                    return
                self.on_sample(got[0])

    def on_sample(self, data: bytes) -> None:
        """One sample: checked (else dropped with the reason), gaps predicted over, one
        filter step, the estimate published."""
        topic = self.p["input_topic"]
        if not self.active:
            return self._drop(topic, self._inactive())
        try:
            t, key, count, *fields = read_joint_state(data)
            position, velocity, u = self._sample_arrays(fields, count,
                                                        self._joint_index(key, data))
        except ValueError as exc:
            return self._drop(topic, str(exc))
        period, start = self.p["sample_period"], self.last_t is None
        if not start:
            gap = t - self.last_t
            if gap <= 0.5 * period:
                return self._drop(topic, f"stamp {t:.9f} s is not after the previous "
                                  f"sample's {self.last_t:.9f} s (late or repeated)", "late")
            k = int(round(gap / period))
            if gap > self.p["max_gap"]:
                start = True
                self.counts["restarts"] += 1
                self.drops.warning(f"{topic}: a gap of {gap:.4g} s (max_gap "
                                   f"{self.p['max_gap']:g} s): filter restarted at the "
                                   "sample's joint angles")
            elif k > 1:  # missed samples: predicted over, no measurement
                self.counts["missed"] += k - 1
                nan = np.full(len(self.measurements), np.nan)
                for _ in range(k - 1):
                    self.estimator.step(self.u, nan)
        if u is not None:
            self.u = u
        self.last_t = t
        self._step(t, position, velocity, start)

    def _sample_arrays(self, fields, count: int, idx):
        """(joint angles, rates or None, input or None) of a sample's (position, velocity,
        effort) of ``count`` names in joint order, each finite (ValueError naming the
        field)."""
        out = []
        for field, values in zip(("position", "velocity", "effort"), fields):
            needed = self._needed[field]
            if not needed:
                out.append(None)
                continue
            if len(values) != count:
                raise ValueError(f"{field}: got {len(values)} values for {count} names; "
                                 "expected one per name")
            arr = values[idx]
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{field}: got non-finite values {fmt(arr)}; expected "
                                 "finite numbers")
            out.append(arr)
        return out

    def on_gauge(self, data: bytes) -> None:
        """A gauge reading (serialized JointState), queued by its stamp for its sample."""
        try:
            t, key, count, position, _, _ = read_joint_state(data)
            idx, slots = self._gauge_slots(key, data)
            if len(position) != count:
                raise ValueError(f"position: got {len(position)} values for {count} names; "
                                 "expected one per name")
            values = np.full(self.n_gauges, np.nan)
            values[slots] = position[idx]
            if not np.all(np.isfinite(values[slots])):
                raise ValueError(f"position: got non-finite values {fmt(values)}")
        except ValueError as exc:
            return self._drop(self.p["gauge_topic"], str(exc), "gauge_dropped")
        self.gauges.append((t, values))

    def _gauge_slots(self, key, data):
        """(positions in the message, slots among the gauge measurements) of a gauge name
        list (cached); ValueError naming an unknown name."""
        found = self._gauge_index.get(key)
        if found is None:
            names = read_joint_state_names(data)
            order = [m.name for m, s in zip(self.measurements, self.sources)
                     if s[0] == "gauge"]
            unknown = [n for n in names if n not in order]
            if unknown:
                raise ValueError(f"name: got {unknown}; expected gauge measurements of "
                                 f"measure: {order}")
            found = self._gauge_index[key] = (np.arange(len(names)),
                                              np.array([order.index(n) for n in names]))
        return found

    def _gauge_at(self, t: float):
        """The gauge values stamped within half a sample period of ``t`` (older ones are
        dropped, counted as gauge_late: their sample has gone), or None."""
        half, q = 0.5 * self.p["sample_period"], self.gauges
        while q and q[0][0] < t - half:
            q.popleft()
            self.counts["gauge_late"] += 1
        if q and q[0][0] <= t + half:
            return q.popleft()[1]
        return None

    def on_command(self, msg: Float64MultiArray) -> None:
        try:
            self.u = conv.finite_array(msg.data, len(self.u), "command",
                                       f"one per joint: {', '.join(self.names)}")
        except ValueError as exc:
            self._drop("effort_controller/commands", str(exc))

    # ------------------------------------------------------------- the step
    def _step(self, t: float, position, velocity, start: bool = False) -> None:
        """One filter step with the sample's readings; at the ``start`` (the first sample
        after configure or activate, or after a gap beyond max_gap) the filter first
        restarts at rest at its joint angles, the links in static balance under its input
        (estimation.recording.initial_q: as estimate_recording starts)."""
        y = self._y
        gauge = self._gauge_at(t) if self.sub_gauge is not None else None
        for k, (field, i) in enumerate(self.sources):
            if field == "position":
                y[k] = position[i]
            elif field == "velocity":
                y[k] = velocity[i]
            else:
                y[k] = gauge[i] if gauge is not None else np.nan
        if start:
            self.estimator.reset(initial_q(self.estimator, y, self.u), t0=t)
        s = self._last_sample = self.estimator.step(self.u, y)
        self.counts["samples"] += 1
        self.nis.add(s.nis, s.nis_dof)
        self.publish(t, s)

    def publish(self, t: float, s) -> None:
        """The estimate of one sample as bytes: joint states, deflections, and the tip pose
        while someone subscribes (its Jacobian and covariance are the costly part, a
        third of the publication; get_subscription_count costs about 1 us)."""
        n = len(self.names)
        js = self._js_values
        js[:n], js[n:2 * n], js[2 * n:] = s.joint_angles, s.joint_rates, self.u[:n]
        self.pub_js.publish(self.cdr_js.fill(t, js))
        self.pub_defl.publish(self.cdr_defl.fill(t, self.outputs.deflections(s.q, s.v)))
        if not self.pub_tip.get_subscription_count():
            return
        tip = self.outputs.tip_values(s.q, s.state_cov, self._tip_values)
        self.pub_tip.publish(self.cdr_tip.fill(t, tip))

    # ------------------------------------------------------------- health
    def health(self):
        """(level, message, values) of the filter's health (the /diagnostics status)."""
        summary = self.nis.summary()
        new = {k: self.counts[k] - self.reported[k] for k in self.counts}
        self.reported = dict(self.counts)
        values = {k: v for k, v in self.counts.items()}
        level, why = "ok", []
        if summary["samples"]:
            lo, hi = summary["nis_band"]
            values.update(nis_mean=f"{summary['nis_mean']:.4g}",
                          nis_95_fraction=f"{summary['nis_95_fraction']:.4g}",
                          nis_window=summary["samples"])
            if not lo <= summary["nis_mean"] <= hi:
                why.append(f"NIS mean {summary['nis_mean']:.3g} outside its 99 % band "
                           f"[{lo:.3g}, {hi:.3g}]")
            if summary["nis_95_fraction"] < 0.9:
                why.append(f"only {summary['nis_95_fraction']:.1%} of the NIS inside the "
                           "95 % bound")
        dropped = new["dropped"] + new["late"] + new["gauge_dropped"]
        if dropped:
            why.append(f"{dropped} input(s) dropped in the last report period")
        if why:
            level = "warn"
        params = getattr(self._last_sample, "parameters", None) or {}
        values.update({f"param/{k}": f"{v:.6g}" for k, v in params.items()})
        stds = getattr(self._last_sample, "parameter_std", None) or {}
        values.update({f"param_std/{k}": f"{v:.3g}" for k, v in stds.items()})
        state = "observing" if self.active else "inactive"
        return level, (f"{state}: " + "; ".join(why) if why else
                       f"{state}: filter consistent"), values

    _last_sample = None

    def on_status(self) -> None:
        if not self.configured:
            return
        level, message, values = self.health()
        self.publish_diagnostic(conv.diagnostic_status(
            self.get_fully_qualified_name(), self.model.arm.name, level, message, **values))


def main(args=None) -> None:
    run_node(ObserverNode, args)


if __name__ == "__main__":
    main()
