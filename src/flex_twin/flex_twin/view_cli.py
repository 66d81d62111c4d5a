"""``flex-twin view``: a planar arm or scenario simulated by the core and streamed live to
Foxglove over WebSocket (flex_model.live_view), at real time or a rate factor; no ROS.

An arm is released from rest at ``--joint-angles-deg`` with a zero joint command (it
swings under gravity) and runs until ``--duration`` or Ctrl-C; a scenario is simulated
first (its inputs, as ``flex-twin simulate``) and then played back. Open it in Foxglove:
Open connection > Foxglove WebSocket > ws://localhost:8765.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from flex_model.command import stop_on_signals


#: after the last frame, the server stays up this long (s) so that it reaches the clients
LINGER = 0.5

VIEW_DESCRIPTION = (
    "Simulate a planar arm or scenario with the core and stream it live to Foxglove "
    "(joint states, tip pose, deflected shape, frames) at real time or --rate-factor. An arm "
    "swings from rest under a zero joint command until --duration or Ctrl-C; a scenario is "
    "simulated first, then played back. In Foxglove: Open connection > Foxglove WebSocket > "
    "ws://localhost:8765 (or the --port given).")


class ArmSource:
    """The arm under a held zero command, integrated on demand (flex_model.stepper)."""

    def __init__(self, model, q0):
        from flex_model.stepper import Stepper
        self.stepper, self.duration = Stepper(model, q0), math.inf

    def warm_up(self) -> None:
        """Load (or compile) the integrator before the clock starts: two steps of a copy."""
        from flex_model.stepper import Stepper
        st = self.stepper
        Stepper(st.model, st.q).advance(2 * st.max_step)

    def at(self, t: float):
        """(t, q, joint angles, rates, torques) at simulation time ``t`` (s)."""
        st = self.stepper
        st.advance(t - st.t)
        return (st.t, st.q, *st.joint_state())


class PlaybackSource:
    """A finished simulation (flex_model.result.SimulationResult), by sample."""

    def __init__(self, result):
        self.result, self.duration = result, float(result.t[-1])

    def warm_up(self) -> None:
        """Nothing to load: the run is done."""

    def at(self, t: float):
        """The last sample at or before ``t`` (s)."""
        r = self.result
        k = max(0, int(np.searchsorted(r.t, t, side="right")) - 1)
        return (float(r.t[k]), r.q[k], r.model.joint_angles(r.q[k]), r.model.G @ r.v[k],
                r.tau[k])


def stream(view, source, duration: float, rate_factor: float, publish_rate: float,
           progress, clock=time.monotonic, sleep=time.sleep,
           stopped=lambda: False) -> tuple[float, float]:
    """Publish ``source`` on ``view`` at ``publish_rate`` (Hz, wall clock): frame k at
    simulation time k rate_factor / publish_rate (the last at ``duration``, s), sent at
    wall time k / publish_rate; returns (simulated, wall) seconds. A source slower than
    that runs behind (frames come late, none is skipped). ``stopped()`` true: stop after
    the frame."""
    period, frame = 1.0 / publish_rate, 0
    start = clock()
    view.epoch_ns = time.time_ns()  # stamps: now + simulation time
    while True:
        target = min(duration, frame * rate_factor * period)
        t, q, angles, rates, torques = source.at(target)
        view.publish(t, q, angles, rates, torques)
        progress(t)
        if target >= duration or stopped():
            return t, clock() - start
        frame += 1
        sleep(max(0.0, start + frame * period - clock()))


def _source(args):
    """(label, source) of the positional argument: a scenario or an arm."""
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.scenario import load_scenario, scenario_names
    from flex_model.spatial.description import is_spatial_arm

    from flex_model.command import Progress
    ref = args.arm_or_scenario
    spatial = ValueError(f"{ref}: a spatial arm; flex-twin view streams planar arms only")
    if is_spatial_arm(ref):
        raise spatial
    if ref in scenario_names() + scenario_names(spatial=True) or _is_scenario_file(ref):
        sc = load_scenario(ref, args.vars_per_link)
        if sc.spatial:
            raise spatial
        if args.joint_angles_deg is not None:
            raise ValueError("--joint-angles-deg: for an arm; a scenario has its own start")
        if args.duration is not None:
            sc.duration = args.duration
        res = sc.run(progress=Progress("view: simulating first"), advise=False)
        return f"scenario {sc.name} on arm {sc.arm.name}", PlaybackSource(res)
    model = FlexArmModel(load_arm(ref, args.vars_per_link))
    n = model.n_links
    angles = args.joint_angles_deg or [0.0]
    if len(angles) not in (1, n):
        raise ValueError(f"--joint-angles-deg: got {len(angles)} values; expected 1 or {n}")
    theta = np.radians(np.broadcast_to(np.asarray(angles, float), (n,)))
    return (f"arm {model.arm.name} released from rest, zero joint command",
            ArmSource(model, model.q_from_joint_angles(theta)))


def _is_scenario_file(ref: str) -> bool:
    """A YAML file with a top-level ``arm`` (scenarios name their arm; arms do not)."""
    from pathlib import Path
    if Path(ref).suffix not in (".yaml", ".yml") or not Path(ref).is_file():
        return False
    from flex_model.config import read_yaml
    data = read_yaml(ref)
    return isinstance(data, dict) and "arm" in data


def _progress(label: str, duration: float):
    """cli.Progress for a finite run; else a line every 10 s of wall time."""
    from flex_model.command import Progress
    if math.isfinite(duration):
        bar = Progress(label)
        return lambda t: bar(t, duration)
    start, marks = time.monotonic(), [10.0]

    def line(t):
        wall = time.monotonic() - start
        if wall >= marks[0]:
            marks[0] += 10.0
            print(f"{label}: t = {t:.1f} s simulated, {wall:.0f} s wall", file=sys.stderr,
                  flush=True)
    return line


def cmd_view(args) -> int:
    from flex_model.live_view import LiveView
    for name in ("rate_factor", "publish_rate"):
        if not getattr(args, name) > 0:
            raise ValueError(f"--{name.replace('_', '-')}: got {getattr(args, name)}; "
                             "expected a value > 0")
    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration: got {args.duration}; expected a time > 0 s")
    label, source = _source(args)
    source.warm_up()
    linger = 0.0
    model = source.stepper.model if isinstance(source, ArmSource) else source.result.model
    duration = args.duration if args.duration is not None else source.duration
    view = LiveView(model, port=args.port, host=args.host, points_per_link=args.shape_points)
    print(f"flex-twin view: {label}; serving {view.url} (Foxglove: Open connection > "
          f"Foxglove WebSocket); Ctrl-C stops", file=sys.stderr, flush=True)
    with stop_on_signals() as stop:
        try:
            if args.wait:
                print("flex-twin view: waiting for a client to subscribe", file=sys.stderr,
                      flush=True)
                while not (view.wait_for_subscriber(0.1) or stop.is_set()):
                    pass
            if not stop.is_set():
                simulated, wall = stream(view, source, duration, args.rate_factor,
                                         args.publish_rate, _progress("view", duration),
                                         stopped=stop.is_set)
                end = " (stopped)" if stop.is_set() else ""
                print(("\n" if end and sys.stderr.isatty() else "") + f"flex-twin view: "
                      f"streamed {simulated:g} s simulated in {wall:.2f} s wall{end}",
                      file=sys.stderr)
                linger = LINGER
        finally:
            view.close(linger)
    return 0


def add_view_parser(sub) -> None:
    from flex_model.live_view import DEFAULT_HOST, DEFAULT_PORT
    sp = sub.add_parser("view", help="stream an arm or scenario live to Foxglove "
                        "(WebSocket, no ROS)", description=VIEW_DESCRIPTION)
    sp.add_argument("arm_or_scenario", help="planar arm or scenario (preset name or YAML)")
    sp.add_argument("--port", type=int, default=DEFAULT_PORT,
                    help=f"WebSocket port (default {DEFAULT_PORT}; 0: any free one)")
    sp.add_argument("--host", default=DEFAULT_HOST,
                    help=f"address to bind (default {DEFAULT_HOST}: this machine only)")
    sp.add_argument("--duration", type=float, default=None, help="simulated time, s "
                    "(default: an arm until Ctrl-C, a scenario its own)")
    sp.add_argument("--rate-factor", type=float, default=1.0,
                    help="simulated seconds per wall second (default 1: real time)")
    sp.add_argument("--publish-rate", type=float, default=30.0,
                    help="messages per channel per wall second, Hz")
    sp.add_argument("--shape-points", type=int, default=15, help="points per link drawn")
    sp.add_argument("--joint-angles-deg", type=float, nargs="+", default=None,
                    help="an arm's initial joint angles, deg (one per joint, or one for all)")
    sp.add_argument("--vars-per-link", type=int, default=None, metavar="N")
    sp.add_argument("--wait", action="store_true",
                    help="start the clock when a client subscribes")
    sp.set_defaults(func=cmd_view)
