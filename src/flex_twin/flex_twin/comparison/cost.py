"""Cost of each discretization on the three-link arm of VALIDATION.md section E (the
spirit of thesis Tables VII-XI): time per evaluation of the equations of motion (mass
matrix, bias, Cholesky solve: flex_model.integrators.derivative) and CPU time per
simulated second (generalized-alpha, 1 ms), at 4 and 8 variables per link, with the
growth exponent d ln(cost) / d ln(variables per link).

Every basis runs through the same compiled kernels in the tip form of thesis Eq. (84),
so at equal variables the evaluation cost is the same for every method (the thesis's
differences, Tables VII-VIII and XII-XV, are those of symbolic expressions that expand
the interconnection in all modal variables); what differs is the stiffness (the highest
frequency a method puts in the model) and its conditioning.
"""
from __future__ import annotations

import time

import numpy as np

from flex_model.integrators import derivative
from flex_model.modes import natural_modes
from flex_model.scenario import load_scenario
from flex_model.inputs import input_data
from flex_model.simulate import SimulationDivergedError
from .methods import METHODS, with_discretization

SCENARIO = "thesis_three_link_pd"


def _scenario(disc: str, n_vars: int, options: dict):
    sc = load_scenario(SCENARIO, vars_per_link=n_vars)
    sc.arm = with_discretization(sc.arm, disc, n_vars, **options)
    return sc


def eom_microseconds(model, sc, repeats: int = 2000) -> float:
    """Best of five: microseconds per evaluation of dx/dt."""
    e = input_data(model, sc.pd, sc.pulses, np.zeros(model.n_links))
    x = np.concatenate([model.q_from_joint_angles(sc.joint_values), np.full(model.nq, 0.01)])
    derivative(0.0, x, model.P, e)
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeats):
            derivative(0.0, x, model.P, e)
        best = min(best, (time.perf_counter() - t0) / repeats)
    return 1e6 * best


def simulated_second(sc, model, duration: float, dt: float) -> float:
    """CPU seconds per simulated second over the first ``duration`` s of the scenario
    (best of two; NaN if the run diverges)."""
    sc.duration, sc.method, sc.step = duration, "fixed", dt
    best = np.inf
    for _ in range(2):
        c0 = time.process_time()
        try:
            sc.run(model=model, advise=False)
        except SimulationDivergedError:
            return float("nan")
        best = min(best, time.process_time() - c0)
    return best / duration


def cost_table(vars_per_link=(4, 8), duration: float = 5.0, dt: float = 1e-3,
               repeats: int = 2000, progress=None) -> list[dict]:
    """One row per method: us per evaluation, CPU s per simulated second and the highest
    natural frequency (clamped joints: what bounds an explicit step) at each variable
    count, growth exponents between the first and the last count."""
    rows = []
    for label, disc, opt in METHODS:
        row = {"method": label, "eval_us": {}, "cpu_per_sim_s": {}, "f_max_hz": {}}
        for n in vars_per_link:
            if progress:
                progress(f"cost: {label}, {n} variables per link")
            sc = _scenario(disc, n, opt)
            model = sc.model()
            row["eval_us"][n] = eom_microseconds(model, sc, repeats)
            row["cpu_per_sim_s"][n] = simulated_second(sc, model, duration, dt)
            row["f_max_hz"][n] = float(natural_modes(model, joints="clamped")
                                       .frequencies_hz[-1])
        lo, hi = vars_per_link[0], vars_per_link[-1]
        ratio = np.log(hi / lo)
        row["eval_exponent"] = float(np.log(row["eval_us"][hi] / row["eval_us"][lo]) / ratio)
        row["sim_exponent"] = float(np.log(row["cpu_per_sim_s"][hi]
                                           / row["cpu_per_sim_s"][lo]) / ratio)
        rows.append(row)
    return rows
