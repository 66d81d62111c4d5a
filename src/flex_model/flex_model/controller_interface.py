"""Controllers that run inside the model's loop: the interface and the loader.

The ros2_control pattern: the controller manager runs the hardware (here: the simulated
arm) and its controllers in one update loop, and topics are only at the edges. A controller
is any object with

    update(time, period, state) -> command      # joint torques (N m) or voltages (V)
    set_trajectory(trajectory)                  # a flex_model.trajectory.JointTrajectoryData
    joint_names                                 # command order

``state`` is a :class:`SensedState` (what the controller may read: joint angles, rates and
the link tip deflections). Controllers are found by name among the entry points of the
group ``flex_twin.controllers`` (flex_control registers its laws there: ``eq95``,
``eq45``, ``state_feedback``), or given as ``module:factory``; the factory is called as
``factory(joint_names, parameters)`` with the controller's parameters (a mapping, validated
by the controller). flex_model itself imports no controller package.
"""
from __future__ import annotations

from importlib import import_module
from importlib.metadata import entry_points
from typing import NamedTuple, Protocol

import numpy as np

ENTRY_POINT_GROUP = "flex_twin.controllers"


class SensedState(NamedTuple):
    """What an in-loop controller reads at an update (SI units, joint order)."""

    positions: np.ndarray       # joint angles (rad), what the encoders measure
    velocities: np.ndarray      # joint rates (rad/s)
    deflections: np.ndarray     # link tip deflections (m)
    deflection_rates: np.ndarray


class InLoopController(Protocol):
    joint_names: list

    def update(self, time: float, period: float, state: SensedState) -> np.ndarray: ...

    def set_trajectory(self, trajectory) -> None: ...


def available_controllers() -> dict:
    """{name: entry point} of the installed in-loop controllers."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def load_controller(name: str, joint_names, parameters: dict | None = None):
    """The in-loop controller ``name`` (an entry point name or ``module:factory``) for the
    joints ``joint_names`` with ``parameters``; ``ValueError`` names what is allowed."""
    found = available_controllers()
    if name in found:
        factory = found[name].load()
    elif ":" in name:
        module, _, attr = name.partition(":")
        try:
            factory = getattr(import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"controller: got {name!r}; cannot load it ({exc})") from None
    else:
        raise ValueError(f"controller: got {name!r}; expected one of "
                         f"{', '.join(sorted(found)) or '(none installed)'} or "
                         "module:factory")
    controller = factory(list(joint_names), dict(parameters or {}))
    for attr in ("update", "set_trajectory"):
        if not callable(getattr(controller, attr, None)):
            raise ValueError(f"controller {name!r}: the object has no {attr}() method")
    return controller
