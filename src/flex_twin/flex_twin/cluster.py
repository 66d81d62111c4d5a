"""Where batch work runs: the local process pool (default) or a Dask distributed cluster.

Every batch tool (``flex-twin diagnose`` of many runs, ``flex-twin sweep``, the hypothesis
fits of one diagnosis) takes an *executor*: anything with ``map(fn, *iterables)`` (results in
order) and ``submit(fn, *args)`` returning a ``concurrent.futures.Future``. Locally that is a
``ProcessPoolExecutor`` on the available cores (serial on one core); with
``--scheduler tcp://HOST:PORT`` (or a scheduler file written by ``dask scheduler
--scheduler-file F``) it is the ``concurrent.futures`` interface of a Dask distributed
``Client``. Dask reschedules the tasks of a worker that dies on the other workers, so a
killed worker loses no result.

Start a cluster (on the machines that will do the work)::

    dask scheduler --host 10.0.0.5 --port 8786
    dask worker tcp://10.0.0.5:8786 --nworkers 2 --nthreads 1   # on each machine

Workers need this project installed (the same versions: constraints.txt) and, for
recordings given by path, the same paths (a shared file system).
"""
from __future__ import annotations

import os
import re
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path

_ADDRESS = re.compile(r"^(tcp|tls|inproc|ucx|ws|wss)://[^\s/]+(:\d+)?/?$")


class SerialExecutor:
    """The executor interface without parallelism (``map`` in order, ``submit`` at once)."""

    def map(self, fn, *iterables):
        return map(fn, *iterables)

    def submit(self, fn, *args):
        from concurrent.futures import Future
        f = Future()
        try:
            f.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001 (delivered through the future, as a pool does)
            f.set_exception(exc)
        return f


def local_executor(workers: int | None = None):
    """A process pool on the available cores (serial with one core or ``workers=1``)."""
    n = workers or len(os.sched_getaffinity(0))
    return SerialExecutor() if n <= 1 else ProcessPoolExecutor(max_workers=n)


def check_scheduler(scheduler: str) -> str:
    """A scheduler address (``tcp://host:port``) or an existing scheduler file; else one
    line naming what is allowed."""
    if _ADDRESS.match(scheduler) or Path(scheduler).is_file():
        return scheduler
    raise ValueError(f"--scheduler: got {scheduler!r}; expected an address such as "
                     "tcp://127.0.0.1:8786 or the path of a scheduler file (dask scheduler "
                     "--scheduler-file FILE)")


@contextmanager
def batch_executor(scheduler: str | None = None, workers: int | None = None,
                   timeout: float = 30.0):
    """The executor for batch work (a context manager that shuts it down afterwards)."""
    if not scheduler:
        if workers is not None and workers < 1:
            raise ValueError(f"--workers: got {workers}; expected >= 1")
        ex = local_executor(workers)
        try:
            yield ex
        finally:
            if hasattr(ex, "shutdown"):
                ex.shutdown(cancel_futures=True)
        return
    check_scheduler(scheduler)
    try:
        from distributed import Client
    except ImportError as exc:  # pragma: no cover - a pinned dependency
        raise ValueError(f"--scheduler needs Dask distributed (pip install distributed): "
                         f"{exc}") from None
    kwargs = {"scheduler_file": scheduler} if Path(scheduler).is_file() else \
        {"address": scheduler}
    try:
        client = Client(timeout=timeout, **kwargs)
    except OSError as exc:
        raise ValueError(f"--scheduler {scheduler}: no Dask scheduler answered within "
                         f"{timeout:g} s ({exc})") from None
    try:
        yield client.get_executor(pure=False)
    finally:
        client.close()
