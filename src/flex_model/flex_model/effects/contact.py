"""Compliant environment at the tip: a one-sided spring-damper surface (seed 003)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import check_number
from .base import Effect, Parameter

#: the planar kernels' contact data (:meth:`ContactSurface.kernel_data`, inputs.InputData.
#: contact) by name: on, the plane's point (x, y), its normal (nx, ny), stiffness, damping
CT_ON, CT_X, CT_Y, CT_NX, CT_NY, CT_K, CT_C = range(7)


@dataclass(frozen=True)
class ContactSurface(Effect):
    """A surface through a point p0 with unit normal n pointing into the free side.
    Penetration of the tip p: delta = -n . (p - p0) > 0 gives the force

        F = max(0, k delta - c n . p') n       (never pulls; seed 003's environment force)

    applied at the tip (generalized force J_tip^T F). The contact force is an output.

    YAML (one effect type for planar and spatial arms): the planar fields ``x``, ``y``,
    ``normal_angle`` give p0 = (x, y, 0) and n = (cos a, sin a, 0): in 3D the plane that
    contains the z direction (a line in the planar x-y plane). A spatial arm may instead
    give the 3D fields ``z`` (m, p0 = (x, y, z)) and ``normal: [nx, ny, nz]``, normalised
    on load (a zero vector is refused; ``normal`` and ``normal_angle`` not both; the
    parameter normal_angle then holds atan2(ny, nx)). A planar arm accepts ``normal``
    only in its plane (nz = 0; dynamics.FlexArmModel).
    """

    TYPE = "contact_surface"
    TARGET = "arm"
    DESCRIPTION = "one-sided spring-damper surface touched by the tip"
    PARAMETERS = (
        Parameter("x", "m", 0.0, (-1e3, 1e3), 0.0, "a point of the surface"),
        Parameter("y", "m", -1e3, (-1e3, 1e3), 0.0, "a point of the surface"),
        Parameter("normal_angle", "rad", np.pi / 2, (-2 * np.pi, 2 * np.pi), 0.0,
                  "direction of the normal into the free side (pi/2: floor)"),
        Parameter("stiffness", "N/m", 0.0, (0.0, 1e12), 0.2, "k"),
        Parameter("damping", "N s/m", 0.0, (0.0, 1e9), 0.5, "c"),
    )
    EQUIVALENT = ("tip load (a constant force while in contact)",)

    #: the 3D fields (not diagnosis parameters): z of p0 (m) and the unit normal (empty:
    #: the planar normal_angle)
    z: float = 0.0
    normal: tuple = ()

    def plane(self) -> tuple:
        """(p0 (3), unit normal n (3), k, c) of the surface in 3D (module docstring)."""
        if self.normal:
            n = np.array(self.normal, float)
        else:
            a = self["normal_angle"]
            n = np.array([np.cos(a), np.sin(a), 0.0])
        return (np.array([self["x"], self["y"], self.z]), n, self["stiffness"],
                self["damping"])

    def kernel_data(self) -> np.ndarray:
        """(on, x, y, nx, ny, k, c) of the planar kernels (the in-plane normal)."""
        _, n, k, c = self.plane()
        return np.array([1.0, self["x"], self["y"], n[0], n[1], k, c])

    def force(self, tip, tip_velocity) -> np.ndarray:
        """Contact force vector (N) for a tip position and velocity (base frame; 2 or 3
        components, the result has as many)."""
        p0, n, k, c = self.plane()
        tip = np.asarray(tip, float)
        p0, n = p0[:len(tip)], n[:len(tip)]
        pen = -n @ (tip - p0)
        if pen <= 0:
            return np.zeros(len(tip))
        return max(0.0, k * pen - c * (n @ np.asarray(tip_velocity, float))) * n

    @classmethod
    def parse(cls, f, joint_names, link_names) -> "ContactSurface":
        """The Effect fields and the 3D ones (``z``, ``normal``; class docstring)."""
        z = f.number("z", 0.0, min_value=-1e3, max_value=1e3, unit="m") if f.has("z") \
            else 0.0
        normal = ()
        if f.has("normal"):
            if f.has("normal_angle"):
                raise f.error("normal", f.raw("normal"),
                              "normal or normal_angle, not both")
            n = np.array(f.vector("normal", 3, unit="a direction"), float)
            size = float(np.linalg.norm(n))
            if not size > 0.0:
                raise f.error("normal", f.raw("normal"),
                              "a non-zero 3-vector (the direction into the free side)")
            normal = tuple(float(v) for v in n / size)
        eff = super().parse(f, joint_names, link_names)
        values = list(eff.values)
        if normal:      # normal_angle: the in-plane direction (what the planar fields keep)
            values[2] = float(np.arctan2(normal[1], normal[0]))
        return cls(target=eff.target, values=tuple(values), z=z, normal=normal)

    @classmethod
    def check(cls, f, values) -> None:
        check_number(values[3], f.source, f.sub("stiffness"), positive=True, unit="N/m")
