"""The offline path: the live filter (Estimator.step) run over the arrays of a recording."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .filter import FIELDS, Estimator, EstimatorSettings, chi2_95

#: Sample fields stacked over time in an EstimationResult (the dicts become arrays by name)
_STACKED = [f for f in FIELDS if f not in ("parameters", "parameter_std")]


@dataclass
class EstimationResult:
    """Arrays over time of the Sample fields (first axis: samples), ``parameters`` and
    ``parameter_std`` as name -> array, ``names`` of the parameters and ``summary``."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    state_cov: np.ndarray
    joint_angles: np.ndarray
    joint_angles_std: np.ndarray
    joint_rates: np.ndarray
    joint_rates_std: np.ndarray
    tip_deflections: np.ndarray
    tip_deflections_std: np.ndarray
    tip_position: np.ndarray
    tip_position_cov: np.ndarray
    tip_orientation: np.ndarray
    tip_pose_cov: np.ndarray
    innovation: np.ndarray
    innovation_cov: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    nis_mean: np.ndarray
    nis_95_fraction: np.ndarray
    parameters: dict
    parameter_std: dict
    summary: dict


def estimate_recording(model, times, inputs, measurements_array, measurements,
                       settings: EstimatorSettings | None = None, q0=None, v0=None,
                       P0=None) -> EstimationResult:
    """Run the filter over a recording: ``times`` (N,), ``inputs`` (N, n_joints: torques,
    or voltages on DC-motor joints), ``measurements_array`` (N, len(measurements), NaN =
    missing). The sample period is the settings' (default: the median step of ``times``).
    q0: default from the first joint-angle readings, the deformation zero."""
    times = np.asarray(times, float)
    inputs = np.atleast_2d(np.asarray(inputs, float))
    Y = np.asarray(measurements_array, float).reshape(len(times), -1)
    if inputs.shape[0] != len(times) or Y.shape[1] != len(measurements):
        raise ValueError(f"estimate_recording: inputs {inputs.shape} and measurements "
                         f"{Y.shape} must have {len(times)} rows and "
                         f"{len(measurements)} measurement columns")
    if settings is None:
        settings = EstimatorSettings(sample_period=float(np.median(np.diff(times))))
    est = Estimator(model, measurements, settings)
    if q0 is None:
        q0 = initial_q(est, Y[0], inputs[0])
    est.reset(q0, v0, P0, t0=float(times[0]))
    samples = [est.step(u, y) for u, y in zip(inputs, Y)]
    result = _stack(samples, est.plant.param_names)
    result.summary["parameter_resets"] = [round(t, 6) for t in est.resets]
    if settings.adapt_horizon:   # the frictions' values above are the last block's fit
        result.summary.update(adapt_horizon=settings.adapt_horizon,
                              adapt_block=settings.adapt_block)
    return result


def initial_q(est: Estimator, y0, u0) -> np.ndarray:
    """q at rest with the joint angles of the first joint-angle readings (others 0) and
    the links deflected in static balance (gravity, the first input): Newton on the
    deformation rows of B(q) a(q, 0, u0) = 0 (Eq. 27 at rest)."""
    plant = est.plant
    theta = np.zeros(plant.n_joints)
    for m, val in zip(est.measurements, y0):
        if m.kind == "joint_angle" and np.isfinite(val):
            theta[m.index] = val
    q = plant.q_from_joint_angles(theta)
    flex, nq, p = plant.flex_indices(), plant.nq, est.x[2 * plant.nq:]
    M = np.linalg.inv(plant.inverse_mass(q, p))

    def balance(qf):
        x = np.concatenate([q, np.zeros(nq), p])
        x[flex] = qf
        return (M @ plant.derivative(x, u0)[nq:2 * nq])[flex]
    qf = q[flex].copy()
    for _ in range(3):
        J = np.column_stack([(balance(qf + h) - balance(qf - h)) / 2e-7
                             for h in np.eye(len(flex)) * 1e-7])
        qf = qf - np.linalg.solve(J, balance(qf))
    q[flex] = qf
    return q


def _stack(samples, names) -> EstimationResult:
    arrays = {k: np.array([getattr(s, k) for s in samples]) for k in _STACKED}
    params = {n: np.array([s.parameters[n] for s in samples]) for n in names}
    pstd = {n: np.array([s.parameter_std[n] for s in samples]) for n in names}
    return EstimationResult(**arrays, parameters=params, parameter_std=pstd,
                            summary=summarize(arrays, params, pstd))


def summarize(arrays, params, pstd) -> dict:
    """nis_mean, nis_95_fraction, mean measurement dimension, final parameters."""
    nis, dof = arrays["nis"], arrays["nis_dof"]
    ok = np.isfinite(nis)
    inside = [n <= chi2_95(int(d)) for n, d in zip(nis[ok], dof[ok])]
    return {"samples": int(len(nis)), "nis_mean": float(np.mean(nis[ok])) if ok.any() else None,
            "nis_dof_mean": float(np.mean(dof[ok])) if ok.any() else None,
            "nis_95_fraction": float(np.mean(inside)) if inside else None,
            "parameters": {n: float(a[-1]) for n, a in params.items()},
            "parameter_std": {n: float(a[-1]) for n, a in pstd.items()}}
