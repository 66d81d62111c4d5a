"""The other link discretizations against the thesis and seed tables (issue 4)."""
from fractions import Fraction

import numpy as np
import pytest
import scipy.linalg as sla

from flex_model.arm import arm_from_dict, load_arm, resolve_preset
from flex_twin.comparison.methods import (exact_condition_number,
                                           original_coordinates_matrix, with_discretization)
from flex_model.config import ConfigError, read_yaml
from flex_model.dynamics import FlexArmModel
from flex_model.effects import parse_effects
from flex_model.lumped import lumped_parameters
from flex_model.mode_shapes import mode_roots, seed000_eq7
from flex_model.modes import natural_modes
from flex_model.statics import TipLoad, static_equilibrium


def in_print(x, paper):
    """x agrees with the paper value as printed: rounded or truncated to its decimals."""
    text = repr(float(paper))
    dec = 0 if float(paper).is_integer() else len(text.split(".")[1])
    scale = 10.0 ** dec
    return paper in (round(x, dec), np.trunc(x * scale) / scale)


def table_row(disc, **opt):
    arm = with_discretization(load_arm("thesis_example1"), disc, 2, **opt)
    model = FlexArmModel(arm.without_gravity())
    f = natural_modes(model, joints="clamped").frequencies_hz[:2]
    out = []
    for mdl, load in ((model, TipLoad(torque=10.0)), (model, TipLoad.from_magnitude(5.0)),
                      (FlexArmModel(arm), TipLoad())):
        r = static_equilibrium(mdl, load=load, linear=True)
        out.append((abs(np.degrees(r.tip_rotation)), abs(1e3 * r.tip_displacement)))
    return f, out


# thesis Tables I, II, III (Example 1, two functions per link): f1, f2 (Hz); rotation
# (deg) / tip displacement (mm) for C = 10 N m, F = 5 N, own weight
@pytest.mark.parametrize("disc, opt, freq, statics", [
    ("wavelet", {}, (1.32, 8.36), ((7.81, 273), (7.81, 363), (4.19, 219))),
    ("assumed_modes", {"mode_type": "clamped_free"}, (1.36, 9.28),
     ((6.26, 241), (6.92, 332), (3.83, 206))),
    ("assumed_modes", {"mode_type": "hinged_free"}, (1.51, 10.00),
     ((5.83, 211), (6.03, 280), (3.20, 167))),
    ("optimized_modes", {"mode_type": "clamped_free"}, (1.36, 9.28),
     ((6.26, 241), (6.92, 332), (3.83, 206))),
    ("ritz_polynomials", {}, (1.32, 8.36), ((7.81, 273), (7.81, 363), (4.19, 219))),
])
def test_thesis_tables_I_to_III(disc, opt, freq, statics):
    f, out = table_row(disc, **opt)
    assert all(in_print(x, p) for x, p in zip(f, freq)), f
    for (rot, disp), (p_rot, p_disp) in zip(out, statics):
        assert in_print(rot, p_rot) and in_print(disp, p_disp), (rot, disp)


def test_fem_coincides_with_wavelets_for_constant_sections():
    """Seed 002's Hermite elements and the thesis's wavelets: the same model for a
    constant section (end masses and inertias included), also with flexible joints."""
    base = load_arm("thesis_three_link", 4)
    effects = parse_effects([{"type": "joint_elasticity", "joint": "joint2",
                              "stiffness": 1e4, "motor_inertia": 0.1}], "<test>",
                            base.joint_names, [lk.name for lk in base.links])
    for arm in (base, base.with_effects(*effects)):
        w = FlexArmModel(arm)
        f = FlexArmModel(with_discretization(arm, "fem"))
        rng = np.random.default_rng(4)
        q = w.q_from_joint_angles([-0.3, 0.2, -0.4], 0.01 * rng.standard_normal(12))
        v = rng.standard_normal(w.nq)
        scale = np.abs(w.mass_matrix(q)).max()
        assert np.abs(f.mass_matrix(q) - w.mass_matrix(q)).max() < 1e-10 * scale
        assert np.abs(f.bias(q, v) - w.bias(q, v)).max() < 1e-10 * np.abs(w.bias(q, v)).max()
        assert np.abs(f.K - w.K).max() < 1e-10 * np.abs(w.K).max()
        fw = natural_modes(w, joints="clamped").frequencies_hz
        ff = natural_modes(f, joints="clamped").frequencies_hz
        np.testing.assert_allclose(ff, fw, rtol=1e-10)


