"""flex_model.control_loop.compile_ahead one at a time per numba cache (issue 43, first
``make demo``): one started while another holds the cache's lock waits for it, then returns
without building a model (the other one's kernels are in the cache); a planner waits for
the shared kernels' lock (wait_for_shared_kernels)."""
import fcntl
import threading
import time

from flex_model import control_loop, dynamics


def test_a_second_compile_ahead_waits_for_the_first_and_compiles_nothing(tmp_path,
                                                                         monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))

    def no_model(*args, **kwargs):
        raise AssertionError("compiled although another compile_ahead held the lock")

    monkeypatch.setattr(dynamics, "FlexArmModel", no_model)
    done, errors, announced = [], [], []

    def second():
        try:
            control_loop.compile_ahead("thesis_example1_motors", 0.002,
                                       announce=lambda: announced.append(1))
        except AssertionError as exc:
            errors.append(exc)
        done.append(time.monotonic())

    with open(tmp_path / "flex_model-compile-ahead.lock", "w") as first:
        fcntl.flock(first, fcntl.LOCK_EX)
        t = threading.Thread(target=second)
        t.start()
        time.sleep(0.3)
        assert done == [] and announced == [1]   # waiting for the first, and said so
        released = time.monotonic()
    t.join(timeout=30)
    assert errors == [] and len(done) == 1 and done[0] >= released
    # alone, it builds the model (here: the stand-in that raises)
    alone_errors = []
    try:
        control_loop.compile_ahead("thesis_example1_motors", 0.002)
    except AssertionError as exc:
        alone_errors.append(exc)
    assert len(alone_errors) == 1


def test_wait_for_shared_kernels_returns_when_the_compiling_process_releases_them(
        tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    control_loop.wait_for_shared_kernels()   # nobody compiling: at once
    done = []
    with open(tmp_path / "flex_model-compile-ahead.shared.lock", "w") as core:
        fcntl.flock(core, fcntl.LOCK_EX)
        t = threading.Thread(target=lambda: done.append(control_loop.wait_for_shared_kernels()))
        t.start()
        time.sleep(0.3)
        assert done == []
    t.join(timeout=30)
    assert done == [None]
