"""The paper tables the comparison reproduces, paper value next to ours.

Thesis Tables I-III (Example 1, two functions per link, VALIDATION.md B), Tables IV-V
(Example 2, VALIDATION.md C), Table VI and
Remark 8 (VALIDATION.md A), seed 000 Tables 2 and 4 (VALIDATION.md G). Every function
returns plain dicts (JSON-ready); ``None`` stands for "not in the paper".
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.linalg as sla

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.lumped import lumped_parameters
from flex_model.mode_shapes import mode_roots
from flex_model.modes import natural_modes
from flex_model.statics import TipLoad, static_equilibrium
from .methods import exact_condition_number, original_coordinates_matrix, with_discretization

#: thesis Table I columns and the discretization behind each (two variables per link)
TABLE_COLUMNS = (
    ("theory", None, {}),
    ("wavelet", "wavelet", {}),
    ("clamped-free modes", "assumed_modes", {"mode_type": "clamped_free"}),
    ("hinged-free modes", "assumed_modes", {"mode_type": "hinged_free"}),
    ("Ritz polynomials", "ritz_polynomials", {}),
    ("optimized modes", "optimized_modes", {"mode_type": "clamped_free"}),
    ("FEM", "fem", {}),
    ("lumped", "lumped", {"mode_type": "clamped_free"}),
)
#: thesis Tables I (f1, f2 Hz), II (tip rotation deg) and III (tip displacement mm) for
#: C = 10 N m, F = 5 N and the own weight
PAPER_TABLES = {
    "theory": {"I": (1.32, 8.29), "II": (7.81, 7.81, 4.19), "III": (273, 363, 219)},
    "wavelet": {"I": (1.32, 8.36), "II": (7.81, 7.81, 4.19), "III": (273, 363, 219)},
    "clamped-free modes": {"I": (1.36, 9.28), "II": (6.26, 6.92, 3.83),
                           "III": (241, 332, 206)},
    "hinged-free modes": {"I": (1.51, 10.00), "II": (5.83, 6.03, 3.20),
                          "III": (211, 280, 167)},
    "Ritz polynomials": {"I": (1.32, 8.36), "II": (7.81, 7.81, 4.19), "III": (273, 363, 219)},
}
LOADS = ("C = 10 N m", "F = 5 N", "own weight")
#: thesis Table VI: n_F -> (cond wavelet, cond Ritz)
PAPER_TABLE_VI = {2: (6.16e3, 5.48e4), 6: (2.35e5, 3.68e11), 10: (1.57e6, 2.53e18)}
#: thesis Remark 8 and VALIDATION.md A
PAPER_REMARK8 = {"cond_wavelet": 7.85e2, "cond_ritz": 1.78e21,
                 "omega_w10": (0.1406, 0.8818, 2.4768, 4.8928, 8.1208, 13.4909, 19.7305,
                               28.6136, 40.6478, 59.7951),
                 "lambda_ritz": "+-i 0.1340, 0.7439, 1.5938, 3.377, +-5.6917, +-i 10.99, "
                                "28.46, +-36.99, +-i 98.28, 205.57"}


def _theory_example1(arm):
    """Closed forms of the 4 m clamped beam (thesis Eqs. 33-34)."""
    seg = arm.links[0].segments[0]
    ei, m = (float(x[0]) for x in seg.properties(np.array([0.0]))[:2])
    length = sum(lk.length for lk in arm.links)
    g = abs(arm.gravity[1])
    f = mode_roots(2, "clamped_free") ** 2 / (2 * np.pi * length ** 2) * np.sqrt(ei / m)
    c, force, q = 10.0, 5.0, m * g
    rot = np.degrees([c * length / ei, force * length ** 2 / (2 * ei),
                      q * length ** 3 / (6 * ei)])
    disp = 1e3 * np.array([c * length ** 2 / (2 * ei), force * length ** 3 / (3 * ei),
                           q * length ** 4 / (8 * ei)])
    return tuple(f), tuple(rot), tuple(disp)


def _static_column(arm, loads):
    """|tip rotation| (deg) and |tip displacement| (mm) of the linear statics for tip
    loads (``None``: the own weight), clamped joints."""
    model = FlexArmModel(arm.without_gravity())
    rot, disp = [], []
    for load in loads:
        mdl = FlexArmModel(arm) if load is None else model
        r = static_equilibrium(mdl, load=TipLoad() if load is None else load, linear=True)
        rot.append(abs(float(np.degrees(r.tip_rotation))))
        disp.append(abs(1e3 * float(r.tip_displacement)))
    return rot, disp


def thesis_tables_I_to_III(n_vars: int = 2) -> list[dict]:
    """One dict per column: name, ours and paper for Tables I, II, III."""
    arm = load_arm("thesis_example1")
    loads = (TipLoad(torque=10.0), TipLoad.from_magnitude(5.0), None)
    rows = []
    for name, disc, opt in TABLE_COLUMNS:
        if disc is None:
            f, rot, disp = _theory_example1(arm)
        else:
            a = with_discretization(arm, disc, n_vars, **opt)
            f = tuple(natural_modes(FlexArmModel(a.without_gravity()),
                                    joints="clamped").frequencies_hz[:2])
            rot, disp = _static_column(a, loads)
        paper = PAPER_TABLES.get(name, {})
        rows.append({"method": name, "discretization": disc, "options": opt,
                     "I": [float(x) for x in f], "II": [float(x) for x in rot],
                     "III": [float(x) for x in disp], "paper_I": paper.get("I"),
                     "paper_II": paper.get("II"), "paper_III": paper.get("III")})
    return rows


#: thesis Tables IV (tip rotation deg) and V (tip displacement mm), Example 2: C = 50 N m,
#: F = 10 N, own weight; "true" = wavelets with 20 variables per link
PAPER_TABLES_IV_V = {"wavelet 20 (true)": ((26.5, 4.32, 1.90), (377, 106, 83)),
                     "wavelet 2": ((26.5, 4.32, 1.90), (377, 106, 83)),
                     "Ritz polynomials 2": ((17.2, 2.94, 1.45), (257, 79, 73))}


def thesis_tables_IV_V() -> list[dict]:
    """Example 2 (piecewise section, VALIDATION.md C): wavelets vs Ritz, two variables."""
    arm = load_arm("thesis_example2")
    loads = (TipLoad(torque=50.0), TipLoad.from_magnitude(10.0), None)
    rows = []
    for name, disc, n in (("wavelet 20 (true)", "wavelet", 20), ("wavelet 2", "wavelet", 2),
                          ("Ritz polynomials 2", "ritz_polynomials", 2),
                          ("clamped-free modes 2", "assumed_modes", 2), ("FEM 2", "fem", 2)):
        rot, disp = _static_column(with_discretization(arm, disc, n), loads)
        paper = PAPER_TABLES_IV_V.get(name, (None, None))
        rows.append({"method": name, "IV": rot, "V": disp, "paper_IV": paper[0],
                     "paper_V": paper[1]})
    return rows


def thesis_table_VI() -> list[dict]:
    """cond B(0) of the Example 1 robot: wavelets and Ritz (in its own variables)."""
    arm = load_arm("thesis_example1")
    rows = []
    for n, (pw, pp) in PAPER_TABLE_VI.items():
        mw = FlexArmModel(with_discretization(arm, "wavelet", n))
        mp = FlexArmModel(with_discretization(arm, "ritz_polynomials", n))
        t = original_coordinates_matrix(mp)
        b_raw = t.T @ mp.mass_matrix(np.zeros(mp.nq)) @ t
        rows.append({"n_F": n, "cond_wavelet": float(np.linalg.cond(
            mw.mass_matrix(np.zeros(mw.nq)))), "cond_ritz": float(np.linalg.cond(b_raw)),
            "paper_cond_wavelet": pw, "paper_cond_ritz": pp})
    return rows


def first_order_eigenvalues(mass, stiffness, inverse: bool = True):
    """Eigenvalues of the state matrix A = [[0, I], [-B^-1 K, 0]] of thesis Eq. (44) in
    float64, B^-1 K formed as inv(B) @ K (``inverse``, as MATLAB's inv) or by an LU solve."""
    n = mass.shape[0]
    b_inv_k = np.linalg.inv(mass) @ stiffness if inverse else np.linalg.solve(mass, stiffness)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-b_inv_k, np.zeros((n, n))]])
    return np.linalg.eigvals(a)


