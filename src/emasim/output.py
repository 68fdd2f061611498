"""Writing results without ever touching anything emasim did not create.

Every folder emasim writes (a run, a comparison, a report) holds a marker file, ``MARKER``,
written first and rewritten at the end with the manifest of the files emasim put there. A
folder is *an emasim result* when it holds that marker. The rules:

* a target that does not exist, or an empty folder, is written;
* an emasim result is replaced only with ``force=True`` (the command line's ``--force``), and
  only while it holds nothing but its manifest's files: a file a user added keeps it;
* anything else (a user's folder, a file, a link) is refused, with or without ``force``.

Files follow the same rules, with ``is_ours`` telling whether an existing file is emasim's
(an FMU carrying emasim's resource, a tuned scenario carrying emasim's header line).

Writing is atomic. A folder is built under a temporary name beside its target,
``.<name>.tmp-<pid>-<token>``, and renamed into place; without ``force`` the rename fails if
anything took the place meanwhile, so two concurrent runs to one place either both succeed or
the second is refused with one line. A kill at any moment leaves the target complete or absent;
the temporaries of processes that no longer run are removed by the next write in that folder:
only folders of this exact pattern that hold the marker, or are empty, and of a replaced
result (``.old-``) only the files its manifest lists (:func:`remove_own`). A file is written the
same way, inside such a temporary marker folder, and hard-linked (or, with ``force``, renamed)
into place; so no leftover is ever a bare file, and a bare file is never removed.

Default run folders never collide: :func:`fresh_folder` gives
``runs/<scenario>/<what>-<YYYYmmdd-HHMMSS>`` with a ``-2``, ``-3``... suffix when taken.
Modes follow the umask (plain ``mkdir`` and ``open``). JSON is written by :func:`json_text`,
which turns NaN and infinity into ``null``, so every JSON file is valid JSON.
"""

import contextlib
import datetime
import fcntl
import json
import math
import os
import re
import secrets
import shutil
from collections.abc import Callable
from pathlib import Path

from .errors import EmasimError

MARKER = ".emasim-result"
RUNS_ROOT = Path("runs")
_LEFTOVER = re.compile(r"^\.(?P<name>.+)\.(?:tmp|old)-(?P<pid>\d+)-[0-9a-f]{8}(?:\.[a-z]+)?$")
_MAX_SUFFIX = 1000


class OutputError(EmasimError):
    """A target cannot be written without losing someone's data, or cannot be written at all."""


def slug(label: str) -> str:
    """A folder name for a label or a scenario name: lower-case letters, digits and dashes."""
    return "".join(ch if ch.isalnum() else "-" for ch in label.lower()).strip("-") or "run"


def stamp() -> str:
    """Local time to the second, for folder names: ``YYYYmmdd-HHMMSS``."""
    return datetime.datetime.now().strftime("%Y%m%d-%H%M%S")


def fresh_folder(root: Path, what: str) -> Path:
    """``root/<what>-<stamp>``, suffixed ``-2``, ``-3``... until the name is free."""
    return fresh_file(root, what, "")


def fresh_file(root: Path, what: str, suffix: str) -> Path:
    """``root/<what>-<stamp><suffix>``, with ``-2``, ``-3``... before the suffix until free."""
    stem = f"{slug(what)}-{stamp()}"
    for n in range(1, _MAX_SUFFIX):
        candidate = root / (f"{stem}{suffix}" if n == 1 else f"{stem}-{n}{suffix}")
        if not os.path.lexists(candidate):
            return candidate
    raise OutputError(f"{root}: no free name for {what!r}")


def is_emasim_folder(path: Path) -> bool:
    """True when ``path`` is a real folder (not a link) that holds emasim's marker."""
    return path.is_dir() and not path.is_symlink() and (path / MARKER).is_file()


def foreign_files(folder: Path) -> list[str]:
    """The files in an emasim result that emasim did not write: every file not in the
    marker's manifest (all of them when the marker has none). [] means emasim may delete it."""
    try:
        listed = set(json.loads((folder / MARKER).read_text())["files"])
    except (OSError, ValueError, KeyError, TypeError):
        listed = set()
    return [name for name in _files_in(folder) if name not in listed]


def _files_in(folder: Path) -> list[str]:
    """Relative paths of every file and link under ``folder`` but the marker."""
    names = []
    for root, dirs, files in os.walk(folder):
        for name in files + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            relative = Path(root, name).relative_to(folder).as_posix()
            if relative != MARKER:
                names.append(relative)
    return sorted(names)


