"""Every command shown in README.md and docs/*.md exists as written (issue 26).

For each command line in a ```bash block of those pages:

* ``flex-twin ...``: the sub-command path exists in :func:`flex_twin.cli.build_parser`, its
  ``--help`` succeeds, every option used is an option of that sub-parser (spelled out, not
  an abbreviation), the whole line parses (choices, types, required arguments), and an arm
  or scenario given by name is a preset (:func:`flex_model.arm.preset_names`, the spatial
  presets,
  :func:`flex_model.scenario.scenario_names`);
* ``flex-model-node``, ``flex-controller-node``, ``flex-planner-node`` (and ``ros2 run PKG
  EXE``): the entry point is in the package's setup.py, and every ``-p name:=value`` names a
  parameter the node declares (read from the node modules without starting ROS); an ``arm``
  is a preset;
* ``make TARGET``: the target is in the Makefile;
* ``python bench/... | test/...``: the script exists;
* ``python -m studies.NAME ...``: the study exists (studies/NAME.py) and the line parses
  with its ``build_parser()`` as a ``flex-twin`` line does with its sub-parser; ``python -m``
  of a package module: the module exists. A sub-command that ``--help`` does not list (the
  moved studies' old names, which only point at ``studies/``) is no command to show.

Repository paths used as arguments (``ros2_ws/params/suite.yaml``) must exist, and so must
the pages' relative links, their anchors and the README's picture (under 200 KB). Lines
are split with shlex (``#`` comments dropped, ``\\`` continuations joined); ``[...]``
around optional arguments and ``...`` are tolerated. Negative cases at the end show that
typos fail. No ROS node is started.
"""
from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import importlib.util
import inspect
import io
import re
import shlex
from dataclasses import dataclass, fields
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
         ROOT / "studies" / "README.md"]
NODE_PACKAGES = {"flex-model-node": "flex_model", "model_node": "flex_model",
                 "flex-controller-node": "flex_control", "controller_node": "flex_control",
                 "flex-planner-node": "flex_planner", "planner_node": "flex_planner"}
#: parameters rclpy declares on every node
ROS_NODE_PARAMETERS = {"use_sim_time", "start_type_description_service"}
REPO_DIRS = ("ros2_ws/", "bench/", "test/", "src/", "docs/", "scripts/", "docker/",
             "studies/")
NUMBER = re.compile(r"^-\d|^-\.\d")


@dataclass(frozen=True)
class Command:
    where: str          # page:line
    argv: tuple


def _blocks(text: str):
    """(line number, line) of every line inside a ```bash block."""
    inside = False
    for n, line in enumerate(text.splitlines(), 1):
        fence = line.strip()
        if fence.startswith("```"):
            inside = not inside and fence[3:].strip() in ("bash", "sh", "shell")
            continue
        if inside:
            yield n, line


def split_commands(line: str) -> list[list[str]]:
    """The commands of one shell line: tokens without comments, env assignments, brackets
    of optional arguments and ``...``; split at ``&&``, ``;``, ``|``, ``||``."""
    out, cur = [], []
    for tok in shlex.split(line, comments=True):
        if tok in ("&&", ";", "|", "||"):
            out.append(cur)
            cur = []
            continue
        tok = tok.strip("[]")
        if tok and tok != "...":
            cur.append(tok)
    out.append(cur)
    cmds = []
    for c in out:
        while c and re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", c[0]):
            c = c[1:]                       # VAR=value prefix
        if c:
            cmds.append(c)
    return cmds


def page_commands(path: Path) -> list[Command]:
    cmds, pending, start = [], "", 0
    rel = path.relative_to(ROOT)
    for n, line in _blocks(path.read_text(encoding="utf-8")):
        if not pending:
            start = n
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        for argv in split_commands(pending + line):
            cmds.append(Command(f"{rel}:{start}", tuple(argv)))
        pending = ""
    return cmds


CHECKED = ("flex-twin", "make", "python", "python3", "ros2", *NODE_PACKAGES)
COMMANDS = [c for p in PAGES for c in page_commands(p)
            if c.argv[0] in CHECKED or c.argv[0].startswith("flex-")]


# ---- what exists --------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def flex_twin_parser() -> argparse.ArgumentParser:
    from flex_twin.cli import build_parser
    return build_parser()


