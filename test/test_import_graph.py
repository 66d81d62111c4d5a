"""The four packages import one way and without rings (issue 43): every ``import`` statement
of the package sources, lazy ones inside functions included, read with :mod:`ast`."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src"
PACKAGES = ("flex_model", "flex_control", "flex_planner", "flex_twin")
#: which package may import which (the README's package layout)
ALLOWED = {"flex_model": {"flex_model"},
           "flex_control": {"flex_control", "flex_model"},
           "flex_planner": {"flex_planner", "flex_model"},
           "flex_twin": set(PACKAGES)}


def module_files() -> dict[str, Path]:
    """Dotted module name -> source file, for every module of the four packages."""
    out = {}
    for package in PACKAGES:
        root = SRC / package
        for path in (root / package).rglob("*.py"):
            parts = path.relative_to(root).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


def imported_modules(name: str, path: Path, known: dict) -> set[str]:
    """The package modules that ``name`` imports anywhere in its file."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = name.split(".") if is_package else name.split(".")[:-1]
                parts = parts[:len(parts) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        found.update(t for t in targets if t in known and t != name)
    return found


def import_rings(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, rings = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            ring = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                ring.append(w)
                if w == v:
                    break
            if len(ring) > 1:
                rings.append(sorted(ring))

    for v in graph:
        if v not in index:
            visit(v)
    return rings


@pytest.fixture(scope="module")
def graph():
    files = module_files()
    return {name: imported_modules(name, path, files) for name, path in files.items()}


def test_the_graph_is_read(graph):
    """A reader that found nothing would pass the tests below: it finds the known edges."""
    assert len(graph) > 150
    assert "flex_model.spatial.description" in graph["flex_model.spatial.urdf"]
    assert "flex_model.command" in graph["flex_twin.cli"]


def test_no_import_rings(graph):
    assert import_rings(graph) == []


def test_rings_are_found():
    assert import_rings({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_packages_import_one_way(graph):
    wrong = [(m, t) for m, targets in graph.items() for t in targets
             if t.split(".")[0] not in ALLOWED[m.split(".")[0]]]
    assert wrong == []


def private_imports(files: dict) -> list[tuple[str, str]]:
    """(importer, module.name) for every ``from module import _name`` across modules."""
    found = []
    for name, path in files.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                hidden = [a.name for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
                found.extend((name, f"{node.module or '.'}.{h}") for h in hidden)
    return found


def test_no_private_names_imported_across_modules():
    """A module's private helpers stay private: what another module needs is public."""
    assert private_imports(module_files()) == []


def test_importing_the_numeric_core_changes_no_environment_variable():
    """Only a process that starts ROS sets ROS_AUTOMATIC_DISCOVERY_RANGE (just before
    rclpy.init); the core, used from plain Python, leaves the environment alone."""
    import os
    import subprocess
    import sys
    probe = ("import os; before = dict(os.environ)\n"
             "import flex_model, flex_model.dynamics, flex_model.simulate, flex_model.spatial\n"
             "import flex_model.ros\n"
             "import flex_control.laws, flex_planner.planning, flex_twin.diagnosis.engine\n"
             "changed = sorted(k for k in set(before) | set(os.environ)\n"
             "                 if before.get(k) != os.environ.get(k))\n"
             "print(changed)")
    env = {k: v for k, v in os.environ.items() if k != "ROS_AUTOMATIC_DISCOVERY_RANGE"}
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def imports_of(path: Path, top: str) -> list[str]:
    """The absolute imports of ``top`` or its modules anywhere in one file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] == top]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module and \
                node.module.split(".")[0] == top:
            found.append(node.module)
    return found


def test_no_package_module_imports_the_studies():
    """The one-off studies (studies/, issue 43) use the packages, never the other way."""
    wrong = {name: imports_of(path, "studies") for name, path in module_files().items()}
    assert {name: found for name, found in wrong.items() if found} == {}


def test_imports_of_the_studies_are_found(tmp_path):
    """The check above finds each form of the import, lazy ones too."""
    source = tmp_path / "m.py"
    source.write_text("import studies.servo_split\nfrom studies import run_floor\n"
                      "def f():\n    from studies.transfer import transfer\n"
                      "from .studies import x\nimport studiesx\n")
    assert sorted(imports_of(source, "studies")) == ["studies", "studies.servo_split",
                                                     "studies.transfer"]


#: ROS's Python modules (rclpy, the message packages, the IDL parser)
ROS_TOPS = re.compile(r"rclpy|rosidl_\w+|builtin_interfaces|rosgraph_msgs|\w+_msgs")
#: the node and ROS-message modules of the other packages (issue 43: flex_model's are its
#: subpackage flex_model.ros)
ROS_MODULES = {"flex_control.controller_node", "flex_control.ros_conversions",
               "flex_planner.planner_node", "flex_planner.ros_messages",
               "flex_twin.cli", "flex_twin.bag_cli", "flex_twin.bags.player",
               "flex_twin.bags.reader", "flex_twin.bags.recorder", "flex_twin.bags.writer",
               "flex_twin.ros_suite",
               "flex_twin.ros_twin_demo", "flex_twin.spatial_bags",
               "flex_twin.real_arms.ros_quanser_import"}


def in_ros(name: str) -> bool:
    return name == "flex_model.ros" or name.startswith("flex_model.ros.")


def ros_importers(files: dict) -> set[str]:
    """The modules that import ROS (or flex_model.ros) anywhere, lazily too."""
    return {name for name, path in files.items()
            if any(ROS_TOPS.fullmatch(t.split(".")[0]) or in_ros(t)
                   for t in _all_imports(path, name))}


def test_only_the_ros_adapters_import_ros():
    """flex_model's ROS adapters are its subpackage flex_model.ros (the ament convention);
    no other flex_model module imports ROS or flex_model.ros; the other packages import ROS
    only in their node and message modules (ROS_MODULES)."""
    found = ros_importers(module_files())
    outside = {n for n in found if not in_ros(n)} - ROS_MODULES
    assert outside == set(), outside
    assert {n for n in found if in_ros(n)} >= {"flex_model.ros.model_node",
                                               "flex_model.ros.observer_node"}


def test_a_lazy_ros_import_is_found(tmp_path):
    """The check above sees lazy and relative imports of ROS and of flex_model.ros."""
    (tmp_path / "a.py").write_text("def f():\n    from sensor_msgs.msg import Imu\n")
    (tmp_path / "b.py").write_text("def f():\n    from .ros import main\n")
    (tmp_path / "c.py").write_text("import numpy\nfrom .ros_like import x\n")
    files = {f"flex_model.{n}": tmp_path / f"{n}.py" for n in "abc"}
    assert ros_importers(files) == {"flex_model.a", "flex_model.b"}


def _all_imports(path: Path, name: str = "") -> list[str]:
    """Every module name an import statement of the file (module ``name``: relative
    imports resolved against it) names."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            out.append(node.module)
        elif isinstance(node, ast.ImportFrom) and name:
            parts = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
            parts = parts[:len(parts) - node.level + 1]
            out += [".".join(parts + ([node.module] if node.module else [a.name]))
                    for a in node.names]
    return out


#: the generalized-alpha formulas (issue 43: one solver layer): Chung-Hulbert's alpha_m,
#: alpha_f from rho_inf and the Arnold-Bruls update of abar from the iterate a1
GALPHA_FORMULAS = {"alpha_m": r"\(2(\.0)? \* rho_inf - 1(\.0)?\) / \(rho_inf \+ 1",
                   "alpha_f": r"rho_inf / \(rho_inf \+ 1",
                   "abar update": r"\(1(\.0)? - (c\.)?af\) \* a1"}
GALPHA_HOME = "flex_model.solvers.galpha"


def formula_sites(files: dict) -> dict[str, set[str]]:
    """Formula name -> the modules whose source writes it."""
    import re
    return {key: {name for name, path in files.items() if re.search(rx, path.read_text())}
            for key, rx in GALPHA_FORMULAS.items()}


def test_one_generalized_alpha_implementation():
    """Only flex_model.solvers.galpha writes the parameters of generalized-alpha and its
    update: every fixed-step loop (planar, exact kinematics, spatial, the planner's
    prescribed-motion loops) calls it."""
    sites = formula_sites(module_files())
    assert sites == {key: {GALPHA_HOME} for key in GALPHA_FORMULAS}


def test_one_newton():
    """Issue 43: the compiled loops' Newton iterations are solvers.loop.newton (and its
    simplified Newton): only it calls the planar backtracking and the spatial convergence
    tests; spatial.integrate.simulate_fixed, the Python reference, the second."""
    import re
    calls = {name for name, path in module_files().items()
             if re.search(r"(backtrack_done|spatial_converged)\(", path.read_text())}
    assert calls == {"flex_model.solvers.loop", "flex_model.solvers.newton",
                     "flex_model.spatial.integrate"}


def test_a_second_copy_of_the_formulas_is_found(tmp_path):
    copy = tmp_path / "copy.py"
    copy.write_text("am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)\naf = rho_inf / (rho_inf + 1)\n"
                    "abar1 = ((1 - af) * a1 + af * a - am * abar) / (1 - am)\n")
    assert formula_sites({"copy": copy}) == {key: {"copy"} for key in GALPHA_FORMULAS}