def test_fem_with_a_tapered_section_converges_to_the_exact_statics():
    """On a tapered link the wavelets are exact with 2 variables (Theorem 1), Hermite
    elements (cubic, real EI(z)) converge to them."""
    arm = load_arm("thesis_example4").without_gravity()
    exact = static_equilibrium(FlexArmModel(arm), load=TipLoad(torque=10.0), linear=True)
    errors = []
    for n in (2, 16):
        m = FlexArmModel(with_discretization(arm, "fem", n))
        r = static_equilibrium(m, load=TipLoad(torque=10.0), linear=True)
        errors.append(abs(r.tip_displacement / exact.tip_displacement - 1.0))
    assert errors[0] > 1e-3 and errors[1] < 1e-4 * 1e3 * errors[0]


def test_mode_roots_solve_seed000_eq7_and_the_classic_cases():
    np.testing.assert_allclose(mode_roots(3, "clamped_free"),
                               [1.8751040687, 4.6940911330, 7.8547574382], rtol=1e-9)
    np.testing.assert_allclose(mode_roots(2, "hinged_free"), [3.9266023120, 7.0685827500],
                               rtol=1e-9)
    for b in mode_roots(4, "clamped_mass", 0.7, 0.01):
        assert abs(seed000_eq7(b, 0.7, 0.01)) < 1e-12


def test_clamped_mass_modes_give_the_exact_first_frequency_of_section_G():
    """Section G (seed 000 Table 1 arm): exact Euler-Bernoulli with tip mass 8.46 Hz."""
    arm = with_discretization(load_arm("seed000_real_arm"), "assumed_modes", 2,
                              mode_type="clamped_mass")
    f = natural_modes(FlexArmModel(arm), joints="clamped").frequencies_hz
    ref = natural_modes(FlexArmModel(load_arm("seed000_real_arm", 16)),
                        joints="clamped").frequencies_hz
    assert f[0] == pytest.approx(ref[0], rel=1e-6) and round(f[0], 2) == 8.46


def test_seed000_table2_lumped_mass_and_spring():
    """Seed 000 Table 2 arm: lumped mass 0.008634 kg, spring 96.7425 N/m (Eqs. 12, 16)
    and the frequency sqrt(K / (M_e + M_p)) = 8.46 Hz (paper's simulation 8.4745 Hz,
    measured 8.24 Hz)."""
    arm = load_arm("seed000_real_arm")
    m_e, k_e = lumped_parameters(arm.links[0].profile, 1, "clamped_mass", arm.payload_mass)
    assert m_e[0] == pytest.approx(0.008634, rel=1e-3)
    assert k_e[0] == pytest.approx(96.7425, rel=1e-3)
    f = np.sqrt(k_e[0] / (m_e[0] + arm.payload_mass)) / (2 * np.pi)
    assert round(f, 2) == 8.46


def test_seed000_lumped_link_is_one_coordinate_with_the_table2_mass_and_spring():
    """The lumped link in the model (one mass): its variable is the tip deflection, its
    mass and stiffness are M_e and K_e of Eqs. (12), (16) (Table 2: 0.008634 kg, 96.7425
    N/m), its clamped f1 sqrt(K_e / (M_e + M_p)) = 8.4597 Hz (paper 8.46-8.47), and a tip
    torque gives a tip rotation F'(L) / F(L) times the tip deflection (Eqs. 10, 14)."""
    arm = with_discretization(load_arm("seed000_real_arm"), "lumped", 1,
                              mode_type="clamped_mass")
    model = FlexArmModel(arm)
    b = model.bases[0]
    m_e, k_e = lumped_parameters(arm.links[0].profile, 1, "clamped_mass", arm.payload_mass)
    assert model.nq == 2 and b.Bw[0, 0] == pytest.approx(m_e[0], rel=1e-12)
    assert b.K[0, 0] == pytest.approx(k_e[0], rel=1e-12)
    f = natural_modes(model, joints="clamped").frequencies_hz[0]
    assert f == pytest.approx(np.sqrt(k_e[0] / (m_e[0] + arm.payload_mass)) / (2 * np.pi),
                              rel=1e-10)
    assert f == pytest.approx(8.4597, abs=5e-5)
    r = static_equilibrium(model, load=TipLoad(torque=0.01), linear=True)
    ratio = b.details["mode"].evaluate(np.array([0.28]))
    assert r.tip_rotation / r.tip_displacement == pytest.approx(
        ratio[1][0, 0] / ratio[0][0, 0], rel=1e-9)


