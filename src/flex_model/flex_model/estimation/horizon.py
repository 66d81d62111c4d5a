"""Moving-horizon least squares of the adapted parameters beside the filter (issue 45).

The identity d/dt (B(q) v) = B a + B' v holds along any motion; integrated over a block of
samples [k0, k1] (the input held over each sample, left rectangles) on the actuator rows Ga:

    e(p) = Ga [(B v)(k1) - (B v)(k0)] - T sum_{k0 <= k < k1} Ga (B a(x_k, u_k; p) + B' v)_k

is zero when the model's acceleration a (Eq. 27 with every joint effect: the model's own
friction law, flex_model.estimation.plant) is the arm's. x_k: the filter's corrected
estimates. e is affine in the joint frictions (the generalized forces are), so
e(p) = e_0 + R p with e_0 = e(0) and R's columns e(unit) - e_0 (the other adapted
parameters at the filter's values):
the parameters minimizing sum |e|^2 over the blocks of the last ``horizon`` s, with the
initial values and stds as a Gaussian prior and the residuals' variance estimated from the
window (per actuator row), are linear least squares. On the base joint's row no elastic
force appears (the links' stiffness acts on their own rows): the fit does not lean on the
estimated deflections' forces, and it is no Kalman gain's doing, so the process noise the
filter is given (its bias: Ljung 1979) does not enter it. The payload is left to the
filter's random walk: the balance is affine in its mass too, but the base row's residual
then follows the filter's own payload (held at 0 on the payload-change run the fit says
0.02 kg, held at the true 0.3 it says 0.28: docs/estimation.md).

While the fit catches up after a change it moves block by block; the filter, which takes
the fitted values as exact between fits, is then overconfident. ``spread``: the fit's
moves over the window, which the filter adds as process noise on the momentum rows the
parameters act on (each parameter error held over a sample through the model's own
Jacobian column df/dp, Estimator.relinearize): the bands widen while the fit moves and
narrow once the window holds no moves (docs/estimation.md, "Coverage while the fit
catches up").
"""
from __future__ import annotations

from collections import deque

import numpy as np

from .plant import PARAMETER_FLOOR

#: the kinds the horizon fit adapts (the others stay the filter's random walks)
HORIZON_KINDS = ("coulomb_friction", "viscous_friction")


class HorizonFit:
    """Blocks of ``block`` s, the last ``horizon`` s of them fitted at each block's end."""

    def __init__(self, plant, horizon, block, sample_period, prior_mean, prior_std):
        if plant.spatial:
            raise ValueError("adapt_horizon: spatial arms not supported; expected 0")
        self.index = np.array([k for k, (kind, _) in enumerate(plant.params)
                               if kind in HORIZON_KINDS], int)
        self.plant, self.T = plant, float(sample_period)
        self.block_n = max(int(round(block / sample_period)), 1)
        self.blocks = deque(maxlen=max(int(round(horizon / block)), 1))
        npar = len(self.index)
        self.variants = np.vstack([np.zeros(npar), np.eye(npar)])
        self.prior_mean = np.asarray(prior_mean, float)[self.index]
        self.prior_var = np.square(np.asarray(prior_std, float))[self.index]
        self.floor = np.array([PARAMETER_FLOOR[plant.params[k][0]] for k in self.index])
        self.sigma2 = None
        self._start, self._sum, self._count = None, None, 0
        self.last = self.prior_mean.copy()
        self.moves = deque(maxlen=self.blocks.maxlen)   # the fit's moves over the window

    def _terms(self, x, u):
        """(momentum, its rate) on the actuator rows for each parameter variant."""
        at, out = 2 * self.plant.nq + self.index, []
        for p in self.variants:
            xv = x.copy()
            xv[at] = p
            out.append(self.plant.momentum_terms(xv, u))
        return np.array([m for m, _ in out]), np.array([g for _, g in out])

    def add(self, x, u):
        """The corrected estimate x at a sample and the input held after it: at a block's
        end the fit of the window, (the fitted parameters, covariance); else None."""
        m, g = self._terms(x, u)
        fit = None
        if self._start is not None and self._count == self.block_n:
            e = m - self._start - self._sum             # (variants, actuator rows)
            self.blocks.append((e[0], (e[1:] - e[0]).T))
            fit = self.solve()
            self._start = None
        if self._start is None:
            self._start, self._sum, self._count = m, np.zeros_like(g), 0
        self._sum = self._sum + self.T * g
        self._count += 1
        return fit

    def solve(self):
        """The window's least squares with the prior, each actuator row weighted by its own
        residuals' variance (the rows' model errors differ); parameters onto their floors."""
        e0 = np.array([b[0] for b in self.blocks])          # (blocks, rows)
        R = np.array([b[1] for b in self.blocks])           # (blocks, rows, parameters)
        if self.sigma2 is None:      # the first window: its residuals about the prior
            self.sigma2 = self._row_variance(e0 + R @ self.prior_mean, 0)
        w = 1.0 / self.sigma2
        info = np.einsum("brp,r,brq->pq", R, w, R) + np.diag(1.0 / self.prior_var)
        rhs = -np.einsum("brp,r,br->p", R, w, e0) + self.prior_mean / self.prior_var
        cov = np.linalg.inv(info)
        p = np.maximum(cov @ rhs, self.floor)
        self.sigma2 = self._row_variance(e0 + R @ p, R.shape[2])
        self.moves.append(p - self.last)
        self.last = p
        return p, cov

    def spread(self) -> np.ndarray:
        """Per parameter, the variance the filter gives its error while the fit moves:
        the squared moves between consecutive fits over the window, summed, times
        block_n (a parameter error held over a block moves the momentum as block_n^2
        samples of it, white noise of the same variance as block_n: the variance as
        white torque noise per sample is block_n times the move's square)."""
        return self.block_n * np.sum(np.square(self.moves), axis=0)

    @staticmethod
    def _row_variance(residual, npar):
        """Each row's residual variance over the window (floored: no division by 0)."""
        dof = max(residual.shape[0] - npar / residual.shape[1], 1.0)
        return np.maximum(np.sum(np.square(residual), axis=0) / dof, 1e-30)
