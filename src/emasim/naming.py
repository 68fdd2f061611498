"""Default names of what emasim writes: ``runs/<scenario>/<what>-<YYYYmmdd-HHMMSS>``, with
``-2``, ``-3``... when the name is taken (:func:`numbered`, which
:func:`emasim.output.write_folder` walks too when another process takes a fresh name first)."""

import datetime
import os
from collections.abc import Iterator
from pathlib import Path

from .errors import OutputError

RUNS_ROOT = Path("runs")


def slug(label: str) -> str:
    """A folder name for a label or a scenario name: lower-case letters, digits and dashes."""
    return "".join(ch if ch.isalnum() else "-" for ch in label.lower()).strip("-") or "run"


def stamp() -> str:
    """Local time to the second, for folder names: ``YYYYmmdd-HHMMSS``."""
    return datetime.datetime.now().strftime("%Y%m%d-%H%M%S")


def numbered(root: Path, stem: str, suffix: str = "") -> Iterator[Path]:
    """``root/<stem><suffix>``, then ``root/<stem>-2<suffix>``, ``-3``... up to ``-999``."""
    yield Path(root) / f"{stem}{suffix}"
    for n in range(2, 1000):
        yield Path(root) / f"{stem}-{n}{suffix}"


def fresh_folder(root: Path, what: str) -> Path:
    """``root/<what>-<stamp>``, suffixed ``-2``, ``-3``... until the name is free."""
    return fresh_file(root, what, "")


def fresh_file(root: Path, what: str, suffix: str) -> Path:
    """``root/<what>-<stamp><suffix>``, with ``-2``, ``-3``... before the suffix until free."""
    for candidate in numbered(root, f"{slug(what)}-{stamp()}", suffix):
        if not os.path.lexists(candidate):
            return candidate
    raise OutputError(f"{root}: no free name for {what!r}")