def test_lumped_link_converges_to_the_first_mode_with_the_masses():
    """Seed 000 Eq. (11): the m masses hold the first mode's kinetic and elastic energy
    for every m, so the clamped f1 is the first-mode (exact, 8.4597 Hz) value for 1, 2, 8
    masses; with a free joint (no hub) the masses' coupling with the rotation (h, k)
    matters and f1 tends to the one-mode assumed-mode value (67.61 Hz) as m grows:
    30.2, 42.0, 56.0 Hz for 2, 8, 32 masses."""
    arm = load_arm("seed000_real_arm")
    first_mode = FlexArmModel(with_discretization(arm, "assumed_modes", 1,
                                                  mode_type="clamped_mass"))
    f_am = {j: natural_modes(first_mode, joints=j).frequencies_hz for j in ("clamped",
                                                                            "hinged")}
    errors = []
    for m in (1, 2, 8, 32):
        model = FlexArmModel(with_discretization(arm, "lumped", m,
                                                 mode_type="clamped_mass"))
        f_c = natural_modes(model, joints="clamped").frequencies_hz[0]
        assert f_c == pytest.approx(f_am["clamped"][0], rel=1e-10)
        errors.append(natural_modes(model, joints="hinged").frequencies_hz[1]
                      / f_am["hinged"][1] - 1.0)
    assert f_am["hinged"][1] == pytest.approx(67.609, abs=1e-3)
    assert errors[1] == pytest.approx(-0.553, abs=1e-3)
    assert np.all(np.diff(np.abs(errors)) < 0) and abs(errors[-1]) < 0.18


def test_lumped_arm_is_an_exact_lagrangian():
    """Lumped links (one variable each, tip rotation r delta, r = F'(L) / F(L)) with tip
    masses, tip inertias and a payload: the tip inertia enters B as 1/2 J+ (alpha' +
    r delta')^2, the next joint angle is alpha_2 - alpha_1 - r delta_1, and a free swing
    of the three-link arm under gravity conserves the energy to 1e-10."""
    import dataclasses
    from flex_model.simulate import simulate
    arm = load_arm("thesis_three_link")
    arm = dataclasses.replace(arm, payload_mass=0.2, payload_inertia=0.005, links=tuple(
        dataclasses.replace(lk, M_plus=0.3, J_plus=0.01) for lk in arm.links))
    model = FlexArmModel(with_discretization(arm, "lumped", 3, mode_type="clamped_mass"))
    r, b = model.tip_rotation_scale, model.bases[2]
    assert model.nq == 6 and model.G[1, 1] == -r[0] and 0.5 < r[0] < 0.6
    mass = model.mass_matrix(np.zeros(6))
    jp, mp, length = 0.015, 0.5, arm.links[2].length
    assert mass[5, 5] == pytest.approx(b.Bw[0, 0] + mp + jp * r[2] ** 2, rel=1e-12)
    assert mass[4, 5] == pytest.approx(b.k[0] + mp * length + jp * r[2], rel=1e-12)
    q0, v0 = np.zeros(6), np.zeros(6)
    q0[model.alpha_indices], v0[model.alpha_indices] = [0.3, -0.5, 0.4], [1.0, -2.0, 0.5]
    v0[model.flex_indices] = [0.05, -0.1, 0.02]
    res = simulate(model, q0, v0, t_final=0.5, sample_period=0.01, rtol=1e-10)
    energy = np.array([sum(model.energy(q, v).values()) for q, v in zip(res.q, res.v)])
    assert np.max(np.abs(energy - energy[0])) < 1e-10 * abs(energy[0])


