"""Fixtures of the flex_control unit tests (independent of flex_planner).

``section_f_quasi_static``: the thesis Ch. V arm (preset ``thesis_example1``: Example 1 in
the vertical plane, gravity on, 2 variables per link) holding static poses along a cubic
spline through the joint angles that put the statically deflected tip on the section F
waypoints (a small static-flexible inversion by Newton's method on the tip position).
It is not the admissible nominal input of thesis V.1 (the planner's job), but a slow,
smooth nominal trajectory through the same poses, enough to exercise the design and the
LTV machinery.
"""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.statics import static_equilibrium

from flex_control.nominal import quasi_static_trajectory

SECTION_F_TIP = np.array([[-1.0, -1.0], [-2.0, -1.0], [-2.0, -2.0], [-1.0, -2.0]])  # m
SECTION_F_T = np.array([0.0, 5.0, 10.0, 15.0])                                     # s


def rigid_ik(p, l1=2.0, l2=2.0):
    """Joint angles of a rigid two-link arm reaching p, elbow above the base-tip line."""
    x, y = p
    c2 = (x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    t2 = np.arccos(c2)
    return np.array([np.arctan2(y, x) - np.arctan2(l2 * np.sin(t2), l1 + l2 * np.cos(t2)),
                     t2])


def static_flexible_ik(model, p):
    """Joint angles whose static deflected tip (joints held) is at p (Newton, 2 x 2)."""
    def tip(th):
        return np.array(static_equilibrium(model, th).tip_position)

    th = rigid_ik(p)
    for _ in range(30):
        err = p - tip(th)
        if np.max(np.abs(err)) < 1e-11:
            return th
        J = np.column_stack([(tip(th + d) - tip(th - d)) / 2e-6 for d in 1e-6 * np.eye(2)])
        th = th + np.linalg.solve(J, err)
    raise AssertionError(f"static-flexible inversion did not converge at {p}")


@pytest.fixture(scope="session")
def section_f_waypoints():
    """(times in s, tip waypoints in m) of VALIDATION.md section F."""
    return SECTION_F_T.copy(), SECTION_F_TIP.copy()


@pytest.fixture(scope="session")
def section_f_model():
    return FlexArmModel(load_arm("thesis_example1"))


@pytest.fixture(scope="session")
def section_f_quasi_static(section_f_model):
    model = section_f_model
    wp = np.unwrap(np.array([static_flexible_ik(model, p) for p in SECTION_F_TIP]), axis=0)
    return quasi_static_trajectory(model, SECTION_F_T, wp, sample_period=0.05)
