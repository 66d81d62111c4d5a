"""ControlLoop: the arm and an in-loop controller advanced together (ros2_control's update
loop: read the sensors, update the controller, write the command, integrate).

Every control ``period`` the controller (:mod:`flex_model.controller_interface`) reads the
sensed state of the arm, its command is held (zero-order hold) while the model integrates
the period in steps of at most the stepper's ``max_step``. No message crosses a process or
an executor inside the loop; the model node publishes the state at its own rates.

A controller whose ``compiled_law()`` returns a :class:`~flex_model.control_kernel.LinearLaw`
(flex_control's built-in laws) runs all the periods of one :meth:`ControlLoop.advance` in
one compiled call (:func:`flex_model.control_kernel.run_periods`), same results; any other
controller (or ``compiled=False``) is called from Python every period.
"""
from __future__ import annotations

import numpy as np

from .control_kernel import run_periods
from .controller_interface import SensedState
from .simulate import RUNAWAY, DIVERGENCE_LIMIT, diverged, newton_failed
from .stepper import Stepper


class ControlLoop:
    """A :class:`~flex_model.stepper.Stepper` driven by an in-loop controller."""

    def __init__(self, stepper: Stepper, controller, period: float, compiled: bool = True):
        if not period > 0:
            raise ValueError(f"control period: got {period!r}; expected > 0 s")
        self.stepper, self.controller, self.period = stepper, controller, float(period)
        self.compiled = bool(compiled)
        m = stepper.model
        self._G = np.ascontiguousarray(m.G, dtype=float)
        self._defl = np.array([m.tip_deflection_index(i) for i in range(m.n_links)],
                              dtype=np.int64)
        self.n_updates = 0
        self.t0 = 0.0  # the trajectory's start (simulation time, s)
        self.idle = False  # after drop_trajectory: zero command, no controller updates

    def set_trajectory(self, trajectory, start: float = 0.0) -> None:
        """Track ``trajectory`` (a JointTrajectoryData) from the simulation time ``start``:
        the controller sees the time since then."""
        self.controller.set_trajectory(trajectory)
        self.t0 = float(start)
        self.idle = False

    def drop_trajectory(self) -> None:
        """Forget the trajectory (a reset): command zero, without updating the controller,
        until the next :meth:`set_trajectory`."""
        self.idle, self.t0 = True, 0.0
        self.stepper.set_command(np.zeros(self.stepper.model.n_links))

    def sense(self) -> SensedState:
        """Joint angles and rates, link tip deflections and their rates, now."""
        q, v = self.stepper.q, self.stepper.v
        return SensedState(self._G @ q, self._G @ v, q[self._defl], v[self._defl])

    def update(self) -> np.ndarray:
        """One controller update at the current time; the command is held from now on."""
        st = self.stepper
        u = np.asarray(self.controller.update(st.t - self.t0, self.period, self.sense()),
                       float)
        if u.shape != (st.model.n_links,) or not np.all(np.isfinite(u)):
            raise ValueError(f"in-loop controller: got the command {u.tolist()}; expected "
                             f"{st.model.n_links} finite values")
        st.set_command(u)
        self.n_updates += 1
        return u

    def compiled_law(self):
        """The controller's LinearLaw for the compiled loop, or None (Python path)."""
        get = getattr(self.controller, "compiled_law", None) if self.compiled else None
        return get() if callable(get) else None

    def advance(self, n_periods: int = 1) -> None:
        """``n_periods`` control periods: update, then integrate one period, each."""
        n = int(n_periods)
        if self.idle and n > 0:  # the zero command of drop_trajectory, held
            self.stepper.advance(n * self.period)
            return
        while n > 0:
            law = self.compiled_law()
            if law is None:  # users' controllers; a built-in law before its first update
                self.update()
                self.stepper.advance(self.period)
                n -= 1
            else:
                self._run_compiled(law, n)
                n = 0

    def _run_compiled(self, law, n: int) -> None:
        st = self.stepper
        m = st.model
        status, done, t, x, a, abar, t_fail, x_fail = run_periods(
            st.t, st.x, st.a, st.abar, n, self.period, st.max_step, st.rho_inf, self.t0,
            self._G, self._defl, law.law, law.interpolation, law.times, law.reference,
            law.gains, law.feedforward, law.limits, 1e-10, DIVERGENCE_LIMIT, m.P, st.E)
        st.t, st.x, st.a, st.abar = t, x, a, abar
        self.n_updates += done + (status in (1, 2))
        if status == 3:
            raise ValueError(f"in-loop controller: got the command {x_fail.tolist()}; "
                             f"expected {m.n_links} finite values")
        if status == 1:
            raise diverged(m, t_fail, x_fail)
        if status == 2:
            raise newton_failed(
                t_fail, self.period / max(1, int(np.ceil(self.period / st.max_step - 1e-9))),
                RUNAWAY)


