"""Batch work on a real Dask cluster: a scheduler and two workers as separate processes on
127.0.0.1 (issue 26; the cluster fixture: conftest.py). Two diagnoses give the same results
as the local run; bad inputs and the CLI's manifest. The sweeps on the cluster:
test_dask_batch_sweep.py."""
import pytest

from flex_twin.cluster import SerialExecutor, batch_executor, check_scheduler
from flex_twin.diagnosis.batch import RunSpec, diagnose_many, expand_runs
from flex_twin.sweep import run_sweep

pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """Two short synthetic healthy runs (different units and noise: seeds 1000, 1001)."""
    from flex_twin.diagnosis.synthetic import generate_case
    d = tmp_path_factory.mktemp("cases")
    runs = []
    for seed in (1000, 1001):
        c = generate_case("healthy", seed, d / f"unit{seed}", duration=3.0)
        runs.append(RunSpec(f"unit{seed}", str(c.fit_csv), str(c.nominal_arm),
                            str(c.controller), str(c.holdout_csv)))
    return runs


def _same_rows(a, b):
    assert [r["run"] for r in a] == [r["run"] for r in b]
    for ra, rb in zip(a, b):
        assert ra["error"] == rb["error"] == ""
        assert ra["verdict"] == rb["verdict"] and ra.get("named") == rb.get("named")
        for k in ("nominal_holdout_J", "final_holdout_J", "holdout_error_reduction"):
            assert ra[k] == pytest.approx(rb[k], rel=1e-9, abs=1e-12)


def test_diagnoses_on_the_cluster_equal_the_local_run(cluster, cases, tmp_path):
    sfile, _ = cluster
    # floor=False: twin-made runs have no model-form floor (test_diagnosis_floor.py tests it)
    local = diagnose_many(cases, tmp_path / "local", SerialExecutor(), plots=False,
                          log=lambda s: None, floor=False)
    with batch_executor(sfile) as ex:
        remote = diagnose_many(cases, tmp_path / "dask", ex, plots=False, log=lambda s: None,
                               floor=False)
    _same_rows(local, remote)
    # the baseline recalibration brings each healthy unit's held-out error down; every run
    # has its report and a summary row
    assert all(r["final_holdout_J"] < r["nominal_holdout_J"] for r in remote)
    for r in cases:
        assert (tmp_path / "dask" / r.name / "diagnosis.json").is_file()
    assert (tmp_path / "dask" / "summary.csv").read_text().count("\n") == 1 + len(cases)


def test_bad_inputs_get_one_line(tmp_path):
    with pytest.raises(ValueError, match="expected an address such as tcp://"):
        check_scheduler("127.0.0.1:8786")
    with pytest.raises(ValueError, match="no Dask scheduler answered"):
        with batch_executor("tcp://127.0.0.1:9", timeout=2):
            pass
    with pytest.raises(ValueError, match="--arm and --controller are needed"):
        (tmp_path / "a.csv").write_text("t\n")
        expand_runs([str(tmp_path)], None, None)
    with pytest.raises(FileNotFoundError, match="no such run"):
        expand_runs([str(tmp_path / "missing.csv")], "a", "c")
    with pytest.raises(ValueError, match="start:stop:step"):
        run_sweep("seed002_step", ["payload.mass=2:0:0.5"], tmp_path, SerialExecutor())
    with pytest.raises(ValueError, match=r"control.nope.kp\[0\]: no field"):
        run_sweep("seed002_step", ["control.nope.kp[0]=1"], tmp_path, SerialExecutor())


def test_the_cli_takes_a_manifest_and_reports_every_run(tmp_path, capsys):
    """flex-twin diagnose MANIFEST: a run that cannot be read is a row with its error (the
    others go on); all failed: exit 1; --holdout with several runs: one line, exit 2."""
    from flex_twin.cli import main
    (tmp_path / "runs.yaml").write_text(
        "runs:\n  - {name: gone, data: missing.csv, arm: thesis_example1_motors,\n"
        "     controller: c.yaml}\n")
    assert main(["diagnose", str(tmp_path / "runs.yaml"), "--out", str(tmp_path / "o"),
                 "--workers", "1"]) == 1
    summary = (tmp_path / "o" / "summary.csv").read_text()
    assert "gone,error," in summary and "c.yaml'; expected a readable file" in summary
    assert main(["diagnose", str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--holdout",
                 "h.csv", "--arm", "x", "--controller", "y"]) == 2
    assert "--holdout names the held-out recording of a single run" in capsys.readouterr().err