def remark8() -> dict:
    """Thesis Remark 8: the single clamped link of VALIDATION.md A, 10 variables. The
    state matrix of Eq. (44) formed with inv(B) in float64 (the thesis's way) has
    spurious eigenvalues with large positive real parts for Ritz polynomials (cond B
    ~ 1e20 > 1/eps), not for wavelets; an LU solve is better, and the symmetric
    generalized eigensolver eigh(K, B) keeps every omega^2 real and positive."""
    arm = load_arm("thesis_single_link")
    wav = FlexArmModel(with_discretization(arm, "wavelet", 10)).bases[0]
    ritz = FlexArmModel(with_discretization(arm, "ritz_polynomials", 10)).bases[0]
    i = range(2, 12)
    exact = exact_condition_number([[Fraction(5) ** (a + b + 1) / (a + b + 1) for b in i]
                                    for a in i])
    lam_r = first_order_eigenvalues(ritz.raw_Bw, ritz.raw_K)
    lam_w = first_order_eigenvalues(wav.Bw, wav.K)
    lam_r_lu = first_order_eigenvalues(ritz.raw_Bw, ritz.raw_K, inverse=False)
    w2_ritz = sla.eigh(ritz.raw_K, ritz.raw_Bw, eigvals_only=True)
    length, ei_m = 5.0, 1.0
    omega_exact = mode_roots(10, "clamped_free") ** 2 / length ** 2 * np.sqrt(ei_m)
    return {"cond_wavelet": float(np.linalg.cond(wav.Bw)),
            "cond_ritz_float": float(np.linalg.cond(ritz.raw_Bw)),
            "cond_ritz_exact": exact,
            "max_real_part_ritz": float(np.max(lam_r.real)),
            "max_abs_real_part_wavelet": float(np.max(np.abs(lam_w.real))),
            "n_unstable_ritz": int(np.sum(lam_r.real > 1e-6)),
            "spurious_ritz": [[float(x.real), float(x.imag)] for x in lam_r
                              if x.real > 1e-6],
            "max_real_part_ritz_lu": float(np.max(lam_r_lu.real)),
            "min_omega2_ritz_eigh": float(np.min(w2_ritz)),
            "omega_ritz_eigh": [float(x) for x in np.sqrt(w2_ritz)],
            "omega_wavelet": [float(x) for x in np.sqrt(sla.eigh(wav.K, wav.Bw,
                                                                  eigvals_only=True))],
            "omega_exact": [float(x) for x in omega_exact], "paper": PAPER_REMARK8,
            "eigenvalues_ritz": [[float(x.real), float(x.imag)] for x in lam_r],
            "eigenvalues_wavelet": [[float(x.real), float(x.imag)] for x in lam_w]}


