"""What a fresh clone compiles: numba compile CPU time per function (issue 43, fast feedback).

Compiles into an empty temporary cache (NUMBA_CACHE_DIR) in one process and prints, per
compiled function, the CPU seconds of its own compilation (exclusive) and with the functions
it compiled on the way (inclusive), and how many times it was compiled (x2: two numba
types), from numba's ``numba:compile`` events.

    python bench/bench_compile.py                  # the in-loop kernels (compile_ahead)
    python bench/bench_compile.py --opt 1          # the same at LLVM -O1 (make demo, tests)
    python bench/bench_compile.py --demo           # the whole twin demo (ROS; 15 s task)
    python bench/bench_compile.py --opt 1 --entry fixed   # one entry point of the tests
        # (fixed: a fixed-step simulate, full Newton; simplified: second order, simplified
        # Newton; exact: exact kinematics; replay: the diagnosis replay loops; planner:
        # the planner's loop; spatial: the spatial loop; several: --entry fixed,exact)
    FLEX_TWIN_COMPILE_LOG=/tmp/log make test   # (an empty folder) then:
    python bench/bench_compile.py --log /tmp/log   # the suite's compiles, per process, and
        # what more than one process compiled (the same function and numba types)
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections import Counter

ARM, PERIOD = "thesis_example1_motors", 1.0 / 500.0   # flex_twin.ros_twin_demo's


def _listen(rows: list) -> None:
    """Record (exclusive, inclusive CPU s, name) of every compilation into ``rows``."""
    from numba.core import event

    stack = []

    class Timer(event.Listener):
        def on_start(self, ev):
            stack.append([time.process_time(), 0.0])

        def on_end(self, ev):
            t0, inner = stack.pop()
            dt = time.process_time() - t0
            if stack:
                stack[-1][1] += dt
            f = ev.data["dispatcher"].py_func
            rows.append((dt - inner, dt, f"{f.__module__}.{f.__qualname__}"))

    event.register("numba:compile", Timer())


def _fixed(kinematics="small_deflection", newton="full") -> None:
    """A fixed-step simulate of 10 steps (bench/one_loop_runs.py's section E arm)."""
    import numpy as np
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.simulate import JointPD, Pulse, simulate
    model = FlexArmModel(load_arm("thesis_three_link", 4).with_kinematics(kinematics))
    th0 = np.radians([-20.0, 20.0, -20.0])
    simulate(model, model.q_from_joint_angles(th0), t_final=0.01, sample_period=0.005,
             method="fixed", dt=1e-3, newton=newton,
             pd=JointPD(np.full(3, 5e3), np.full(3, 250.0), th0),
             pulses=[Pulse(0.001, 0.002, (1000.0, 0.0, 0.0))])


def _replay() -> None:
    """The diagnosis replay loops, as test/numba_warmup.py compiles them."""
    import tempfile
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
    import numba_warmup
    with tempfile.TemporaryDirectory() as tmp:
        numba_warmup.replay_loops(Path(tmp))


def _planner() -> None:
    """The planner's loop (flex_planner.nominal_input) on a held pose."""
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_planner import SECTION_F_WAYPOINTS, plan
    model = FlexArmModel(load_arm("thesis_example1"))
    plan(model, [SECTION_F_WAYPOINTS[1]] * 2, [0.0, 0.1], sample_period=0.01)


def _spatial() -> None:
    import numpy as np
    from flex_model.spatial.dynamics import SpatialArmModel
    from flex_model.spatial.integrate import simulate_fixed_compiled
    from flex_model.spatial.loader import load_spatial_arm
    model = SpatialArmModel(load_spatial_arm("seed000_real_arm_3d"))
    z = np.zeros(model.nq)
    simulate_fixed_compiled(model, z, z, 1e-3, 2)


def _compile_ahead() -> None:
    from flex_model import control_loop
    control_loop.compile_ahead(ARM, PERIOD)


ENTRIES = {"compile_ahead": _compile_ahead, "fixed": _fixed,
           "simplified": lambda: _fixed("second_order", "simplified"),
           "exact": lambda: _fixed("exact"), "replay": _replay, "planner": _planner,
           "spatial": _spatial}


def _run(demo: bool, entries=("compile_ahead",)) -> None:
    from flex_model import control_loop
    if not demo:
        for name in entries:
            ENTRIES[name]()
        return

    class Done:   # compile_ahead already ran, in this process (one process to time)
        stdout = None

        def wait(self):
            return 0

        def poll(self):
            return 0

    def inline(arm, period, law="eq95"):
        control_loop.compile_ahead(arm, period, law)
        return Done()

    control_loop.compile_ahead_in_background = inline
    from flex_twin import ros_twin_demo
    with tempfile.TemporaryDirectory() as out:
        ros_twin_demo.run(os.path.join(out, "demo"))


def summarize(folder: str, top: int) -> None:
    """Print the compile CPU of a test session's processes (FLEX_TWIN_COMPILE_LOG, conftest.py)
    and the compilations done by more than one of them (same function, same numba types)."""
    from pathlib import Path
    rows = [line.rstrip("\n").split("\t") for f in sorted(Path(folder).glob("*.tsv"))
            for line in f.open()]
    per_pid, seen = Counter(), {}
    for pid, worker, w0, w1, own, incl, name, sig in rows:
        per_pid[f"{pid} (worker {worker})"] += float(own)
        seen.setdefault((name, sig), []).append((pid, float(own), float(w0), float(w1)))
    print(f"{len(rows)} compilations, {sum(per_pid.values()):.1f} CPU-s compiling")
    for who, cpu in per_pid.most_common():
        print(f"  process {who}: {cpu:.1f} CPU-s")
    dup = [(sum(o for _, o, _, _ in v) - max(o for _, o, _, _ in v), k, v)
           for k, v in seen.items() if len({p for p, *_ in v}) > 1]
    print(f"compiled by more than one process: {len(dup)} (function, types), "
          f"{sum(d[0] for d in dup):.1f} CPU-s beyond the first")
    for extra, (name, _), v in sorted(dup, reverse=True)[:top]:
        overlap = "overlapping" if max(w0 for *_, w0, _ in v) < min(w1 for *_, w1 in v) \
            else "one after the other"
        print(f"{extra:10.2f}  {name} x{len(v)} ({overlap})")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--opt", type=int, choices=(0, 1, 2, 3), default=3,
                   help="NUMBA_OPT (LLVM optimization level; numba's default 3)")
    p.add_argument("--demo", action="store_true", help="the whole twin demo (needs ROS)")
    p.add_argument("--entry", default="compile_ahead",
                   help=f"entry points, comma-separated: {', '.join(ENTRIES)}")
    p.add_argument("--top", type=int, default=25, help="functions to list")
    p.add_argument("--log", metavar="FOLDER",
                   help="sum up a test session's FLEX_TWIN_COMPILE_LOG folder instead")
    args = p.parse_args(argv)
    if args.log:
        summarize(args.log, args.top)
        return 0
    entries = args.entry.split(",")
    for name in entries:
        if name not in ENTRIES:
            p.error(f"--entry: got {name!r}; expected one of {', '.join(ENTRIES)}")
    if "numba" in sys.modules:
        raise SystemExit("bench_compile: numba imported before its environment was set")
    with tempfile.TemporaryDirectory() as cache:
        os.environ.update(NUMBA_OPT=str(args.opt), NUMBA_CACHE_DIR=cache)
        rows = []
        _listen(rows)
        c0 = time.process_time()
        _run(args.demo, entries)
        total = time.process_time() - c0
    own = [r for r in rows if not r[2].startswith("numba.")]
    times = Counter(r[2] for r in own)
    print(f"{'demo' if args.demo else args.entry} at -O{args.opt}: {total:.1f} CPU-s, "
          f"of which compiling {sum(r[0] for r in rows):.1f} ({len(own)} compilations of "
          f"{len(times)} project functions, {len(rows) - len(own)} numba internals)")
    print(f"{'own CPU s':>10s} {'with callees':>12s}  function")
    for excl, incl, name in sorted(own, reverse=True)[:args.top]:
        again = "" if times[name] == 1 else f" (x{times[name]})"
        print(f"{excl:10.2f} {incl:12.2f}  {name}{again}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
