"""Bad inputs to ``flex-twin diagnose`` (issue 21): each is refused before any replay with
one line on stderr that names the file and the field, and exit code 2 (the suite's
convention, :func:`flex_model.command.run_command`)."""
import pytest
import yaml

from flex_twin.cli import main

ARM = "thesis_example1_motors"     # a two-link preset
PD = {"law": "pd", "kp": [200.0, 80.0], "kd": [20.0, 8.0], "period": 0.002,
      "feedforward": "none"}
HEADER = ["t", "q1", "q2", "v1", "v2", "tau1", "tau2", "qset1", "qset2"]


def _rows(n=100, dt=0.002):
    return [[k * dt, 0.1, 0.0, 0.0, 0.0, 1.0, 0.2, 0.1, 0.0] for k in range(n)]


def _csv(path, rows, header=HEADER):
    path.write_text(",".join(header) + "\n"
                    + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


def _controller(path, **change):
    path.write_text(yaml.safe_dump({"controller": dict(PD, **change)}))
    return path


def _refusal(capsys, data, ctl, tmp_path) -> str:
    """Run the CLI; assert exit 2, one line, no traceback; return that line."""
    code = main(["diagnose", str(data), "--arm", ARM, "--controller", str(ctl),
                 "--out", str(tmp_path / "out"), "--no-plots"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    assert not (tmp_path / "out" / "report.md").exists()
    return err[0]


def test_unknown_controller_law_names_file_field_and_the_laws(tmp_path, capsys):
    ctl = _controller(tmp_path / "ctl.yaml", law="pid")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", _rows()), ctl, tmp_path)
    assert "ctl.yaml" in line and "law" in line and "'pid'" in line
    assert "pd" in line and "state_feedback" in line      # what is allowed


def test_run_shorter_than_one_control_step(tmp_path, capsys):
    # 100 samples at 2 ms (0.198 s) under a law sampled every 0.5 s: not one step
    ctl = _controller(tmp_path / "ctl.yaml", period=0.5)
    line = _refusal(capsys, _csv(tmp_path / "run.csv", _rows()), ctl, tmp_path)
    assert "run.csv" in line and "t:" in line
    assert "0.198 s" in line and "one control step (0.5 s" in line


def test_run_of_too_few_samples(tmp_path, capsys):
    ctl = _controller(tmp_path / "ctl.yaml")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", _rows(3)), ctl, tmp_path)
    assert "run.csv" in line and "3 samples" in line


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_nan_row_names_channel_and_sample(tmp_path, capsys, value):
    rows = _rows()
    rows[37] = [rows[37][0]] + [value] * (len(HEADER) - 1)
    ctl = _controller(tmp_path / "ctl.yaml")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", rows), ctl, tmp_path)
    assert "run.csv" in line and "channel q1" in line
    assert "sample 37" in line and "t = 0.074 s" in line


def test_missing_columns_are_named(tmp_path, capsys):
    header = [h for h in HEADER if h not in ("tau2", "qset1")]
    rows = [[v for h, v in zip(HEADER, r) if h in header] for r in _rows()]
    ctl = _controller(tmp_path / "ctl.yaml")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", rows, header), ctl, tmp_path)
    assert "run.csv" in line and "missing channel(s) tau2, qset1" in line


def test_missing_time_column(tmp_path, capsys):
    rows = [r[1:] for r in _rows()]
    ctl = _controller(tmp_path / "ctl.yaml")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", rows, HEADER[1:]), ctl, tmp_path)
    assert "run.csv" in line and "no 't' column" in line


@pytest.mark.parametrize("swap", [True, False])
def test_non_monotonic_time(tmp_path, capsys, swap):
    rows = _rows()
    if swap:      # two samples out of order
        rows[50][0], rows[51][0] = rows[51][0], rows[50][0]
    else:         # a repeated time stamp
        rows[51][0] = rows[50][0]
    ctl = _controller(tmp_path / "ctl.yaml")
    line = _refusal(capsys, _csv(tmp_path / "run.csv", rows), ctl, tmp_path)
    assert "run.csv" in line and "t is not increasing (sample 51)" in line


def test_bad_holdout_is_named_too(tmp_path, capsys):
    rows = _rows()
    rows[20][3] = "nan"      # v1
    data = _csv(tmp_path / "run.csv", _rows())
    ho = _csv(tmp_path / "held.csv", rows)
    ctl = _controller(tmp_path / "ctl.yaml")
    code = main(["diagnose", str(data), "--holdout", str(ho), "--arm", ARM, "--controller",
                 str(ctl), "--out", str(tmp_path / "out"), "--no-plots"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "held.csv" in err[0] and "channel v1" in err[0] and "sample 20" in err[0]
