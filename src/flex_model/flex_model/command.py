"""The command-line exit convention shared by every package's entry point (flex-twin,
flex-control, flex-planner): 0 success, 2 bad input (one line on stderr), 1 a failed
computation."""
from __future__ import annotations

import sys

import numpy as np


def run_command(args) -> int:
    """Run a parsed subcommand (``args.func(args)``) with the suite's exit codes."""
    from .config import ConfigError
    from .simulate import SimulationDivergedError
    from .statics import StaticConvergenceError

    try:
        return args.func(args)
    except (ConfigError, ValueError, FileNotFoundError) as exc:
        print(f"flex-twin: error: {exc}", file=sys.stderr)
        return 2
    except (StaticConvergenceError, SimulationDivergedError, np.linalg.LinAlgError) as exc:
        print(f"flex-twin: failed: {exc}", file=sys.stderr)
        return 1
