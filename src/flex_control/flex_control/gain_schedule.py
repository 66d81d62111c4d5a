"""Gain schedule of the Eq. (95) PD: designed (h, a) per joint at points of a trajectory.

Thesis V.2: "The global nonlinear control law is then calculated by interpolating the
controller gains in the various points of the trajectory. A controller is thus obtained,
whose gains are nonlinear functions of the rigid motion coordinates and, possibly, of some
measurable deformation coordinates."

Interpolation: inverse-distance weighting (Shepard) in the scheduling variables
``s = [theta; w * delta]`` (joint angles in rad, link tip deflections in m times the weight
``w`` in rad/m, zero by default)::

    g(s) = sum_k d_k^-p g_k / sum_k d_k^-p,   d_k = |s - s_k|_2,   g(s_k) = g_k,

which is continuous, returns the designed gains exactly at the design points and is a
convex combination of them everywhere (so interpolated gains never leave the designed
range). ``h`` and ``a`` are interpolated separately, so ``Kp = h a^2`` and
``Kd = sqrt(2) h a`` keep the structure of Eq. (95).

File format (YAML, SI units, angles in rad)::

    format: flex_control/gain_schedule/v1
    joint_names: [joint1, joint2]
    interpolation: {power: 2.0, deflection_weight_rad_per_m: 0.0}
    points:
      - {t_s: 0.0, theta_rad: [..], tip_deflections_m: [..], h: [..], a: [..]}
    info: {...}                  # free-form design record (arm, cost, figures per point)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from flex_model.config import ConfigError, Fields, read_yaml

SCHEDULE_FORMAT = "flex_control/gain_schedule/v1"


@dataclass(frozen=True, eq=False)
class GainSchedule:
    """Design points and their gains; :meth:`gains` interpolates (module doc).

    ``theta`` (P, n_joints) rad; ``h`` (P, n_joints) kg m^2 and ``a`` (P, n_joints) rad/s,
    both > 0; ``t`` (P,) s, optional; ``deflections`` (P, n_links) m, required when
    ``deflection_weight`` (rad/m) > 0; ``power`` > 0 of the inverse-distance weights.
    """

    joint_names: tuple
    theta: np.ndarray
    h: np.ndarray
    a: np.ndarray
    t: np.ndarray | None = None
    deflections: np.ndarray | None = None
    deflection_weight: float = 0.0
    power: float = 2.0
    info: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        names = tuple(str(n) for n in self.joint_names)
        nj = len(names)
        if nj == 0 or len(set(names)) != nj:
            raise ValueError(f"joint_names: got {list(names)}; expected unique names")
        object.__setattr__(self, "joint_names", names)
        theta = np.atleast_2d(np.asarray(self.theta, float))
        P = theta.shape[0]
        for name, value, positive in (("theta", theta, False), ("h", self.h, True),
                                      ("a", self.a, True)):
            arr = np.atleast_2d(np.asarray(value, float))
            if arr.shape != (P, nj) or not np.all(np.isfinite(arr)):
                raise ValueError(f"{name}: got shape {arr.shape}; expected ({P}, {nj}) "
                                 "finite values (one row per design point)")
            if positive and np.any(arr <= 0):
                raise ValueError(f"{name}: got {arr.min():g} at a design point; expected "
                                 "gains > 0")
            object.__setattr__(self, name, arr)
        if P < 1:
            raise ValueError("points: got 0 design points; expected at least 1")
        if self.t is not None:
            t = np.asarray(self.t, float).reshape(-1)
            if t.shape != (P,) or not np.all(np.isfinite(t)):
                raise ValueError(f"t: got shape {t.shape}; expected ({P},) finite times (s)")
            object.__setattr__(self, "t", t)
        if not (np.isfinite(self.power) and self.power > 0):
            raise ValueError(f"power: got {self.power!r}; expected a number > 0")
        if not (np.isfinite(self.deflection_weight) and self.deflection_weight >= 0):
            raise ValueError(f"deflection_weight: got {self.deflection_weight!r}; expected "
                             "a number >= 0 (rad/m)")
        if self.deflections is not None:
            d = np.atleast_2d(np.asarray(self.deflections, float))
            if d.shape[0] != P or not np.all(np.isfinite(d)):
                raise ValueError(f"deflections: got shape {d.shape}; expected ({P}, "
                                 "n_links) finite values (m)")
            object.__setattr__(self, "deflections", d)
        elif self.deflection_weight > 0:
            raise ValueError("deflections: got None; expected the design points' tip "
                             "deflections when deflection_weight > 0")
        object.__setattr__(self, "_points", self._scheduling(self.theta, self.deflections))
        object.__setattr__(self, "_ha", np.hstack([self.h, self.a]))

    # ----------------------------------------------------------------- evaluation
    @property
    def n_points(self) -> int:
        return self.theta.shape[0]

    def _scheduling(self, theta, deflections):
        if self.deflection_weight > 0:
            return np.hstack([theta, self.deflection_weight * deflections])
        return theta

    def gains(self, theta, deflections=None) -> tuple[np.ndarray, np.ndarray]:
        """``(h, a)`` per joint at joint angles ``theta`` (rad) and, when the schedule uses
        them, the link tip deflections (m; the design points' values if not given)."""
        theta = np.asarray(theta, float).reshape(-1)
        if theta.shape != (len(self.joint_names),):
            raise ValueError(f"theta: got {theta.shape[0]} values; expected "
                             f"{len(self.joint_names)} (joints {list(self.joint_names)})")
        if self.deflection_weight > 0:
            if deflections is None:
                d = self.deflections[int(np.argmin(np.sum((self.theta - theta) ** 2, 1)))]
            else:
                d = np.asarray(deflections, float).reshape(-1)
                if d.shape != (self.deflections.shape[1],):
                    raise ValueError(f"deflections: got {d.shape[0]} values; expected "
                                     f"{self.deflections.shape[1]} (one per link, m)")
            s = np.concatenate([theta, self.deflection_weight * d])
        else:
            s = theta
        diff = self._points - s
        d2 = np.einsum("ij,ij->i", diff, diff)
        k = int(d2.argmin())
        if d2[k] <= 1e-24:
            return self.h[k].copy(), self.a[k].copy()
        w = 1.0 / d2 if self.power == 2.0 else d2 ** (-0.5 * self.power)
        ha = (w / w.sum()) @ self._ha
        n = len(self.joint_names)
        return ha[:n], ha[n:]

    def max_gains(self) -> tuple[np.ndarray, np.ndarray]:
        """The thesis V.3 simplification: the largest h and a over the design points."""
        return self.h.max(axis=0), self.a.max(axis=0)

    # ----------------------------------------------------------------- YAML
    def to_dict(self) -> dict:
        points = []
        for k in range(self.n_points):
            p = {}
            if self.t is not None:
                p["t_s"] = float(self.t[k])
            p["theta_rad"] = [float(v) for v in self.theta[k]]
            if self.deflections is not None:
                p["tip_deflections_m"] = [float(v) for v in self.deflections[k]]
            p["h"] = [float(v) for v in self.h[k]]
            p["a"] = [float(v) for v in self.a[k]]
            points.append(p)
        return {"format": SCHEDULE_FORMAT, "joint_names": list(self.joint_names),
                "interpolation": {"power": float(self.power),
                                  "deflection_weight_rad_per_m": float(self.deflection_weight)},
                "points": points, "info": _plain(self.info)}

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(yaml.safe_dump(self.to_dict(), sort_keys=False, width=99))
        return path

    @classmethod
    def from_dict(cls, data, source: str = "<memory>") -> "GainSchedule":
        """Validate a parsed schedule; errors name the source, the field, the value and
        what is allowed."""
        f = Fields(data, source, "")
        fmt = f.string("format")
        if fmt != SCHEDULE_FORMAT:
            raise f.error("format", fmt, f"'{SCHEDULE_FORMAT}'")
        names = f.items("joint_names", min_len=1)
        if not all(isinstance(n, str) for n in names) or len(set(names)) != len(names):
            raise f.error("joint_names", names, "a list of unique joint names (strings)")
        nj = len(names)
        interp = f.mapping("interpolation", {})
        power = interp.number("power", 2.0, positive=True)
        weight = interp.number("deflection_weight_rad_per_m", 0.0, nonnegative=True,
                               unit="rad/m")
        interp.done()
        raw = f.items("points", min_len=1)
        t, theta, defl, h, a = [], [], [], [], []
        for k, r in enumerate(raw):
            pf = Fields(r, source, f"points[{k}]")
            if pf.has("t_s"):
                t.append(pf.number("t_s", unit="s"))
            theta.append(pf.vector("theta_rad", nj, unit="rad"))
            if pf.has("tip_deflections_m"):
                defl.append(pf.vector("tip_deflections_m", unit="m"))
            for key, out in (("h", h), ("a", a)):
                vals = pf.vector(key, nj)
                for i, v in enumerate(vals):
                    if not v > 0:
                        raise ConfigError(source, f"points[{k}].{key}[{i}]", v,
                                          "a gain > 0")
                out.append(vals)
            pf.done(["t_s", "theta_rad", "tip_deflections_m", "h", "a"])
        for key, lst in (("t_s", t), ("tip_deflections_m", defl)):
            if lst and len(lst) != len(raw):
                raise f.error("points", f"{len(lst)} of {len(raw)} points with {key}",
                              f"{key} on every point or on none")
        if defl and len({len(d) for d in defl}) != 1:
            raise f.error("points", [len(d) for d in defl],
                          "tip_deflections_m of the same length (one per link) on every point")
        if weight > 0 and not defl:
            raise ConfigError(source, "interpolation.deflection_weight_rad_per_m", weight,
                              "0 unless every point has tip_deflections_m")
        info = f.raw("info", {})
        if not isinstance(info, dict):
            raise f.error("info", info, "a mapping")
        f.done()
        return cls(joint_names=tuple(names), theta=np.array(theta), h=np.array(h),
                   a=np.array(a), t=np.array(t) if t else None,
                   deflections=np.array(defl) if defl else None, deflection_weight=weight,
                   power=power, info=info)

    @classmethod
    def load(cls, path) -> "GainSchedule":
        return cls.from_dict(read_yaml(path), str(path))


def _plain(obj):
    """Numpy scalars and arrays to plain YAML-safe Python."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