def seed000_tables() -> dict:
    """Seed 000 Table 2 (one lumped mass and spring, 8.46-8.47 Hz vs measured 8.24 Hz) and
    Table 4 frequencies (L = 1 m, payload 0.2 kg: assumed modes vs lumped); the lumped
    link with 1, 2, 8 masses clamped (the first mode's f1 for every m) and with a free
    joint (no hub: tends to the one-mode assumed-mode f1 as m grows)."""
    out = {}
    for preset in ("seed000_real_arm", "seed000_table3"):
        arm = load_arm(preset)
        prof, mp = arm.links[0].profile, arm.payload_mass
        m_e, k_e = lumped_parameters(prof, 1, "clamped_mass", mp)
        row = {"lumped_mass_kg": float(m_e[0]), "lumped_spring_n_m": float(k_e[0]),
               "f_lumped_1_mass_hz": float(np.sqrt(k_e[0] / (m_e[0] + mp)) / (2 * np.pi))}
        for label, disc, n, opt in (("f_assumed_modes_2_hz", "assumed_modes", 2,
                                     {"mode_type": "clamped_mass"}),
                                    ("f_clamped_free_modes_2_hz", "assumed_modes", 2,
                                     {"mode_type": "clamped_free"}),
                                    ("f_lumped_model_1_2_8_hz", "lumped", (1, 2, 8),
                                     {"mode_type": "clamped_mass"}),
                                    ("f_wavelet_16_hz", "wavelet", 16, {}),
                                    ("f_free_first_mode_hz", "assumed_modes", 1,
                                     {"mode_type": "clamped_mass"}),
                                    ("f_free_lumped_2_8_32_hz", "lumped", (2, 8, 32),
                                     {"mode_type": "clamped_mass"})):
            joints = "hinged" if label.startswith("f_free") else "clamped"
            f = [natural_modes(FlexArmModel(with_discretization(arm, disc, m, **opt)),
                               joints=joints).frequencies_hz[int(joints == "hinged")]
                 for m in np.atleast_1d(n)]
            row[label] = [float(x) for x in f] if isinstance(n, tuple) else float(f[0])
        out[preset] = row
    out["seed000_real_arm"]["paper"] = {"lumped_mass_kg": 0.008634,
                                        "lumped_spring_n_m": 96.7425,
                                        "f_simulation_hz": 8.4745, "f_measured_hz": 8.24,
                                        "f_euler_bernoulli_hz": 8.46}
    out["seed000_table3"]["paper"] = {"f_assumed_modes_hz": 0.7937, "f_lumped_hz": 0.813,
                                      "f_exact_hz": 0.824, "amplitude_assumed_modes_m": 0.1462,
                                      "amplitude_lumped_m": 0.2032}
    return out


def seed002_flexible_joints() -> dict:
    """Seed 002 (VALIDATION.md H): the two-link FEM arm, two Hermite elements per link,
    with the flexible joints of Eqs. 11-14 (k = 1e4 N m/rad, motor inertia 0.1 kg m^2,
    the ``joint_elasticity`` effect) and rigid: FEM vs wavelet frequencies of the free
    (hinged) arm, the two rigid-body modes left out."""
    from flex_model.effects import parse_effects
    arm = load_arm("seed002_two_link")
    eff = parse_effects([{"type": "joint_elasticity", "joint": j, "stiffness": 1e4,
                          "motor_inertia": 0.1} for j in arm.joint_names], "<compare>",
                        arm.joint_names, [lk.name for lk in arm.links])
    out = {}
    for label, a in (("rigid joints", arm), ("flexible joints", arm.with_effects(*eff))):
        f = {d: natural_modes(FlexArmModel(with_discretization(a, d, 4)),
                              joints="hinged").frequencies_hz[2:7] for d in ("wavelet", "fem")}
        out[label] = {"wavelet_hz": [float(x) for x in f["wavelet"]],
                      "fem_hz": [float(x) for x in f["fem"]],
                      "max_relative_difference": float(np.max(np.abs(f["fem"] / f["wavelet"]
                                                                     - 1.0)))}
    return out
