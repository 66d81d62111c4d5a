"""Sweeps on a real Dask cluster (the cluster fixture: conftest.py): the same results as the
local run, and a worker killed mid-run loses no result (issue 26; split from
test_dask_batch.py so that the two run on both pytest-xdist workers)."""
import os
import signal

import numpy as np
import pytest

from flex_twin.cluster import SerialExecutor, batch_executor
from flex_twin.sweep import run_sweep

pytest.importorskip("distributed")

SWEEP = ["payload.mass=0,0.5,1", "duration=0.4"]


def test_sweep_on_the_cluster_equals_the_local_run(cluster, tmp_path):
    sfile, _ = cluster
    local = run_sweep("seed002_step", SWEEP, tmp_path / "local", SerialExecutor(),
                      plot=False)
    with batch_executor(sfile) as ex:
        remote = run_sweep("seed002_step", SWEEP, tmp_path / "dask", ex, plot=False)
    assert [r["payload.mass"] for r in remote] == [0.0, 0.5, 1.0]
    for a, b in zip(local, remote):
        assert a["error"] == b["error"] == ""
        for k in ("tip_peak_deflection_m", "residual_vibration_m", "tip_final_error_m"):
            assert a[k] == b[k]  # the same computation, bit for bit
    # the payload reached the model: a heavier tip deflects less at the same step (it lags
    # the joints' motion, the arm being slower), by more than round-off
    peak = [r["tip_peak_deflection_m"] for r in remote]
    assert len(set(peak)) == 3


def test_a_worker_killed_mid_run_loses_no_result(cluster, tmp_path):
    """Six sweep points on two workers; one worker is SIGKILLed after the first result
    arrives, while it computes: Dask reruns its task on the other worker."""
    sfile, workers = cluster
    vary = ["payload.mass=0:1.25:0.25", "duration=0.6"]
    local = run_sweep("seed002_step", vary, tmp_path / "local", SerialExecutor(), plot=False)
    done = []

    def log(line):
        done.append(line)
        if len(done) == 1:
            os.killpg(workers[0].pid, signal.SIGKILL)

    with batch_executor(sfile) as ex:
        remote = run_sweep("seed002_step", vary, tmp_path / "dask", ex, plot=False, log=log)
    assert workers[0].wait(timeout=10) == -signal.SIGKILL
    assert len(remote) == 6 and all(r["error"] == "" for r in remote)
    np.testing.assert_array_equal([r["residual_vibration_m"] for r in remote],
                                  [r["residual_vibration_m"] for r in local])
