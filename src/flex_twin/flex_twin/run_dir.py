"""Where a command writes its outputs: ``--out`` as given, else ``runs/<time>-<name>``."""
from __future__ import annotations

from datetime import datetime
from pathlib import Path


def run_dir(base: str | None, name: str) -> Path:
    """The output directory (created): ``base``, or ``runs/YYYYmmdd-HHMMSS-<name>``."""
    path = Path(base) if base else Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}-{name}"
    path.mkdir(parents=True, exist_ok=True)
    return path