def compile_ahead(arm: str, period: float, law: str = "eq95", announce=None) -> None:
    """Compile the in-loop kernels for ``arm`` (a preset or file) and ``law`` into numba's
    on-disk cache: two periods of a held arm, nothing computed that is kept. One at a time
    per cache (a lock file beside it): one that finds another compiling waits for it and
    returns (make demo starts one during the bootstrap, the demo another). While it
    compiles the model's equations (the Stepper's consistent start, the kernels a planner
    shares) it holds a second lock (:func:`wait_for_shared_kernels`); ``announce()`` is
    called once it holds its locks or waits for another's."""
    import fcntl

    from .arm import load_arm
    from .controller_interface import load_controller
    from .dynamics import FlexArmModel
    whole, shared = _lock_paths()
    with open(whole, "w") as lock, open(shared, "w") as core:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)   # released when it closes
        except BlockingIOError:
            if announce is not None:
                announce()
            fcntl.flock(lock, fcntl.LOCK_EX)   # the other one's kernels are in the cache
            return
        fcntl.flock(core, fcntl.LOCK_EX)
        if announce is not None:
            announce()
        model = FlexArmModel(load_arm(arm))
        ctl = load_controller(law, list(model.arm.joint_names), {})
        stepper = Stepper(model)
        fcntl.flock(core, fcntl.LOCK_UN)
        ControlLoop(stepper, ctl, period).advance(2)


def _lock_paths():
    """compile_ahead's lock files (whole, shared kernels), in numba's cache directory
    (without NUMBA_CACHE_DIR: this package's __pycache__, else the temporary directory)."""
    import os
    import tempfile
    from pathlib import Path
    cache = Path(os.environ.get("NUMBA_CACHE_DIR") or Path(__file__).parent / "__pycache__")
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:
        cache = Path(tempfile.gettempdir())
    if not os.access(cache, os.W_OK):
        cache = Path(tempfile.gettempdir())
    return (cache / "flex_model-compile-ahead.lock",
            cache / "flex_model-compile-ahead.shared.lock")


def wait_for_shared_kernels(ahead=None) -> None:
    """Return once no :func:`compile_ahead` compiles the model's equations (a planner
    started then loads them from the cache instead of compiling them beside it: about 15
    CPU-s less on a fresh clone). ``ahead``: a process of
    :func:`compile_ahead_in_background`, whose announcement is awaited first."""
    import fcntl
    if ahead is not None and getattr(ahead, "stdout", None) is not None:
        ahead.stdout.readline()   # its locks taken (or it died: then "")
    with open(_lock_paths()[1], "w") as core:
        fcntl.flock(core, fcntl.LOCK_SH)


def compile_ahead_in_background(arm: str, period: float, law: str = "eq95"):
    """:func:`compile_ahead` in another process (the second core), e.g. while a planner
    compiles its own loops; returns the Popen (``wait()`` before building the model: then
    the model loads the kernels from the cache instead of compiling them again; its
    stdout announces the locks taken, :func:`wait_for_shared_kernels`)."""
    import subprocess
    import sys
    code = ("import sys; from flex_model.control_loop import compile_ahead; "
            "compile_ahead(sys.argv[1], float(sys.argv[2]), sys.argv[3], "
            "lambda: print('locked', flush=True))")
    return subprocess.Popen([sys.executable, "-c", code, str(arm), repr(float(period)), law],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
