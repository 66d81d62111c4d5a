"""Twins of real arms: data import, replay, calibration, validation (issue 9)."""
