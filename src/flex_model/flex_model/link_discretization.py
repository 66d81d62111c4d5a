"""The basis a link description asks for: its ``discretization`` (wavelet functions of the
thesis Ch. II are the default, :mod:`flex_model.basis`; the seeds' alternatives in
:mod:`flex_model.discretizations` and :mod:`flex_model.lumped`) with its options."""
from __future__ import annotations

from .discretizations import assumed_modes_basis, fem_basis, ritz_basis
from .lumped import lumped_basis


def discretized_basis(link, payload_mass: float = 0.0, payload_inertia: float = 0.0):
    """The basis a link description asks for (``discretization`` and its options); the
    payload counts as tip mass of clamped_mass modes unless tip_mass is given."""
    disc, n = link.discretization, link.n_vars
    if disc == "fem":
        return fem_basis(link.profile, n // 2)
    if disc == "ritz_polynomials":
        return ritz_basis(link.profile, n)
    tip_m = link.M_plus + payload_mass if link.tip_mass is None else link.tip_mass
    tip_j = link.J_plus + payload_inertia if link.tip_inertia is None else link.tip_inertia
    if disc == "lumped":
        return lumped_basis(link.profile, n, link.mode_type, tip_m, tip_j)
    if disc in ("assumed_modes", "optimized_modes"):
        return assumed_modes_basis(link.profile, n, link.mode_type, tip_m, tip_j, kind=disc)
    raise ValueError(f"discretization {disc!r} has no basis builder")