@functools.lru_cache(maxsize=None)
def study_parser(name: str) -> argparse.ArgumentParser | None:
    """The parser of ``python -m studies.<name>`` (None: no such study or no parser)."""
    if not re.fullmatch(r"[a-z_]+", name) or not (ROOT / "studies" / f"{name}.py").is_file():
        return None
    module = importlib.import_module(f"studies.{name}")
    return module.build_parser() if hasattr(module, "build_parser") else None


@functools.lru_cache(maxsize=None)
def presets() -> tuple[set, set]:
    from flex_model.arm import preset_names
    from flex_model.scenario import scenario_names
    from flex_model.spatial.description import SPATIAL_PRESET_DIR
    spatial = {p.stem for p in SPATIAL_PRESET_DIR.glob("*.yaml")}
    return set(preset_names()) | spatial, set(scenario_names()) | set(scenario_names(spatial=True))


@functools.lru_cache(maxsize=None)
def entry_points(package: str) -> set:
    text = (ROOT / "src" / package / "setup.py").read_text(encoding="utf-8")
    return set(re.findall(r"['\"]\s*([\w.-]+)\s*=\s*[\w.]+:\w+\s*['\"]", text))


@functools.lru_cache(maxsize=None)
def node_parameters(package: str) -> set:
    """The parameter names a node declares, read from its module (rclpy is imported, no
    context or node is created)."""
    from flex_model.ros.main import lean_node
    lean = set(list(inspect.signature(lean_node).parameters)[1:])  # after ``node``
    if package == "flex_model":
        from flex_model.ros.model_node import PARAMETERS
        from flex_model.ros.observer_node import PARAMETERS as OBSERVER  # (-p mode:=observer)
        names = {p.name for p in PARAMETERS + OBSERVER}
    elif package == "flex_control":
        from flex_control.controller_node import NODE_PARAMETERS
        from flex_control.params import ControllerParams
        names = {f.name for f in fields(ControllerParams)} | {n for n, _ in NODE_PARAMETERS}
    else:
        from flex_planner.config import PlannerConfig
        names = {f.name for f in fields(PlannerConfig)}
    return names | lean | ROS_NODE_PARAMETERS


@functools.lru_cache(maxsize=None)
def make_targets() -> set:
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    return set(re.findall(r"^([A-Za-z0-9_-]+)\s*:(?!=)", text, re.M))


# ---- checks -------------------------------------------------------------------------------

def _is_name(value: str) -> bool:
    """A preset name rather than a path or a shell placeholder."""
    return bool(re.fullmatch(r"[A-Za-z0-9_]+", value))


def check_repo_paths(args) -> list[str]:
    return [f"{a}: no such file or directory in the repository" for a in args
            if a.startswith(REPO_DIRS) and not (ROOT / a).exists()]


