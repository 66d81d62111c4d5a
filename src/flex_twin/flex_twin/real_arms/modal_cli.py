"""``flex-twin cantilever`` and ``flex-twin frequency-gap`` moved out of the package (issue
43): ``python -m studies.cantilever`` and ``python -m studies.frequency_gap``; the old names
only say so (:data:`.cli.MOVED_COMMANDS`)."""
from __future__ import annotations

from .cli import MOVED_COMMANDS, add_moved_studies


def add_modal_parsers(sub) -> None:
    """The old ``cantilever`` and ``frequency-gap`` sub-commands, pointing at studies/."""
    add_moved_studies(sub, MOVED_COMMANDS, prefix="", listed=True)
