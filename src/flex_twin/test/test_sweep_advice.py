"""The sweep checks the step advice once when its points share the discretization, and at
every point when it varies the discretization (flex_twin.sweep.DISCRETIZATION): the check
runs the scenario's window about ten times over, and on Dask workers a warning per point
would be lost."""
import json

from flex_model.scenario import Scenario
from flex_twin.cluster import SerialExecutor
from flex_twin.sweep import run_sweep


def _counting(monkeypatch):
    calls = []
    real = Scenario.advice

    def advice(self, *a, **kw):
        calls.append(self.source)
        return real(self, *a, **kw)
    monkeypatch.setattr(Scenario, "advice", advice)
    return calls


def test_one_check_for_points_of_one_discretization(monkeypatch, tmp_path):
    calls = _counting(monkeypatch)
    rows = run_sweep("seed002_step", ["payload.mass=0,0.5,1", "duration=0.1"], tmp_path,
                     SerialExecutor(), plot=False)
    assert len(calls) == 1 and [r["error"] for r in rows] == ["", "", ""]
    assert [r["advice"] for r in rows] == ["", "", ""]
    assert "advice" in json.loads((tmp_path / "sweep.json").read_text())


def test_a_check_per_point_when_the_sweep_varies_the_discretization(monkeypatch, tmp_path):
    calls = _counting(monkeypatch)
    rows = run_sweep("seed002_step", ["integrator.rtol=1e-3,1e-6", "duration=0.1"],
                     tmp_path, SerialExecutor(), plot=False)
    assert len(calls) == 2 and [r["error"] for r in rows] == ["", ""]
    assert json.loads((tmp_path / "sweep.json").read_text())["advice"] is None
