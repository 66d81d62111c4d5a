"""A measured experiment: uniformly sampled channels read from a CSV file (or a bag, see
:mod:`flex_twin.diagnosis.ros_recording`), validated before any computation: the columns
``t, q<i>, v<i>, tau<i>, qset<i>`` (required) and ``w<i>, wz<i>, phi<i>, tip_x, tip_y,
tau_ff<i>, ql<i>, vl<i>`` (optional), the ``# start_window`` comment line and the refusals
(:class:`RecordingError`, a ``ValueError``): docs/diagnosis.md ("The workflow").
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: the residual channels the replay predicts, in this order, per joint/link index
MEASURED_KINDS = ("q", "v", "tau", "w", "wz", "phi")
MIN_SAMPLES = 50
#: optional link-side encoder channels of elastic joints (angle, rate), paired
LINK_KINDS = ("ql", "vl")


class RecordingError(ValueError):
    """The measured data cannot be used; the message says which file and why."""


@dataclass
class Recording:
    """Uniformly sampled measurements: ``t`` (s) and named channels (SI)."""

    t: np.ndarray
    channels: dict
    n_joints: int
    source: str = "<memory>"
    meta: dict = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    def stack(self, kind: str) -> np.ndarray:
        """(n_samples, n_joints) of ``q``, ``v``, ``tau``, ``qset``, ``w`` or ``tau_ff``."""
        return np.column_stack([self.channels[f"{kind}{i + 1}"] for i in range(self.n_joints)])

    def has(self, name: str) -> bool:
        return name in self.channels

    def link_encoders(self) -> list[int]:
        """Joints (0-based) with a link-side encoder (``ql<i>`` and ``vl<i>``)."""
        return [i for i in range(self.n_joints) if f"ql{i + 1}" in self.channels]

    @property
    def residual_channels(self) -> list[str]:
        """Measured channels the diagnosis compares with the twin."""
        names = [f"{k}{i + 1}" for k in MEASURED_KINDS for i in range(self.n_joints)]
        names += ["tip_x", "tip_y"]
        return [n for n in names if n in self.channels]

    def window(self, t0: float, t1: float) -> "Recording":
        """The samples with t0 <= t <= t1 (times kept)."""
        sel = (self.t >= t0 - 1e-12) & (self.t <= t1 + 1e-12)
        return Recording(self.t[sel], {k: v[sel] for k, v in self.channels.items()},
                         self.n_joints, self.source, dict(self.meta))


def validate(t, channels: dict, n_joints: int, source: str) -> Recording:
    """Check channels, finiteness and uniform sampling; return the Recording."""
    t = np.asarray(t, float)
    required = [f"{k}{i + 1}" for k in ("q", "v", "tau", "qset") for i in range(n_joints)]
    missing = [n for n in required if n not in channels]
    if missing:
        raise RecordingError(f"{source}: missing channel(s) {', '.join(missing)} "
                             f"(the {n_joints}-joint arm needs q, v, tau, qset per joint)")
    if len(t) < MIN_SAMPLES:
        raise RecordingError(f"{source}: {len(t)} samples; need at least {MIN_SAMPLES}")
    for name in channels:
        kind = name.rstrip("0123456789")
        if kind in LINK_KINDS:
            i = name[len(kind):]
            if not i.isdigit() or not 1 <= int(i) <= n_joints:
                raise RecordingError(f"{source}: channel {name}: no joint {i or '(none)'} "
                                     f"(link-side encoders ql<i>, vl<i>, i = 1..{n_joints})")
            other = ("vl" if kind == "ql" else "ql") + i
            if other not in channels:
                raise RecordingError(f"{source}: channel {name} without {other} (a link-side "
                                     "encoder needs both its angle ql<i> and rate vl<i>)")
    for name, values in channels.items():
        bad = ~np.isfinite(values)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise RecordingError(f"{source}: channel {name}: non-finite value at sample {k} "
                                 f"(t = {t[k]:.6g} s)")
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not dt > 0 or np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) if np.any(steps <= 0) else 0
        raise RecordingError(f"{source}: t is not increasing (sample {k + 1})")
    if np.max(np.abs(steps - dt)) > 1e-3 * dt:
        k = int(np.argmax(np.abs(steps - dt)))
        raise RecordingError(f"{source}: non-uniform sampling at sample {k + 1} (step "
                             f"{steps[k]:.6g} s, median {dt:.6g} s); resample first")
    return Recording(t, {k: np.asarray(v, float) for k, v in channels.items()}, n_joints,
                     source)


def load_csv(path, n_joints: int) -> Recording:
    """Read a CSV with the documented columns (module docstring)."""
    path = Path(path)
    try:
        with open(path, newline="") as stream:
            rows = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise RecordingError(f"{path}: cannot read ({exc})") from None
    meta = _directives(rows, path)
    rows = [r for r in rows if r and not r[0].startswith("#")]
    if not rows:
        raise RecordingError(f"{path}: empty file")
    header = [h.strip() for h in rows[0]]
    if "t" not in header:
        raise RecordingError(f"{path}: no 't' column in the header ({', '.join(header)})")
    if len(set(header)) != len(header):
        raise RecordingError(f"{path}: duplicate column names in the header")
    data = np.empty((len(rows) - 1, len(header)))
    for k, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise RecordingError(f"{path}: line {k + 2}: {len(row)} fields, header has "
                                 f"{len(header)} (truncated or corrupt file)")
        try:
            data[k] = [float(x) for x in row]
        except ValueError:
            raise RecordingError(f"{path}: line {k + 2}: a field is not a number") from None
    channels = {h: data[:, j] for j, h in enumerate(header) if h != "t"}
    rec = validate(data[:, header.index("t")], channels, n_joints, str(path))
    rec.meta.update(meta)
    return rec


#: comment-line settings a CSV may carry (``# name: value``), with their check
DIRECTIVES = {"start_window": "a number of seconds >= 0"}


def _directives(rows, path) -> dict:
    """``# start_window: <s>`` comment lines -> {"start_window": s}, validated."""
    out = {}
    for r in rows:
        if not r or not r[0].startswith("#"):
            continue
        text = ",".join(r).lstrip("#").strip()
        name, sep, value = text.partition(":")
        if not sep or name.strip() not in DIRECTIVES:
            continue   # an ordinary comment
        name = name.strip()
        out[name] = directive_value(name, value, path)
    return out


def directive_value(name: str, value, source) -> float:
    """A setting of :data:`DIRECTIVES` (a CSV comment line, a bag's metadata
    ``custom_data``) as a number, checked."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = float("nan")
    if not (np.isfinite(x) and x >= 0):
        raise RecordingError(f"{source}: {name}: {str(value).strip()!r} is not "
                             f"{DIRECTIVES[name]}")
    return x


def save_csv(rec: Recording, path) -> None:
    """Write a Recording in the documented CSV layout."""
    names = list(rec.channels)
    head = "".join(f"# {k}: {rec.meta[k]!r}\n" for k in DIRECTIVES if k in rec.meta)
    np.savetxt(path, np.column_stack([rec.t] + [rec.channels[n] for n in names]),
               delimiter=",", header=head + ",".join(["t"] + names), comments="",
               fmt="%.12g")
