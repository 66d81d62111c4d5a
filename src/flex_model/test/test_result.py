"""One result type (issue 43): every run path (planar variable, fixed and exact, spatial)
gives a flex_model.result.SimulationResult with the same status, columns and CSV."""
from __future__ import annotations

import dataclasses

import numpy as np

from flex_model.result import SimulationResult
from flex_model.scenario import load_scenario
from flex_model.solvers.status import FINISHED


def _short(name: str, **kw):
    sc = load_scenario(name)
    return dataclasses.replace(sc, duration=0.05, sample_period=0.01, **kw)


def test_every_run_path_gives_one_result(tmp_path):
    runs = {"variable": _short("seed002_step", method="variable"),
            "fixed": _short("seed002_step", method="fixed", step=1e-3),
            "spatial": _short("seed003_like_pd_step", step=1e-3)}
    for label, sc in runs.items():
        res = sc.run(advise=False)
        assert type(res) is SimulationResult and res.spatial == sc.spatial, label
        assert (res.status, res.message, res.advice) == (FINISHED, "finished", None)
        n = sc.arm.n_links
        assert res.joint_angles.shape == res.joint_rates.shape == (6, n)
        assert res.tip_positions.shape == (6, 3 if sc.spatial else 2)
        names, data = res.table()
        head = ["t"] + [f"{c}{i + 1}" for c in ("q", "v", "tau") for i in range(n)]
        assert names[:1 + 3 * n] == head
        assert "tip_x" in names and ("tip_z" in names) == sc.spatial
        res.to_csv(tmp_path / f"{label}.csv")
        back = np.loadtxt(tmp_path / f"{label}.csv", delimiter=",", skiprows=1)
        np.testing.assert_array_equal(back, data)      # %.17g: the doubles round-trip
        assert set(res.summary()) >= {"final_tip_m"}
