"""Fixtures of flex_twin's tests: a real Dask cluster on 127.0.0.1 (test_dask_batch*.py; each
module starts its own, so pytest-xdist's --dist loadfile can run the files on both workers)."""
import os
import signal
import subprocess
import sys
import time

import pytest


def _spawn(args, log):
    return subprocess.Popen([sys.executable, "-m", *args], stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(scheduler file, worker processes): scheduler and two single-threaded workers without
    nanny (a killed worker stays dead), all on 127.0.0.1."""
    from distributed import Client
    d = tmp_path_factory.mktemp("dask")
    sfile = d / "scheduler.json"
    log = open(d / "cluster.log", "w")
    procs = [_spawn(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                     "--scheduler-file", str(sfile), "--no-dashboard"], log)]
    deadline = time.monotonic() + 60
    while not sfile.exists():
        assert time.monotonic() < deadline, "the Dask scheduler did not start"
        time.sleep(0.2)
    workers = [_spawn(["distributed.cli.dask_worker", "--scheduler-file", str(sfile),
                       "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny",
                       "--no-dashboard", "--name", f"w{k}"], log) for k in (1, 2)]
    procs += workers
    try:
        with Client(scheduler_file=str(sfile), timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
            assert all(v["host"] == "127.0.0.1" for v in c.scheduler_info()["workers"].values()
                       ) or all("127.0.0.1" in a for a in c.scheduler_info()["workers"])
        yield str(sfile), workers
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
        log.close()
