"""The twin demo's arm, control rate and law, and its in-loop kernels compiled ahead.

``python -m flex_twin.twin_demo_ahead`` compiles them into numba's cache
(flex_model.control_loop.compile_ahead). ``make demo`` starts it from the bootstrap once
the wheels are in (``scripts/bootstrap.sh --demo``, before the project's packages are
installed: it runs from src/ on PYTHONPATH and needs numba, numpy and PyYAML only), so the
compile runs beside the rest of the bootstrap and the demo's start; the demo's own
compile-ahead process then waits for it (a lock) and loads what it compiled
(docs/development.md, first ``make demo``). Imports no ROS, unlike flex_twin.ros_twin_demo.
"""
from __future__ import annotations

ARM = "thesis_example1_motors"
#: control and integration rate (Hz) of the model's loop
RATE = 500.0
#: the in-loop law by module (the entry point ``eq95``: the same factory; the entry points
#: exist only once the packages are installed)
LAW = "flex_control.in_loop:eq95"


def main() -> None:
    """Compile (or load) the kernels; prints this process's wall and CPU seconds (in the
    bootstrap's .venv/twin-demo-ahead.log)."""
    import time
    wall0 = time.time()
    from flex_model.control_loop import compile_ahead
    compile_ahead(ARM, 1.0 / RATE, LAW)
    print(f"twin demo kernels compiled ahead: {time.time() - wall0:.1f} s wall, "
          f"{time.process_time():.1f} CPU-s (started {wall0:.1f})")


if __name__ == "__main__":
    main()
