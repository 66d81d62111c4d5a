"""Does the hub stick? Per-run stiction evidence of the CU Boulder Quanser logs (issue 22).

A hub is *stuck* at a sample when its logged angle moves at most :data:`STUCK_TRAVEL` over
the centred window of :data:`STUCK_WINDOW` s around it (one encoder count, 2 pi / 4096 =
1.53 mrad, shows as 1 or 2 mrad in the 3-decimal log). Per hold (from a reference step
to the next step or to the end of the run), over its stuck samples:

- ``stuck_fraction`` of the hold (without its first :data:`STUCK_WINDOW` s: a hub at
  rest when the step comes is not held yet) and ``stick_after_s``, the time from the
  step until the hub first sticks;
- ``error_rad`` r - theta and ``voltage_V`` (means), the motor's holding torque
  ``motor_torque_Nm`` = n K_t V / R (at rest: no back-EMF; the handout's n = 48.4,
  K_t = 0.0107 N m/A, R = 3.29 ohm, 0.157 N m/V);
- ``root_moment_Nm``: the peak of the link's moment on the hub, 3 EI d / L^2 (static
  cantilever, d the tip deflection about the gauge bias; handout EI 0.2496 N m^2,
  L 0.45 m: 3.7 mN m per mm), and ``held_torque_Nm``, the largest |motor torque + root
  moment| held still: a lower bound of the break-away torque;
- ``slips``: stuck intervals that end before the next step (the hub broke free within
  the hold: stick-slip cycles) and ``slip_torque_Nm``, the torque when the first did.

The diagnosis compares a twin's replay with the data; whether the replay can show the
sticking depends on where the twin stops, not only on whether the data stick
(:func:`run_statistics` gives the figures of docs/real-arm-studies.md).
"""
from __future__ import annotations

import numpy as np

#: travel of a stuck hub over the window (rad): one encoder count as logged to 1 mrad
STUCK_TRAVEL = 2.0e-3
#: centred window of the stuck test (s)
STUCK_WINDOW = 0.1
#: the handout's torque per volt at rest, n K_t / R (N m/V), and the link (EI, L)
TORQUE_PER_VOLT = 48.4 * 0.0107 / 3.29
LINK_EI = 0.24956
LINK_LENGTH = 0.45


def stuck_mask(run, window: float = STUCK_WINDOW, travel: float = STUCK_TRAVEL) -> np.ndarray:
    """Per sample: the hub angle's range over the centred ``window`` is at most
    ``travel`` (samples within half a window of either end: False)."""
    from numpy.lib.stride_tricks import sliding_window_view
    half = max(1, int(round(0.5 * window / run.dt)))
    out = np.zeros(len(run.t), bool)
    if len(run.t) > 2 * half:
        out[half:-half] = np.ptp(sliding_window_view(run.theta, 2 * half + 1), axis=1) <= travel
    return out


def intervals(mask) -> list:
    """[start, stop) of the runs of True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def hold_statistics(run, torque_per_volt: float = TORQUE_PER_VOLT, ei: float = LINK_EI,
                    length: float = LINK_LENGTH) -> list:
    """Per hold of the run, the figures of the module docstring (dicts; a hold in which
    the hub never sticks has ``stuck_fraction`` 0 and no other figure)."""
    stuck = stuck_mask(run)
    d = run.deflection - run.gauge_bias() if run.has_gauge else np.zeros(len(run.t))
    moment = 3.0 * ei * run.gauge_sign() * d / length ** 2
    tau_m = torque_per_volt * run.voltage
    half = max(1, int(round(0.5 * STUCK_WINDOW / run.dt)))
    out = []
    for a0, b in run.holds():
        a = min(a0 + 2 * half, b - 1) if a0 > 0 else a0   # the step's break-away excluded
        s = stuck[a:b]
        h = {"t_step": float(run.t[a0]), "duration_s": float(run.t[b - 1] - run.t[a0]),
             "direction": float(np.sign(run.reference[a0] - run.reference[max(a0 - 1, 0)])),
             "stuck_fraction": float(np.mean(s))}
        if s.any():
            k = np.flatnonzero(s) + a
            tot = tau_m[k] + moment[k]
            ends = [(i0 + a, i1 + a) for i0, i1 in intervals(s) if i1 + a < b - half]
            h.update(stick_after_s=float(run.t[k[0]] - run.t[a0]),
                     error_rad=float(np.mean(run.reference[k] - run.theta[k])),
                     voltage_V=float(np.mean(run.voltage[k])),
                     motor_torque_Nm=float(np.mean(tau_m[k])),
                     root_moment_Nm=float(np.max(np.abs(moment[k]))),
                     held_torque_Nm=float(np.max(np.abs(tot))),
                     slips=len(ends),
                     slip_torque_Nm=(float(abs(tau_m[ends[0][1]] + moment[ends[0][1]]))
                                     if ends else None))
        out.append(h)
    return out


def run_statistics(run) -> dict:
    """The run's stuck fraction (the whole log), its holds (:func:`hold_statistics`) and
    the largest torque held still over them (N m)."""
    holds = hold_statistics(run)
    held = [h["held_torque_Nm"] for h in holds if "held_torque_Nm" in h]
    return {"run": run.name, "gains": [float(k) for k in run.gains],
            "stuck_fraction": float(np.mean(stuck_mask(run))), "holds": holds,
            "held_torque_Nm": max(held) if held else None}


def markdown_rows(stats: list) -> list:
    """Markdown table rows, one per hold: run, step time and direction, stuck share,
    hold error, voltage, motor torque, root moment, torque held, slips."""
    rows = ["| run | hold from (dir.) | stuck | after | r - theta | V | n K_t V / R | "
            "root moment peak | torque held | slips |", "|---" * 10 + "|"]
    for st in stats:
        for h in st["holds"]:
            head = f"| {st['run']} | {h['t_step']:.2f} s ({h['direction']:+.0f}) | " \
                   f"{100 * h['stuck_fraction']:.0f} % |"
            if "error_rad" not in h:
                rows.append(head + " - | - | - | - | - | - | 0 |")
                continue
            rows.append(head + f" {h['stick_after_s']:.2f} s | {1e3 * h['error_rad']:+.1f} mrad | "
                        f"{h['voltage_V']:+.3f} V | {1e3 * h['motor_torque_Nm']:+.1f} mN m | "
                        f"{1e3 * h['root_moment_Nm']:.1f} mN m | "
                        f"{1e3 * h['held_torque_Nm']:.1f} mN m | {h['slips']} |")
    return rows


def cmd_holds_table(args) -> int:
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    from flex_twin.real_arms.quanser_twin import data_root
    runs = read_cuboulder(data_root(args.data) / CUBOULDER)
    names = args.runs or [n for n, r in runs.items() if r.kind == "flexible"]
    print("\n".join(markdown_rows([run_statistics(runs[n]) for n in names])))
    return 0


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("stiction_evidence", "per hold of each CU Boulder run: stuck "
                          "share, hold error, voltage, torques, slips (a markdown table)")
    parser.add_argument("runs", nargs="*", help="run names (default: every flexible-link "
                        "run)")
    add_data_option(parser)
    parser.set_defaults(func=cmd_holds_table)
    return parser


def main(argv=None) -> int:
    """``python -m studies.stiction_evidence [RUN ...]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
