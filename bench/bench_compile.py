"""What a fresh clone compiles: numba compile CPU time per function (issue 43, fast feedback).

Compiles into an empty temporary cache (NUMBA_CACHE_DIR) in one process and prints, per
compiled function, the CPU seconds of its own compilation (exclusive) and with the functions
it compiled on the way (inclusive), from numba's ``numba:compile`` events.

    python bench/bench_compile.py                  # the in-loop kernels (compile_ahead)
    python bench/bench_compile.py --opt 1          # the same at LLVM -O1 (make demo, tests)
    python bench/bench_compile.py --demo           # the whole twin demo (ROS; 15 s task)
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

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


def _run(demo: bool) -> None:
    from flex_model import control_loop
    if not demo:
        control_loop.compile_ahead(ARM, PERIOD)
        return

    class Done:   # compile_ahead already ran, in this process (one process to time)
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--opt", type=int, choices=(0, 1, 2, 3), default=3,
                   help="NUMBA_OPT (LLVM optimization level; numba's default 3)")
    p.add_argument("--demo", action="store_true", help="the whole twin demo (needs ROS)")
    p.add_argument("--top", type=int, default=25, help="functions to list")
    args = p.parse_args(argv)
    if "numba" in sys.modules:
        raise SystemExit("bench_compile: numba imported before its environment was set")
    with tempfile.TemporaryDirectory() as cache:
        os.environ.update(NUMBA_OPT=str(args.opt), NUMBA_CACHE_DIR=cache)
        rows = []
        _listen(rows)
        c0 = time.process_time()
        _run(args.demo)
        total = time.process_time() - c0
    own = [r for r in rows if not r[2].startswith("numba.")]
    print(f"{'demo' if args.demo else 'compile_ahead'} at -O{args.opt}: {total:.1f} CPU-s, "
          f"of which compiling {sum(r[0] for r in rows):.1f} ({len(own)} project functions, "
          f"{len(rows) - len(own)} numba internals)")
    print(f"{'own CPU s':>10s} {'with callees':>12s}  function")
    for excl, incl, name in sorted(own, reverse=True)[:args.top]:
        print(f"{excl:10.2f} {incl:12.2f}  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