def check_flex_twin(args) -> list[str]:
    parser = flex_twin_parser()
    node, path, rest = parser, [], list(args)
    while True:
        subs = [a for a in node._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            break
        if not rest or rest[0] not in subs[0].choices:
            got = rest[0] if rest else "nothing"
            return [f"flex-twin {' '.join(path)}: no sub-command {got!r} (choose from "
                    f"{', '.join(subs[0].choices)})"]
        path.append(rest.pop(0))
        node = subs[0].choices[path[-1]]
        listed = {a.dest for a in subs[0]._choices_actions}
        if path[-1] not in listed:
            return [f"flex-twin {' '.join(path)}: not listed by --help (the old name of a "
                    "moved study?)"]
    return check_parser(parser, path, node, rest, f"flex-twin {' '.join(path)}")


def check_parser(parser, path, node, rest, label) -> list[str]:
    """``label --help`` works, every option in ``rest`` is one of ``node`` (the sub-parser
    of ``path``), the line parses, arms and scenarios named are presets, paths exist."""
    errors = []
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            parser.parse_args([*path, "--help"])
            code = 0
        except SystemExit as exc:
            code = exc.code
    if code != 0 or "usage:" not in out.getvalue():
        errors.append(f"{label} --help failed: {err.getvalue().strip()}")
    for tok in rest:
        if tok.startswith("-") and tok != "-" and not NUMBER.match(tok):
            opt = tok.split("=", 1)[0]
            if opt not in node._option_string_actions:
                errors.append(f"{label}: no option {opt} (has "
                              f"{', '.join(sorted(node._option_string_actions))})")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            ns, extra = parser.parse_known_args([*path, *rest])
        except SystemExit:
            return errors + [f"{label}: {err.getvalue().strip()}"]
    if extra:
        errors.append(f"{label}: unrecognized arguments {extra}")
    arms, scenarios = presets()
    for attr, known, what in (("arm", arms, "arm preset"), ("scenario", scenarios, "scenario")):
        values = getattr(ns, attr, None)
        for v in values if isinstance(values, list) else [values]:
            if isinstance(v, str) and v in rest and _is_name(v) and v not in known:
                errors.append(f"{v}: no such {what} (have {', '.join(sorted(known))})")
    return errors + check_repo_paths(rest)


def check_node(exe, args, package=None) -> list[str]:
    package = package or NODE_PACKAGES[exe]
    if exe not in entry_points(package):
        return [f"{exe}: not an entry point of src/{package}/setup.py"]
    errors, declared = [], node_parameters(package)
    it = iter(args)
    for tok in it:
        if tok in ("-p", "--param"):
            name, _, value = next(it, "").partition(":=")
            if package == "flex_model" and name.startswith("controller_params."):
                name = "controller"  # the in-loop controller's own parameters
            if name not in declared:
                errors.append(f"{exe}: no parameter {name!r} (declares "
                              f"{', '.join(sorted(declared))})")
            elif name == "arm" and _is_name(value) and value not in presets()[0]:
                errors.append(f"{exe}: arm {value!r} is not a preset")
        elif tok == "--params-file":
            next(it, None)
        elif tok not in ("--ros-args", "-r", "--remap") and \
                not tok.startswith("__") and ":=" not in tok and not tok.startswith(REPO_DIRS):
            errors.append(f"{exe}: unexpected argument {tok!r}")
    return errors + check_repo_paths(args)


def check_python_module(module: str, rest: list) -> list[str]:
    """``python -m MODULE ...``: a study parses ``rest``; a package module exists."""
    if module.startswith("studies."):
        name = module.split(".", 1)[1]
        parser = study_parser(name)
        if parser is None:
            have = sorted(p.stem for p in (ROOT / "studies").glob("*.py")
                          if study_parser(p.stem) is not None)
            return [f"python -m {module}: no such study (have {', '.join(have)})"]
        return check_parser(parser, [], parser, rest, f"python -m {module}")
    if module.split(".")[0] in ("flex_model", "flex_control", "flex_planner", "flex_twin"):
        try:
            found = importlib.util.find_spec(module) is not None
        except ModuleNotFoundError:
            found = False
        if not found:
            return [f"python -m {module}: no such module"]
    return []


def check(argv) -> list[str]:
    cmd, args = argv[0], list(argv[1:])
    if cmd == "flex-twin":
        return check_flex_twin(args)
    if cmd in NODE_PACKAGES:
        return check_node(cmd, args)
    if cmd == "make":
        bad = [a for a in args if "=" not in a and not a.startswith("-")
               and a not in make_targets()]
        return [f"make {a}: no such target in the Makefile" for a in bad]
    if cmd in ("python", "python3"):
        errors = check_python_module(args[1], args[2:]) \
            if args[:1] == ["-m"] and len(args) >= 2 else []
        scripts = [a for a in args if a.endswith(".py")]
        return errors + [f"{a}: no such script" for a in scripts if not (ROOT / a).is_file()]
    if cmd == "ros2" and args[:1] == ["run"] and len(args) >= 3:
        package, exe, rest = args[1], args[2], args[3:]
        if not (ROOT / "src" / package / "setup.py").is_file():
            return [f"ros2 run {package}: no such package in src/"]
        if exe not in entry_points(package):
            return [f"ros2 run {package} {exe}: not an entry point of its setup.py"]
        if exe == "flex-twin":
            return check_flex_twin(rest)
        return check_node(exe, rest, package)
    if cmd.startswith("flex-"):
        return [f"{cmd}: no such command (flex-twin or a node entry point)"]
    return []


# ---- tests --------------------------------------------------------------------------------

def test_the_pages_show_commands():
    assert (ROOT / "docs").is_dir()
    studies = {c.argv[2] for c in COMMANDS if c.argv[1:2] == ("-m",)
               and c.argv[2].startswith("studies.")}
    assert len(studies) == 12
    shown = {c.argv[0] for c in COMMANDS}
    assert {"flex-twin", "make", "flex-model-node", "flex-controller-node",
            "flex-planner-node"} <= shown
    assert sum(c.argv[0] == "flex-twin" for c in COMMANDS) >= 40
    readme = [c.argv for c in COMMANDS if c.where.startswith("README.md")]
    assert ("make", "demo") in readme and ("make", "test") in readme


@pytest.mark.parametrize("command", COMMANDS, ids=[f"{c.where} {' '.join(c.argv[:3])}"[:60]
                                                   for c in COMMANDS])
def test_documented_command(command):
    errors = check(command.argv)
    assert not errors, f"{command.where}: {' '.join(command.argv)}\n  " + "\n  ".join(errors)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_links_and_pictures(page):
    text = page.read_text(encoding="utf-8")
    errors = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"^[a-z]+:", target):
            continue
        file, _, anchor = target.partition("#")
        dest = (page.parent / file).resolve() if file else page
        if not dest.exists():
            errors.append(f"{target}: no such file")
            continue
        if anchor and dest.suffix == ".md":
            headings = re.findall(r"^#+\s+(.*)$", dest.read_text(encoding="utf-8"), re.M)
            if anchor not in {_slug(h) for h in headings}:
                errors.append(f"{target}: no heading with that anchor in {dest.name}")
        if dest.suffix == ".png" and dest.stat().st_size >= 200_000:
            errors.append(f"{target}: {dest.stat().st_size} bytes (keep pictures < 200 KB)")
    assert not errors, f"{page.name}:\n  " + "\n  ".join(errors)