def test_seed000_table4_step_response_lumped_vs_assumed_modes():
    """Seed 000 Table 4 (L = 1 m, payload 0.2 kg, Eq. 45 step 10 -> 30 deg): the one-mass
    lumped link and two clamped-mass modes oscillate at the damped first clamped mode
    (0.8244 Hz sqrt(1 - 0.1^2) = 0.820 Hz; paper 0.813 / 0.7937 Hz) with amplitudes
    0.2209 / 0.2248 m, 1.8 % apart (paper 0.2032 / 0.1462 m, 28 %): the payload dominates
    the coupling (k + M_p L) / (B_f + M_p) of both (1.000 / 1.017 m), which sets the
    amplitude."""
    step_response = pytest.importorskip("flex_control.step_response").step_response
    arm = load_arm("seed000_table3")
    lumped, modes = (step_response(with_discretization(arm, d, n, mode_type="clamped_mass"))
                     for d, n in (("lumped", 1), ("assumed_modes", 2)))
    f_damped = 0.82436 * np.sqrt(1 - 0.1 ** 2)
    assert lumped.tip_frequency_hz == pytest.approx(f_damped, rel=1e-3)
    assert modes.tip_frequency_hz == pytest.approx(f_damped, rel=1e-3)
    assert lumped.tip_amplitude_m == pytest.approx(0.2209, abs=5e-4)
    assert modes.tip_amplitude_m / lumped.tip_amplitude_m == pytest.approx(1.018, abs=2e-3)


def test_remark8_ritz_ill_conditioning_and_wavelets():
    """Thesis Remark 8 (single clamped link, L = 5 m, m = 1 kg/m, EI = 1): Ritz with 10
    polynomials cond(B) ~ 1e21 (paper 1.78e21; exactly 7.16e20 for Eq. 50); the state
    matrix [[0, I], [-inv(B) K, 0]] of Eq. (44) formed in float64 (the thesis's inv/eig)
    has spurious eigenvalues with large positive real parts (here 30.94 +- 36.64i,
    2.56 +- 3.14i; paper +5.69, +36.99), while eigh(K, B) gives real omega^2 > 0 with
    the exact first five; wavelets: purely imaginary, cond 7.85e2, section A
    frequencies."""
    from flex_twin.comparison.tables import first_order_eigenvalues
    arm = load_arm("thesis_single_link")
    ritz = FlexArmModel(with_discretization(arm, "ritz_polynomials")).bases[0]
    i = range(2, 12)
    exact = exact_condition_number([[Fraction(5) ** (a + b + 1) / (a + b + 1) for b in i]
                                    for a in i])
    assert 1e20 < exact < 1e22 and 1e20 < np.linalg.cond(ritz.raw_Bw) < 1e22
    np.testing.assert_allclose(ritz.raw_Bw[:3, :3], [[625, 5**6 / 6, 5**7 / 7],
                                                     [5**6 / 6, 5**7 / 7, 5**8 / 8],
                                                     [5**7 / 7, 5**8 / 8, 5**9 / 9]],
                               rtol=1e-12)
    wav = FlexArmModel(arm).bases[0]
    lam_ritz = first_order_eigenvalues(ritz.raw_Bw, ritz.raw_K)
    lam_wav = first_order_eigenvalues(wav.Bw, wav.K)
    assert np.sum(lam_ritz.real > 1.0) >= 2 and np.max(lam_ritz.real) > 10.0
    assert np.max(np.abs(lam_wav.real)) < 1e-10
    w2 = sla.eigh(ritz.raw_K, ritz.raw_Bw, eigvals_only=True)
    assert np.all(w2 > 0)
    omega_exact = mode_roots(5, "clamped_free") ** 2 / 25.0  # 0.1406 ... 7.9944 rad/s
    np.testing.assert_allclose(np.sqrt(w2[:5]), omega_exact, rtol=2e-4)
    assert f"{np.linalg.cond(wav.Bw):.2e}" == "7.85e+02"
    w = np.sqrt(sla.eigh(wav.K, wav.Bw, eigvals_only=True))
    np.testing.assert_allclose(w[:5], [0.1406, 0.8818, 2.4768, 4.8928, 8.1208], atol=6e-5)