def remove_own(folder: Path) -> bool:
    """Delete from an emasim folder only the files its marker's manifest lists, then the
    marker and the folders left empty; anything else stays, with the folders that hold it.
    A manifest entry that leaves the folder, or reaches through a link, is skipped. True when
    the folder is gone."""
    base = folder.resolve()
    try:
        listed = json.loads((folder / MARKER).read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        listed = []
    for name in listed if isinstance(listed, list) else []:
        target = folder / str(name)
        inside = target.parent.resolve() == base.joinpath(str(name)).parent
        if inside and (target.is_symlink() or target.is_file()):
            with contextlib.suppress(OSError):
                target.unlink()  # a link itself, never what it points to
    with contextlib.suppress(OSError):
        (folder / MARKER).unlink()
    for root, dirs, _ in os.walk(folder, topdown=False):
        for name in dirs:
            with contextlib.suppress(OSError):
                os.rmdir(Path(root, name))  # only an empty folder (a link is not one)
    with contextlib.suppress(OSError):
        os.rmdir(folder)
    return not os.path.lexists(folder)


def _is_empty_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink() and not any(path.iterdir())


def check_parents(path: Path, what: str) -> None:
    """Refuse a target under a file, or in a folder that cannot be written."""
    for parent in path.absolute().parents:
        if os.path.lexists(parent):
            if not parent.is_dir():
                raise OutputError(f"{what} {path}: {parent} is a file, not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise OutputError(f"{what} {path}: cannot write in {parent}")
            return


def check_folder(path: Path, force: bool, what: str = "--out") -> None:
    """Raise OutputError unless a result folder may be written at ``path`` (module rules)."""
    path = Path(path)
    check_parents(path, what)
    if not os.path.lexists(path) or _is_empty_folder(path):
        return
    if is_emasim_folder(path):
        if force:
            _refuse_foreign(path, what)
            return
        raise OutputError(
            f"{what} {path}: holds an emasim result already; add --force to replace it, "
            "or leave --out out for a fresh folder"
        )
    kind = "a link" if path.is_symlink() else "a file" if not path.is_dir() else "a folder"
    raise OutputError(
        f"{what} {path}: is {kind} that emasim did not write; emasim never replaces it "
        "(choose another path)"
    )


def _refuse_foreign(path: Path, what: str) -> None:
    """Refuse to replace an emasim result into which someone put files of their own."""
    foreign = foreign_files(path)
    if foreign:
        raise OutputError(
            f"{what} {path}: holds files emasim did not write ({foreign[0]}"
            + (f" and {len(foreign) - 1} more" if len(foreign) > 1 else "")
            + "); move them out first, or choose another path"
        )


def check_file(path: Path, force: bool, is_ours: Callable[[Path], bool], what: str) -> None:
    """Raise OutputError unless a file may be written at ``path`` (module rules)."""
    path = Path(path)
    check_parents(path, what)
    if not os.path.lexists(path):
        return
    if path.is_file() and not path.is_symlink() and is_ours(path):
        if force:
            return
        raise OutputError(f"{what} {path}: exists (written by emasim); add --force to replace it")
    raise OutputError(
        f"{what} {path}: exists and emasim did not write it; emasim never replaces it "
        "(choose another path)"
    )


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_leftovers(folder: Path) -> list[Path]:
    """Remove the temporaries that killed emasim processes left in ``folder``; return them.

    Only folders of the module's temporary pattern whose process no longer runs, and of
    those only: a ``.tmp-`` one that holds the marker (a folder that process made with a fresh
    name and filled, never published); of a ``.old-`` one (a published result being
    replaced), the files of its manifest (:func:`remove_own`); an empty one (``os.rmdir``,
    which cannot remove a file). A bare file is never removed: nothing could prove it
    emasim's (write_file's temporaries are marker folders).
    """
    removed = []
    if not folder.is_dir():
        return removed
    for entry in folder.iterdir():
        match = _LEFTOVER.match(entry.name)
        if match is None or _alive(int(match["pid"])) or not entry.is_dir() or entry.is_symlink():
            continue
        with contextlib.suppress(OSError):
            if is_emasim_folder(entry) and ".tmp-" in entry.name:
                shutil.rmtree(entry)
            elif is_emasim_folder(entry):
                if not remove_own(entry):
                    continue  # a user's file in it keeps it
            elif _is_empty_folder(entry):
                os.rmdir(entry)  # killed before its marker: empty, and rmdir removes no file
            else:
                continue
            removed.append(entry)
    return removed


def _temporary(target: Path, kind: str) -> Path:
    suffix = target.suffix if kind == "tmp" and target.suffix else ""
    return target.with_name(
        f".{target.name}.{kind}-{os.getpid()}-{secrets.token_hex(4)}{suffix.lower()}"
    )


@contextlib.contextmanager
def _locked(folder: Path):
    """Hold an exclusive lock on ``folder`` (flock on the folder itself: no lock file)."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _prepare(path: Path, what: str) -> Path:
    """Create the target's parent folders, clean killed runs' leftovers there, and return the
    name of a temporary beside the target."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise _os_error(what, path, err) from None
    clean_leftovers(path.parent)
    return _temporary(path, "tmp")


def _os_error(what: str, path: Path, err: OSError) -> OutputError:
    return OutputError(f"{what} {path}: cannot write ({err.strerror or err})")


def write_folder(
    path: Path,
    write: Callable[[Path], None],
    *,
    force: bool = False,
    unique: bool = False,
    kind: str = "run",
    what: str = "--out",
) -> Path:
    """Build a result folder with ``write(tmp)``, move it to ``path`` atomically, return where.

    ``unique``: ``path`` came from :func:`fresh_folder`; if another process takes the name
    meanwhile, the next free suffix is used instead of refusing. ``kind`` goes into the marker
    ('run', 'comparison', 'report'). Raises OutputError when the module's rules refuse
    ``path``, before anything is written.
    """
    path = Path(path)
    check_folder(path, force, what)
    tmp = _prepare(path, what)
    try:
        os.mkdir(tmp)
    except OSError as err:
        raise _os_error(what, path, err) from None
    try:
        write_marker(tmp, kind)
        write(tmp)
        write_marker(tmp, kind, files=_files_in(tmp))
        candidates = [path] + [path.with_name(f"{path.name}-{n}") for n in range(2, _MAX_SUFFIX)]
        for candidate in candidates if unique else candidates[:1]:
            if _move_into_place(tmp, candidate, force, what, refuse=not unique):
                return candidate
        raise OutputError(f"{what} {path}: no free folder name")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def write_marker(folder: Path, kind: str, files: list[str] | None = None) -> None:
    """The marker that makes ``folder`` an emasim result: written first, then again with the
    manifest of ``files`` emasim wrote (relative paths), which alone it may ever delete."""
    from . import __version__

    record = {"kind": kind, "emasim_version": __version__, "files": files or []}
    (folder / MARKER).write_text(json_text(record))


def _move_into_place(tmp: Path, path: Path, force: bool, what: str, refuse: bool) -> bool:
    """Rename ``tmp`` to ``path``; False if the place was taken and ``refuse`` is off."""
    with _locked(path.parent):
        if force and is_emasim_folder(path):
            _refuse_foreign(path, what)  # again, under the lock
            old = _temporary(path, "old")
            path.rename(old)
            tmp.rename(path)
            remove_own(old)  # its manifest's files only: one put in meanwhile stays
            return True
        try:
            tmp.rename(path)  # fails if a non-empty folder or a file took the place meanwhile
            return True
        except OSError as err:
            if not os.path.lexists(path):
                raise _os_error(what, path, err) from None
        if not refuse:
            return False
        raise OutputError(
            f"{what} {path}: another process wrote it meanwhile; nothing was replaced"
        )


def write_file(
    path: Path,
    content: bytes | str | Path,
    *,
    force: bool = False,
    is_ours: Callable[[Path], bool],
    what: str,
) -> Path:
    """Write a file atomically: ``content`` (bytes, text, or the path of a finished file to
    copy). Without ``force`` an existing file is never replaced, even one that appears while
    writing (the new file is hard-linked into place, which fails if the name is taken)."""
    path = Path(path)
    check_file(path, force, is_ours, what)
    folder = _prepare(path, what)  # the temporary: a marker folder holding the new file
    try:
        os.mkdir(folder)  # fails if the name exists: what is removed below is this process's
    except OSError as err:
        raise _os_error(what, path, err) from None
    try:
        write_marker(folder, "file", files=[path.name])
        tmp = folder / path.name
        with open(tmp, "xb") as handle:
            if isinstance(content, Path):
                with open(content, "rb") as source:
                    shutil.copyfileobj(source, handle)
            else:
                handle.write(content.encode() if isinstance(content, str) else content)
        if force:
            os.replace(tmp, path)
        else:
            os.link(tmp, path)
    except FileExistsError:
        raise OutputError(
            f"{what} {path}: another process wrote it meanwhile; nothing was replaced"
        ) from None
    except OSError as err:
        raise _os_error(what, path, err) from None
    finally:
        remove_own(folder)  # the temporary file (its manifest) and the marker
    return path


def finite_or_none(value):
    """``value`` with every NaN and infinity (also nested in dicts and lists) set to None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_or_none(v) for key, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # a numpy scalar
        return finite_or_none(value.item())
    return value


def json_text(value) -> str:
    """Valid JSON (no NaN or Infinity tokens: they become null), indented, with a newline."""
    return json.dumps(finite_or_none(value), indent=2, allow_nan=False, default=str) + "\n"
