"""What the studies share: a ``python -m studies.<name>`` parser with the package's exit
codes (:func:`flex_model.command.run_command`: 0 done, 2 bad input, 1 a failed
computation) and their outputs (:func:`write_study`: markdown and JSON)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from flex_model.command import run_command


def study_parser(module: str, description: str) -> argparse.ArgumentParser:
    """The parser of ``python -m studies.<module>``."""
    return argparse.ArgumentParser(prog=f"python -m studies.{module}",
                                   description=description)


def add_batch_options(parser, out: str) -> None:
    """--out, --workers, --scheduler and --json of a study run on the batch executor."""
    parser.add_argument("--out", default=out, help="output directory")
    parser.add_argument("--workers", type=int, default=None, help="parallel processes")
    parser.add_argument("--scheduler", default=None, help="a Dask scheduler address or file "
                        "(default: processes on this machine; its workers need the "
                        "repository root on their PYTHONPATH)")
    parser.add_argument("--json", action="store_true")


def run_study(parser: argparse.ArgumentParser, argv=None) -> int:
    """Parse ``argv`` (default: the command line) and run the study's ``func``."""
    return run_command(parser.parse_args(argv))


def write_study(out, stem: str, report: dict, lines: list) -> Path:
    """``<stem>.json`` (the report) and ``<stem>.md`` (the markdown ``lines``) in ``out``
    (created); returns the markdown's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{stem}.json").write_text(json.dumps(report, indent=1, default=float))
    (out / f"{stem}.md").write_text("\n".join(lines) + "\n")
    return out / f"{stem}.md"
