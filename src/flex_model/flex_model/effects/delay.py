"""Actuator delay: the commands of a digital controller reach the joint late."""
from __future__ import annotations

from .base import Effect, Parameter


class ActuatorDelay(Effect):
    """The command computed at t acts from t + delay (s) on: a transport delay of the
    policy's (controller's) commands, as a fieldbus or a drive adds. The built-in
    continuous PD law of simulate() is not delayed."""

    TYPE = "actuator_delay"
    TARGET = "joint"
    DESCRIPTION = "transport delay of the joint commands"
    PARAMETERS = (Parameter("delay", "s", 0.0, (0.0, 1.0), 0.2, "command delay"),)
    EQUIVALENT = ("joint encoder delay (sensor delay) in closed loop",)
