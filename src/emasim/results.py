"""The results emasim wrote under a folder: find them, list them, prune the old ones.

A result is a folder holding emasim's marker (emasim.manifest): a run, a comparison, a study,
a report, an identification. :func:`find` walks a folder for them, never following a link and
never descending into a result (its runs are part of it). :func:`prune` chooses by age and
count and removes a chosen result the way the output layer removes its own files
(emasim.output.remove_own): a result's nested results first, then its own files, and only
when nothing in it is foreign (a file emasim did not write, or one changed since): such a
result stays whole, and is reported. Nothing else is ever removed.
"""

import json
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

from .errors import InputError
from .manifest import MARKER
from .output import foreign_files, is_emasim_folder, locked, remove_own

AGE = re.compile(r"^(\d+(?:\.\d+)?)([smhdw])$")
SECONDS = {"s": 1, "m": 60, "h": 3600, "d": 86400, "w": 604800}


@dataclass(frozen=True)
class Found:
    """A result: its folder, kind (the marker's), when it was written (the marker's time,
    seconds since the epoch) and its size in bytes (every file under it)."""

    folder: Path
    kind: str
    written: float
    size: int


def _kind(folder: Path) -> str:
    try:
        return str(json.loads((folder / MARKER).read_text()).get("kind", "?"))
    except (OSError, ValueError, AttributeError):
        return "?"


def _size(folder: Path) -> int:
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            try:
                total += os.lstat(Path(root, name)).st_size
            except OSError:
                pass
    return total


def find(root: Path) -> list[Found]:
    """Every result under ``root`` (module docstring), oldest first."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: no such folder")
    found = []
    for here, dirs, _ in os.walk(root):
        path = Path(here)
        if is_emasim_folder(path):
            found.append(Found(path, _kind(path), (path / MARKER).stat().st_mtime, _size(path)))
            dirs[:] = []  # its runs are part of it
            continue
        # never into a link, nor into a build's or a moved-aside result's hidden folder
        dirs[:] = [d for d in dirs if not os.path.islink(path / d) and not d.startswith(".")]
    return sorted(found, key=lambda f: f.written)


def parse_age(text: str) -> float:
    """``30m``, ``12h``, ``7d``, ``2w`` as seconds; one InputError line otherwise."""
    match = AGE.match(text.strip())
    if not match:
        raise InputError(f"--older-than {text!r}: give a number and s, m, h, d or w, e.g. 7d")
    return float(match.group(1)) * SECONDS[match.group(2)]


def choose(results: list[Found], older_than_s: float | None, keep: int | None,
           now: float | None = None) -> list[Found]:  # fmt: skip
    """The results to prune: older than ``older_than_s`` and beyond the ``keep`` newest of
    their folder (each where given; at least one must be)."""
    if older_than_s is None and keep is None:
        raise InputError("prune: give --older-than AGE, --keep N or both")
    if keep is not None and keep < 0:
        raise InputError(f"--keep {keep}: give 0 or more")
    now = time.time() if now is None else now
    by_parent: dict[Path, list[Found]] = {}
    for result in results:
        by_parent.setdefault(result.folder.parent, []).append(result)
    chosen = []
    for group in by_parent.values():
        newest_first = sorted(group, key=lambda f: f.written, reverse=True)
        for rank, result in enumerate(newest_first):
            old = older_than_s is None or now - result.written > older_than_s
            surplus = keep is None or rank >= keep
            if old and surplus:
                chosen.append(result)
    return sorted(chosen, key=lambda f: f.written)


def remove(folder: Path) -> list[str]:
    """Remove the result ``folder`` as the module docstring says; the files that kept it (or
    a nested result) in place, [] when it is gone. An OSError (a read-only file system, a
    permission) when one of emasim's own files cannot be removed."""
    for here, dirs, _ in os.walk(folder, topdown=True):
        path = Path(here)
        if path != folder and is_emasim_folder(path):
            dirs[:] = []
            remove(path)
    with locked(folder.parent):
        kept = foreign_files(folder)
        if kept:
            return kept
        failures: list[OSError] = []
        remove_own(folder, failures)
        if failures:
            raise failures[0]
    return [] if not os.path.lexists(folder) else sorted(os.listdir(folder))
