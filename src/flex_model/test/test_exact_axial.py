"""Axial extensibility of the exact kinematics (``axial_vars``, flex_model.exact_kinematics):
closed forms of a rod (static stretch, own weight, first axial frequency), the Lagrangian
check of the sweep with axial variables, and the one-line refusals."""
import numpy as np
import pytest
import scipy.linalg as sl

from flex_model.arm import arm_from_dict
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.exact_kinematics import ExactKinematicsUnsupported
from flex_model.scenario import scenario_from_dict
from flex_model.statics import TipLoad, static_equilibrium

E_MOD, RHO, L = 6.4e10, 2700.0, 2.0
AREA = 0.020 ** 2 - 0.018 ** 2            # square tube 20 x 1 mm
TUBE = {"length": L, "material": {"E": E_MOD, "rho": RHO},
        "section": {"shape": "square_hollow", "side": 0.020, "wall": 0.001}, "variables": 4}


def rod(axial_vars, gravity=(0.0, 0.0), links=(TUBE,)):
    return FlexArmModel(arm_from_dict({
        "name": "rod", "gravity": list(gravity), "kinematics": "exact",
        "axial_vars": axial_vars, "links": [dict(lk) for lk in links]}))


@pytest.mark.parametrize("na", [1, 3])
def test_static_stretch_under_a_tip_force_is_FL_over_EA(na):
    """A clamped link pulled along its axis by F = 2 kN: tip at L + F L / EA (0.82 mm)
    to 1e-6 of the stretch, from one axial variable; the bending stays zero."""
    m = rod(na)
    F = 2000.0
    res = static_equilibrium(m, [0.0], joints="clamped", load=TipLoad((F, 0.0)))
    stretch = F * L / (E_MOD * AREA)
    assert res.tip_position[0] - L == pytest.approx(stretch, rel=1e-6)
    assert abs(res.tip_position[1]) < 1e-12


def test_hanging_rod_stretches_by_rho_g_over_E_under_its_own_weight():
    """Hanging from the clamped joint under gravity: u(s) = rho g (L s - s^2 / 2) / E,
    tip rho g L^2 / (2 E) = 0.83 um; the linear strain (two axial variables) is exact
    at every point, one (constant strain) only at the tip (its Ritz optimum), 1/3 short
    at mid-length."""
    g = 9.81
    u = RHO * g / E_MOD * np.array([L * L / 2 - L * L / 8, L * L / 2])   # s = L/2, L
    for na, mid_rel in ((2, 1e-6), (1, 0.34)):
        m = rod(na, gravity=(0.0, -g))
        q = static_equilibrium(m, [-np.pi / 2], joints="clamped").q
        pts = m._exact.shape(q, points_per_link=3)[0]
        assert -pts[2, 1] - L == pytest.approx(u[1], rel=1e-6)
        assert -pts[1, 1] - L / 2 == pytest.approx(u[0], rel=mid_rel)
        assert np.max(np.abs(pts[:, 0])) < 1e-12
    assert -pts[1, 1] - L / 2 == pytest.approx(2 / 3 * u[0], rel=1e-6)


def test_first_axial_frequency_of_the_clamped_free_rod():
    """omega_1 = (pi / 2) c / L, c = sqrt(E / rho) (634 Hz here): one axial variable is
    the constant strain's Ritz value sqrt(3) c / L exactly (10 % high), four within 1e-6
    (the axial block of K and B(0) at the clamped joint; it does not couple to the
    bending or the joint angle in the straight link)."""
    c = np.sqrt(E_MOD / RHO)
    for na, expect, rel in ((1, np.sqrt(3.0) * c / L, 1e-9), (4, 0.5 * np.pi * c / L, 1e-6)):
        m = rod(na)
        a = slice(int(m.axial_off[0]), int(m.axial_off[0]) + na)
        B = m.mass_matrix(np.zeros(m.nq))
        assert np.max(np.abs(B[a, :1])) < 1e-15 and np.max(np.abs(B[a, 1:a.start])) < 1e-15
        w = np.sqrt(sl.eigh(m.K[a, a], B[a, a], eigvals_only=True)[0])
        assert w == pytest.approx(expect, rel=rel)


def test_bias_is_the_lagrangian_with_axial_variables(lagrange_bias):
    """c(q, v) = dB/dt v - 1/2 d(v^T B v)/dq + dU_g/dq by central differences on two
    extensible links with end masses (strains 1e-3, large bending), the compiled sweep
    equals the NumPy one, and the tip Jacobian is the derivative of the tip position."""
    link = dict(TUBE, length=0.5, end_masses={"M_minus": 0.2, "M_plus": 0.1,
                                              "J_minus": 0.01, "J_plus": 1e-4})
    m = rod(2, gravity=(0.0, -9.81), links=(link, dict(TUBE, length=0.4)))
    rng = np.random.default_rng(3)
    q = rng.normal(size=m.nq) * 0.3
    q[m.axial_off[0]:] *= 3e-3
    v = rng.normal(size=m.nq)
    c = m.bias(q, v)
    assert np.max(np.abs(c - lagrange_bias(m, q, v))) < 1e-7 * np.max(np.abs(c))
    B1, c1 = m._exact.mass_and_bias(q, v, 0.0, -9.81)
    B2, c2 = m._exact.mass_and_bias_numpy(q, v, 0.0, -9.81)
    assert np.max(np.abs(B1 - B2)) < 1e-14 and np.max(np.abs(c1 - c2)) < 1e-12
    h = 1e-6
    Jn = np.array([(m.link_origins(q + h * e)[-1] - m.link_origins(q - h * e)[-1]) / (2 * h)
                   for e in np.eye(m.nq)]).T
    assert np.max(np.abs(m.tip_jacobian(q) - Jn)) < 1e-8
    assert m.coordinate_names()[-1] == "link2/axial1"


def test_axial_vars_refused_in_one_line_where_they_cannot_run():
    """Outside kinematics: exact (arm file and scenario override), and on an explicit
    (EI, m) section whose EA is unknown."""
    arm = {"name": "a", "links": [TUBE], "axial_vars": 2}
    with pytest.raises(ConfigError, match="axial_vars: got 2; expected 0 unless "
                                          "kinematics: exact") as e1:
        arm_from_dict(dict(arm, kinematics="second_order"))
    sc = {"arm": dict(arm, kinematics="exact"), "kinematics": "small_deflection",
          "duration": 0.1}
    with pytest.raises(ConfigError, match="axial_vars") as e2:
        scenario_from_dict(sc)
    link = {"length": 0.5, "section": {"shape": "explicit", "EI": 2.0, "m": 0.3}}
    with pytest.raises(ExactKinematicsUnsupported, match="EA is unknown") as e3:
        FlexArmModel(arm_from_dict({"name": "b", "links": [link], "kinematics": "exact",
                                    "axial_vars": 1}))
    for e in (e1, e2, e3):
        assert "\n" not in str(e.value)