@pytest.mark.parametrize("n, cond_w, cond_p", [(2, 6.16e3, 5.48e4), (6, 2.35e5, 3.68e11)])
def test_thesis_table_VI_condition_numbers(n, cond_w, cond_p):
    """Thesis Table VI (Example 1 robot, inertia matrix at the straight configuration):
    wavelets vs Ritz polynomials in their own variables (n = 10: 1.57e6 / 4e18, paper
    2.53e18, where the Ritz value is round-off)."""
    arm = load_arm("thesis_example1")
    mw = FlexArmModel(with_discretization(arm, "wavelet", n))
    mp = FlexArmModel(with_discretization(arm, "ritz_polynomials", n))
    t = original_coordinates_matrix(mp)
    b_raw = t.T @ mp.mass_matrix(np.zeros(mp.nq)) @ t
    assert float(f"{np.linalg.cond(mw.mass_matrix(np.zeros(mw.nq))):.2e}") == cond_w
    assert float(f"{np.linalg.cond(b_raw):.2e}") == cond_p


def test_discretization_fields_are_validated():
    data = read_yaml(resolve_preset("thesis_example1"))
    for field, value, allowed in (("discretization", "splines", "one of wavelet"),
                                  ("mode_type", "free_free", "one of clamped_free")):
        d = {**data, "links": [dict(data["links"][0]), data["links"][1]]}
        d["links"][0]["discretization"] = "assumed_modes"
        d["links"][0][field] = value
        with pytest.raises(ConfigError) as e:
            arm_from_dict(d, "arm.yaml")
        msg = str(e.value)
        assert "arm.yaml" in msg and field in msg and value in msg and allowed in msg
    d = {**data, "links": [dict(data["links"][0]), data["links"][1]]}
    d["links"][0].update(discretization="fem", variables=3)
    with pytest.raises(ConfigError, match="variables"):
        arm_from_dict(d, "arm.yaml")
    d["links"][0].update(discretization="assumed_modes", variables=3)
    assert arm_from_dict(d, "arm.yaml").links[0].n_vars == 3


def test_thesis_tables_IV_V_ritz_column():
    """Thesis Tables IV-V (Example 2, piecewise section): two Ritz polynomials per link
    give 17.2 / 2.94 / 1.45 deg and 257 / 79 / 73 mm where the exact values are 26.5 /
    4.32 / 1.90 deg and 377 / 106 / 83 mm (the wavelets, exact with two variables)."""
    from flex_twin.comparison.tables import thesis_tables_IV_V
    rows = {r["method"]: r for r in thesis_tables_IV_V()}
    for name in ("wavelet 2", "Ritz polynomials 2"):
        r = rows[name]
        for key in ("IV", "V"):
            assert all(in_print(x, p) for x, p in zip(r[key], r[f"paper_{key}"])), r


def test_compare_cli_writes_the_report(tmp_path, capsys):
    """``flex-twin compare`` (without the slow parts) writes report.md with the paper
    value next to ours, and a bad --out is a one-line error with exit code 2."""
    from flex_twin.cli import main
    assert main(["compare", "--out", str(tmp_path / "c"), "--no-cost", "--no-frequency",
                 "--no-step", "--quiet", "--json"]) == 0
    text = (tmp_path / "c" / "report.md").read_text()
    assert "| f1 | 1.32 / 1.323 | 1.32 / 1.323 | 1.36 / 1.363 | 1.51 / 1.508 |" in text
    assert "| 0.008634 kg | 0.008632 kg |" in text
    (tmp_path / "file").write_text("")
    capsys.readouterr()
    assert main(["compare", "--out", str(tmp_path / "file"), "--no-cost", "--quiet"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_tip_torque_response_tends_to_the_static_compliance():
    """|H(j w)| tip torque -> tip rotation at w -> 0 is the static compliance L / EI of
    the 4 m clamped beam of Example 1 (Theorem 1: exact with two wavelets per link), and
    the response has a pole at the first clamped frequency."""
    from flex_twin.comparison.frequency import tip_torque_response
    arm = load_arm("thesis_example1").without_gravity()
    model = FlexArmModel(arm)
    ei = float(arm.links[0].segments[0].properties(np.array([0.0]))[0][0])
    h = tip_torque_response(model, np.array([1e-4, 1.3233, 1.3234]))
    assert abs(h[0]) == pytest.approx(4.0 / ei, rel=1e-6)
    assert abs(h[1]) > 1e3 * abs(h[0]) or abs(h[2]) > 1e3 * abs(h[0])
