"""Cross-section properties along a link: bending stiffness EI(z) and mass per length m(z).

A link is a list of segments; each segment has a cross-section whose dimensions are
constant or linearly tapered from the segment's root to its tip (thesis Ch. II,
Examples 2 and 4: piecewise-constant and tapered square hollow sections).

All quantities in SI units: lengths in m, E and G in Pa, rho in kg/m^3.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: Dimensions each shape takes (each a number or a [root, tip] pair), in metres.
SHAPE_DIMENSIONS = {
    "square_hollow": ("side", "wall"),
    "rectangular_hollow": ("width", "height", "wall"),
    "rectangular": ("width", "height"),
    "circular": ("diameter",),
    "circular_hollow": ("diameter", "wall"),
    "explicit": ("EI", "m"),
}

#: Shear factor chi of thesis Eq. (4) per shape (Timoshenko), used when not given.
DEFAULT_SHEAR_FACTOR = {
    "square_hollow": 2.0,
    "rectangular_hollow": 2.0,
    "rectangular": 1.2,
    "circular": 10.0 / 9.0,
    "circular_hollow": 2.0,
    "explicit": 1.2,
}


def area_and_inertia(shape: str, dims: dict, z_frac: np.ndarray):
    """Area A (m^2) and second moment I (m^4) about the bending axis at fractions of a segment.

    ``dims`` maps each dimension name to ``(root, tip)``; ``z_frac`` in [0, 1].
    Bending is about the axis normal to the plane of motion: ``height`` lies in the plane.
    """
    def d(name):
        a, b = dims[name]
        return a + (b - a) * z_frac

    if shape == "square_hollow":
        s, t = d("side"), d("wall")
        inner = s - 2 * t
        return s * s - inner * inner, (s**4 - inner**4) / 12.0
    if shape == "rectangular_hollow":
        w, h, t = d("width"), d("height"), d("wall")
        wi, hi = w - 2 * t, h - 2 * t
        return w * h - wi * hi, (w * h**3 - wi * hi**3) / 12.0
    if shape == "rectangular":
        w, h = d("width"), d("height")
        return w * h, w * h**3 / 12.0
    if shape == "circular":
        dd = d("diameter")
        return np.pi * dd**2 / 4.0, np.pi * dd**4 / 64.0
    if shape == "circular_hollow":
        dd, t = d("diameter"), d("wall")
        di = dd - 2 * t
        return np.pi * (dd**2 - di**2) / 4.0, np.pi * (dd**4 - di**4) / 64.0
    raise ValueError(f"unknown cross-section shape {shape!r}")


@dataclass(frozen=True)
class Segment:
    """A piece of a link with one cross-section law.

    ``dims`` maps dimension names to (root, tip) values; for shape ``explicit`` they are
    EI (N m^2) and m (kg/m) themselves and ``E``/``rho`` are unused.
    """

    length: float
    shape: str
    dims: dict
    E: float = 0.0
    rho: float = 0.0
    G: float = 0.0
    shear_factor: float = 0.0

    def scaled(self, stiffness: float = 1.0, mass: float = 1.0) -> "Segment":
        """This segment with E I times ``stiffness`` and the mass per length times ``mass``
        (E and rho of a material section, EI and m of an ``explicit`` one)."""
        if self.shape == "explicit":
            return replace(self, dims=dict(self.dims,
                                           EI=tuple(stiffness * v for v in self.dims["EI"]),
                                           m=tuple(mass * v for v in self.dims["m"])))
        return replace(self, E=stiffness * self.E, rho=mass * self.rho)

    @property
    def tapered(self) -> bool:
        return any(abs(a - b) > 0.0 for a, b in self.dims.values())

    def properties(self, z_frac):
        """Return (EI, m, GA/chi) at fractions ``z_frac`` of the segment (arrays)."""
        z_frac = np.asarray(z_frac, dtype=float)
        if self.shape == "explicit":
            ei0, ei1 = self.dims["EI"]
            m0, m1 = self.dims["m"]
            ei = ei0 + (ei1 - ei0) * z_frac
            m = m0 + (m1 - m0) * z_frac
            ga = np.full_like(z_frac, np.inf)
            if "GA" in self.dims:
                g0, g1 = self.dims["GA"]
                ga = (g0 + (g1 - g0) * z_frac) / (self.shear_factor or 1.0)
            return ei, m, ga
        area, inertia = area_and_inertia(self.shape, self.dims, z_frac)
        chi = self.shear_factor or DEFAULT_SHEAR_FACTOR[self.shape]
        ga = self.G * area / chi if self.G > 0 else np.full_like(z_frac, np.inf)
        return self.E * inertia, self.rho * area, ga


class SectionProfile:
    """EI(z), m(z) and GA(z)/chi along a whole link made of consecutive segments."""

    def __init__(self, segments: list[Segment]):
        self.segments = list(segments)
        self.breaks = np.concatenate([[0.0], np.cumsum([s.length for s in self.segments])])

    @property
    def length(self) -> float:
        return float(self.breaks[-1])

    def properties(self, z):
        """(EI, m, GA/chi) at positions ``z`` (m from the link root), arrays."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        idx = np.clip(np.searchsorted(self.breaks, z, side="right") - 1, 0,
                      len(self.segments) - 1)
        ei = np.empty_like(z)
        m = np.empty_like(z)
        ga = np.empty_like(z)
        for k, seg in enumerate(self.segments):
            sel = idx == k
            if np.any(sel):
                frac = (z[sel] - self.breaks[k]) / seg.length
                ei[sel], m[sel], ga[sel] = seg.properties(frac)
        return ei, m, ga

    def property_on_piece(self, k: int, z):
        """Properties evaluated with segment ``k``'s law (for quadrature inside a piece)."""
        seg = self.segments[k]
        return seg.properties((np.asarray(z) - self.breaks[k]) / seg.length)
