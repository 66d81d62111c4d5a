"""Functions fit on a screen (issue 43; docs/development.md's code rules): no function of
the package sources (tests excluded) is longer than 150 lines, read with :mod:`ast`."""
from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"
LIMIT = 150
#: functions over the limit that are being split on other branches (issue 43): remove an
#: entry when its split is merged (the test fails while a listed function is short)
BEING_SPLIT = {"flex_twin/flex_twin/diagnosis/engine.py::diagnose"}


def function_lengths() -> dict[str, int]:
    """'package/module path::function' -> its lines (decorators excluded), every function
    and method of the package sources outside their test folders."""
    out = {}
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC)
        if "test" in rel.parts[:-1]:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out[f"{rel.as_posix()}::{node.name}"] = node.end_lineno - node.lineno + 1
    return out


def test_no_function_is_longer_than_150_lines():
    """Every function within LIMIT lines but those listed as being split, and each of those
    still over it (else the list is stale)."""
    lengths = function_lengths()
    assert len(lengths) > 1000          # the walk found the sources
    long = {name: n for name, n in lengths.items() if n > LIMIT}
    assert set(long) - BEING_SPLIT == set(), sorted(long.items())
    assert BEING_SPLIT - set(long) == set(), "split: remove from BEING_SPLIT"