def test_readme_is_short():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) < 150


@pytest.mark.parametrize("line, message", [
    ("flex-twin mdoes thesis_example1", "no sub-command 'mdoes'"),
    ("flex-twin control desing thesis_example1", "no sub-command 'desing'"),
    ("flex-twin modes thesis_example1 --cuont 4", "no option --cuont"),
    ("flex-twin modes thesis_example1 --coun 4", "no option --coun"),        # abbreviation
    ("flex-twin static thesis_example1 --joints welded", "invalid choice"),
    ("flex-twin modes thesis_exampel1 --count 4", "thesis_exampel1: no such arm preset"),
    ("flex-twin simulate thesis_three_link_dp --method fixed", "no such scenario"),
    ("flex-twin control step --arm seed000_real_arm seed000_tabel3", "no such arm preset"),
    ("flex-twin up ros2_ws/params/suite.yml", "no such file"),
    ("flex-model-node --ros-args -p amr:=thesis_three_link", "no parameter 'amr'"),
    ("flex-model-node --ros-args -p arm:=thesis_tree_link", "is not a preset"),
    ("flex-controller-node --ros-args -p rate:=500.0", "no parameter 'rate'"),
    ("flex-planner-nod --ros-args -p arm:=thesis_example1", "no such command"),
    ("ros2 run flex_model modle_node", "not an entry point"),
    ("make tset", "no such target"),
    ("python bench/bench_section_F.py", "no such script"),
    ("python -m studies.servo_splt", "no such study"),
    ("python -m studies.command", "no such study"),                      # no parser
    ("python -m studies.servo_split --kt-tolernce 0.3", "no option --kt-tolernce"),
    ("python -m studies.servo_split --kt-tolerance x", "invalid float value"),
    ("python -m studies.transfer", "required"),
    ("python -m studies.stuck_holds --out studies/nowhere/x", "no such file"),
    ("python -m flex_twin.real_arms.servo_split", "no such module"),
    ("flex-twin real-arm servo-split", "not listed by --help"),
])
def test_a_typo_fails(line, message):
    (argv,) = split_commands(line)
    errors = check(argv)
    assert errors and any(message in e for e in errors), errors


def test_optional_brackets_comments_and_continuations():
    assert split_commands("flex-twin modes thesis_example1 [--json] ... # note") == \
        [["flex-twin", "modes", "thesis_example1", "--json"]]
    assert split_commands("ROS_DOMAIN_ID=91 make test && flex-twin presets") == \
        [["make", "test"], ["flex-twin", "presets"]]
    assert not check(("flex-twin", "modes", "thesis_example1", "--count", "4", "--json"))
