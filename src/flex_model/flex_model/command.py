"""What every package's entry point (flex-twin, flex-control, flex-planner) shares: the
output directory, the progress line and the exit convention: 0 success, 2 bad input (one
line on stderr), 1 a failed computation."""
from __future__ import annotations

import signal
import sys
import threading
import time
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

import numpy as np


def run_dir(base: str | None, name: str) -> Path:
    """The output directory (created): ``base``, or ``runs/YYYYmmdd-HHMMSS-<name>``."""
    path = Path(base) if base else Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}-{name}"
    path.mkdir(parents=True, exist_ok=True)
    return path


class Progress:
    """Progress of a long run on stderr: a live line on a terminal, else every 10 %."""

    def __init__(self, label: str, enabled: bool = True):
        self.label, self.enabled = label, enabled
        self.tty = sys.stderr.isatty()
        self.start = time.perf_counter()
        self.next_mark = 0.1

    def __call__(self, t: float, total: float) -> None:
        if not self.enabled:
            return
        frac = t / total
        wall = time.perf_counter() - self.start
        msg = f"{self.label}: t = {t:7.3f} / {total:g} s ({100 * frac:5.1f} %, {wall:6.2f} s wall)"
        if self.tty:
            print("\r" + msg, end="" if frac < 1 else "\n", file=sys.stderr, flush=True)
        elif frac >= self.next_mark - 1e-9 or frac >= 1:
            print(msg, file=sys.stderr, flush=True)
            self.next_mark = np.floor(frac * 10 + 1e-9) / 10 + 0.1


@contextmanager
def stop_on_signals():
    """A ``threading.Event`` that SIGINT and SIGTERM set while inside (their previous
    handlers come back on exit; outside the main thread none is installed): loops check
    it between steps, so nothing interrupts a callback or a compiled call, and a ROS
    context stays valid for a last command."""
    stop = threading.Event()
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda *_: stop.set())
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def run_command(args) -> int:
    """Run a parsed subcommand (``args.func(args)``) with the suite's exit codes."""
    from .config import ConfigError
    from .errors import SolverError

    try:
        return args.func(args)
    except (ConfigError, ValueError, FileNotFoundError) as exc:
        print(f"flex-twin: error: {exc}", file=sys.stderr)
        return 2
    except (SolverError, TimeoutError, np.linalg.LinAlgError) as exc:
        print(f"flex-twin: failed: {exc}", file=sys.stderr)
        return 1
