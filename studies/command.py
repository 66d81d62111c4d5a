"""What the studies' command lines share: a ``python -m studies.<name>`` parser and the
package's exit codes (:func:`flex_model.command.run_command`: 0 done, 2 bad input, 1 a
failed computation)."""
from __future__ import annotations

import argparse

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
