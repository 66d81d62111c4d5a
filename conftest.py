"""Session-wide test setup for flex-twin.

Runs at import time, i.e. before any test module (or anything it imports) loads rclpy:
* ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (forced): DDS discovery must never leave this host.
* ROS_DOMAIN_ID: per run (derived from the pytest pid, 1..101) unless already set, so that
  concurrent runs on one machine do not see each other. 1..101 keeps Fast DDS's port ranges
  clear of the Linux ephemeral port range.
* ROS_PYTHON_CHECK_FIELDS=1: generated message classes check field types on assignment.
* NUMBA_OPT=1 (unless set): LLVM's -O1 instead of numba's -O3. A fresh clone compiles every
  kernel once; at -O1 that takes about a third less time (generalized_alpha 92 against 141
  s, the diagnosis replay 24 against 35 s, under load), the compiled code runs as fast on
  these kernels (a 20 s replay 0.55 against 0.53 CPU-s, a 20 s fixed-step run 0.42 against
  0.43 CPU-s) and computes the same numbers (no fast-math: IEEE results do not depend on
  the optimization level). Subprocesses (process pools, Dask workers, nodes) inherit it.
  Its kernels are cached apart (NUMBA_CACHE_DIR=.numba_test_cache unless set).

When a session collects most of the suite, test/numba_warmup.py compiles the loops that
later tests need in a background process (the second core; FLEX_TWIN_NUMBA_WARMUP=0: off),
except under pytest-xdist (``make test`` runs two workers, ``-n 2 --dist loadfile``: the two
workers keep both cores busy; each worker gets a ROS_DOMAIN_ID of its own, 50 apart).
"""
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; RANGE above is authoritative
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))
#: pytest-xdist worker index (make test runs two workers: gw0, gw1); -1 without xdist
XDIST_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw-1")[2:])
if XDIST_WORKER > 0:   # each worker a domain of its own, 50 apart, still in 1..101
    os.environ["ROS_DOMAIN_ID"] = str(1 + (int(os.environ["ROS_DOMAIN_ID"]) - 1
                                           + 50 * XDIST_WORKER) % 101)
os.environ.setdefault("ROS_PYTHON_CHECK_FIELDS", "1")
if "NUMBA_OPT" not in os.environ:
    os.environ["NUMBA_OPT"] = "1"
    # numba's cache index does not record the optimization level: -O1 kernels in the
    # packages' __pycache__ would be loaded by the user's runs (the in-loop core at a
    # real-time factor of 27 instead of 44); the tests keep their own cache
    os.environ.setdefault("NUMBA_CACHE_DIR",
                          str(Path(__file__).resolve().parent / ".numba_test_cache"))


def _log_compiles(folder: str) -> None:
    """FLEX_TWIN_COMPILE_LOG=folder: each test process appends one line per numba compile
    (pid, worker, wall start and end, own and inclusive CPU s, function, signature) to
    folder/<pid>.tsv; ``python bench/bench_compile.py --log folder`` sums them up."""
    import time

    from numba.core import event
    out = open(Path(folder) / f"{os.getpid()}.tsv", "a", buffering=1)  # noqa: SIM115
    stack = []

    class Log(event.Listener):
        def on_start(self, ev):
            stack.append([time.time(), time.process_time(), 0.0])

        def on_end(self, ev):
            w0, c0, inner = stack.pop()
            dt = time.process_time() - c0
            if stack:
                stack[-1][2] += dt
            f = ev.data["dispatcher"].py_func
            sig = ",".join(str(a) for a in ev.data["args"]).replace("\t", " ")
            out.write(f"{os.getpid()}\t{XDIST_WORKER}\t{w0:.3f}\t{time.time():.3f}\t"
                      f"{dt - inner:.3f}\t{dt:.3f}\t{f.__module__}.{f.__qualname__}\t"
                      f"{sig[:3000]}\n")

    event.register("numba:compile", Log())


if os.environ.get("FLEX_TWIN_COMPILE_LOG"):
    _log_compiles(os.environ["FLEX_TWIN_COMPILE_LOG"])

if "rclpy" in sys.modules:  # e.g. a pytest plugin imported it before this conftest
    warnings.warn("rclpy was imported before conftest.py set the ROS environment",
                  RuntimeWarning, stacklevel=1)

REPO_ROOT = Path(__file__).resolve().parent
if str(REPO_ROOT) not in sys.path:   # studies/ (python -m studies.X from the root) for its tests
    sys.path.insert(0, str(REPO_ROOT))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The checkout's root directory."""
    return REPO_ROOT


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the checkout (reference data); skips the test when it is absent."""
    path = REPO_ROOT.parent / "shared"
    if not path.is_dir():
        pytest.skip(f"../shared not found beside the checkout: {path}")
    return path


@pytest.fixture(scope="session")
def cuboulder_root(shared_dir) -> Path:
    """The CU Boulder Quanser lab logs in ../shared/data/real (skips when they are absent)."""
    path = shared_dir / "data" / "real" / "quanser_rotary_flexible_link_cuboulder"
    if not path.is_dir():
        pytest.skip(f"no {path}")
    return path


#: a session with at least this many tests is "most of the suite" (the warm-up pays off)
WARMUP_MIN_TESTS = 300


def pytest_collection_finish(session):
    if len(session.items) < WARMUP_MIN_TESTS or XDIST_WORKER >= 0 or \
            os.environ.get("FLEX_TWIN_NUMBA_WARMUP", "1") == "0":
        return
    session.config._numba_warmup = subprocess.Popen(
        [sys.executable, str(REPO_ROOT / "test" / "numba_warmup.py")],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True)


#: "on": the acceptance tier runs too (bench/bench_acceptance.py); "full": with its costliest
ACCEPTANCE_ENV = "FLEX_TWIN_ACCEPTANCE"


def pytest_collection_modifyitems(config, items):
    """Tests marked ``acceptance`` (minutes of diagnosis each) run only with
    FLEX_TWIN_ACCEPTANCE=on|full: ``python bench/bench_acceptance.py`` runs and prints them."""
    if os.environ.get(ACCEPTANCE_ENV) in ("on", "full"):
        return
    skip = pytest.mark.skip(reason=f"acceptance tier: python bench/bench_acceptance.py "
                                   f"({ACCEPTANCE_ENV}=on)")
    for item in items:
        if "acceptance" in item.keywords:
            item.add_marker(skip)


def pytest_sessionfinish(session):
    proc = getattr(session.config, "_numba_warmup", None)
    if proc is not None and proc.poll() is None:
        proc.kill()
        proc.wait()


class RosGraph:
    """The tests' ROS harness: a private context and namespace ``ns``, a probe node and
    the nodes under test (``factory(**kwargs)`` with the parameters ``params``, if
    given, as ``node``; more with ``add``), spun by one SingleThreadedExecutor.
    ``subscribe`` collects a topic's messages in a list; ``spin_until`` waits
    ``timeout`` s unless told."""

    timeout = 10.0

    def __init__(self, factory=None, params=None, prefix: str = "t", args=None):
        import uuid

        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, args=args)
        self.ns = f"/{prefix}{uuid.uuid4().hex[:8]}"
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.nodes, self.node = [], None
        try:
            if factory is not None:
                self.node = self.make(factory, **params)
        except BaseException:
            self.close()
            raise
        # the node's topics are relative: the probe in its namespace uses the same names
        self.probe = self.add(rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}",
                                                context=self.ctx, namespace=self.ns))

    def make(self, factory, namespace: str | None = None, **params):
        """A node ``factory(...)`` of this context in ``namespace`` (default ``ns``) with
        the parameters ``params``, spun with the others."""
        from rclpy.parameter import Parameter
        return self.add(factory(context=self.ctx, namespace=namespace or self.ns,
                                parameter_overrides=[Parameter(k, value=v)
                                                     for k, v in params.items()]))

    def add(self, node):
        self.nodes.append(node)
        self.ex.add_node(node)
        return node

    def remove(self, node) -> None:
        self.ex.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    def subscribe(self, msg_type, topic: str, qos=10) -> list:
        got = []
        self.probe.create_subscription(msg_type, topic, got.append, qos)
        return got

    def spin_until(self, pred, what: str, timeout: float | None = None) -> None:
        import time
        end = time.monotonic() + (timeout or self.timeout)
        while not pred():
            assert time.monotonic() < end, f"timed out waiting for {what}"
            self.ex.spin_once(timeout_sec=0.005)

    def spin_for(self, seconds: float, step: float = 0.005) -> None:
        import time
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=step)

    def call(self, client, request, timeout: float | None = None):
        """The answer of a service ``client`` to ``request``."""
        self.spin_until(client.service_is_ready, f"the service {client.srv_name}", timeout)
        future = client.call_async(request)
        self.spin_until(future.done, f"the answer of {client.srv_name}", timeout)
        return future.result()

    def discovered(self, publisher, timeout: float | None = None) -> None:
        """Spin until the node subscribes to the probe's ``publisher``."""
        self.spin_until(lambda: publisher.get_subscription_count() > 0, "discovery", timeout)

    def close(self) -> None:
        import rclpy
        self.ex.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.fixture
def ros_graph():
    """``ros_graph(factory, prefix, args=None, **params)``: a :class:`RosGraph` (factory
    None: no node yet), closed after the test."""
    made = []

    def make(factory=None, prefix: str = "t", args=None, **params) -> RosGraph:
        made.append(RosGraph(factory, params, prefix, args))
        return made[-1]
    yield make
    for graph in made:
        graph.close()
