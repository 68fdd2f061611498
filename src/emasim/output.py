"""Writing results without ever deleting, renaming or replacing anything emasim did not create.

* A result is a real folder holding emasim's marker (:mod:`emasim.manifest`), whose manifest
  lists each file emasim wrote there with its size and modification time. A new path or an
  empty folder is written; an emasim result is replaced only with ``force``, and only while it
  holds its manifest's files alone, unchanged; anything else (a user's folder, file or link) is
  refused. A file follows the same rules, ``is_ours`` telling whether one there is emasim's.
* A write builds in ``.<name>.tmp-<pid>-<token>`` beside the target, marked from the start, its
  journal listing each file before it exists (:func:`new_file`); it writes the manifest and,
  under the parent's lock, publishes by a rename that replaces nothing (:func:`_rename`).
* ``force`` moves the old result aside (``.<name>.old-<pid>-<token>``), checks it against its
  manifest (anything else there: put back, refused), renames the new one in and deletes the old
  one's own files. A file is hard-linked into place (replacing nothing), or with ``force``
  checked again under the lock and replaced: a file saved there between the two is the race left.
* A kill leaves the target complete or absent. Its debris, a real folder named as above whose
  process is gone, holding the marker or empty, loses at the next write there the files its
  journal or manifest lists, its marker, journal and empty folders: nothing else.
* No link is ever followed; modes follow the umask. For users: docs/guide.md, "Where results go".
"""

import contextlib
import ctypes
import errno
import fcntl
import os
import re
import secrets
import stat
from collections.abc import Callable
from pathlib import Path

from .errors import OutputError
from .manifest import MARKER, list_file, manifest_stamps, stamp, write_marker
from .naming import numbered

JOURNAL = ".emasim-journal"
CLI_HINTS = ("add --force to replace it", "or leave --out out for a fresh folder")
_DEBRIS = re.compile(r"^\..+\.(?P<kind>tmp|old)-(?P<pid>\d+)-[0-9a-f]{8}$")
_TAKEN = "another process wrote it meanwhile; nothing was replaced"
_RENAMEAT2 = getattr(ctypes.CDLL(None, use_errno=True), "renameat2", None)  # glibc >= 2.28


def _beside(path: Path, kind: str) -> Path:
    return path.with_name(f".{path.name}.{kind}-{os.getpid()}-{secrets.token_hex(4)}")


def _real_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink()


def is_emasim_folder(path: Path) -> bool:
    """True when ``path`` is a real folder (not a link) that holds emasim's marker."""
    return _real_folder(Path(path)) and (Path(path) / MARKER).is_file()


def _owned(folder: Path) -> dict[str, bool]:
    """Each file or link under ``folder`` -> whether it is emasim's: listed in the manifest with
    its stamp unchanged (a name without a stamp proves nothing), else listed in the journal or
    the same inode as a file listed there (new_file killed between its link and its line)."""
    stamps, found, journal = manifest_stamps(folder), {}, set()
    with contextlib.suppress(OSError, ValueError):
        journal = set((folder / JOURNAL).read_text().splitlines())
    for root, dirs, files in os.walk(folder):  # never into a link
        for name in files + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            with contextlib.suppress(OSError):
                found[Path(root, name).relative_to(folder).as_posix()] = os.lstat(Path(root, name))
    inode = {n: (st.st_dev, st.st_ino) for n, st in found.items() if not stat.S_ISLNK(st.st_mode)}
    parts = {inode[name] for name in journal if name in inode}
    own = {n: n in journal or inode.get(n) in parts for n in found.keys() - {MARKER, JOURNAL}}
    return own | {n: stamps[n] == stamp(found[n]) for n in own.keys() & stamps.keys()}


def foreign_files(folder: Path) -> list[str]:
    """The files under ``folder`` that are not emasim's as written: [] lets emasim delete it."""
    return sorted(name for name, own in _owned(Path(folder)).items() if not own)


def remove_own(folder: Path) -> bool:
    """Delete emasim's files under the real folder ``folder`` (a link itself, never its target),
    its journal, marker and emptied folders; True when ``folder`` is gone."""
    if not _real_folder(folder):
        return False
    for name in [name for name, own in _owned(folder).items() if own] + [JOURNAL, MARKER]:
        with contextlib.suppress(OSError):
            os.unlink(folder / name)
    for root, _, _ in os.walk(folder, topdown=False):  # the deepest first, ``folder`` last
        with contextlib.suppress(OSError):
            os.rmdir(root)  # an empty folder only
    return not os.path.lexists(folder)


@contextlib.contextmanager
def new_file(path: Path):
    """Yield a handle writing bytes to a new file; never opens an existing name. In a build, a
    hidden part is journalled, written, linked to ``path`` (only if free), then that journalled."""
    path = Path(path).absolute()
    builds = [p for p in path.parents if (m := _DEBRIS.match(p.name)) and m["kind"] == "tmp"]
    if not builds:
        with open(path, "xb") as handle:
            yield handle
        return
    part = path.with_name(f".{path.name}.part-{secrets.token_hex(4)}")
    with open(builds[0] / JOURNAL, "ab", buffering=0) as journal:  # one O_APPEND write a line
        journal.write(f"{part.relative_to(builds[0]).as_posix()}\n".encode())
        handle = open(part, "xb")  # before the try: a name that exists is not removed
        try:
            with handle:
                yield handle
            os.link(part, path)
            journal.write(f"{path.relative_to(builds[0]).as_posix()}\n".encode())
        finally:
            part.unlink()


def write_new(path: Path, content: str | bytes) -> None:
    """Write ``content`` (text, as UTF-8, or bytes) to a new file through :func:`new_file`."""
    with new_file(path) as handle:
        handle.write(content.encode() if isinstance(content, str) else content)


def check_parents(path: Path, what: str) -> None:
    """Refuse a target under a file, or in a folder that cannot be written."""
    parent = next(p for p in Path(path).absolute().parents if os.path.lexists(p))
    if not parent.is_dir():
        raise OutputError(f"{what} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: cannot write in {parent}")


def check_folder(path: Path, force: bool, what: str = "--out", hints=CLI_HINTS, is_ours=None):
    """Raise OutputError unless a result folder (or, given ``is_ours``, a file) may be written
    at ``path``; ``hints`` say how to replace it, and how to get a fresh one."""
    path, folder = Path(path), is_ours is None
    check_parents(path, what)
    if not os.path.lexists(path) or folder and _real_folder(path) and not any(path.iterdir()):
        return
    never = "emasim never replaces it (choose another path)"
    if folder and not is_emasim_folder(path):
        kind = "a link" if path.is_symlink() else "a folder" if path.is_dir() else "a file"
        raise OutputError(f"{what} {path}: is {kind} that emasim did not write; {never}")
    if not folder and not (path.is_file() and not path.is_symlink() and is_ours(path)):
        raise OutputError(f"{what} {path}: exists and emasim did not write it; {never}")
    if not force:
        told = "holds an emasim result already" if folder else "exists (written by emasim)"
        raise OutputError(f"{what} {path}: {told}; {', '.join(hints)}")
    _refuse_foreign(path, path, what)  # a file holds no files


def check_file(path: Path, force: bool, is_ours: Callable[[Path], bool], what: str,
               replace_hint: str = CLI_HINTS[0]) -> None:  # fmt: skip
    """Raise OutputError unless a file may be written at ``path``."""
    check_folder(path, force, what, (replace_hint,), is_ours)


def _refuse_foreign(folder: Path, path: Path, what: str) -> None:
    """Refuse to replace ``path``, an emasim result (now at ``folder``) holding foreign files."""
    if foreign := foreign_files(folder):
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise OutputError(
            f"{what} {path}: holds files emasim did not write, or changed since ({foreign[0]}"
            f"{more}); move them out first, or choose another path"
        )


def clean_leftovers(folder: Path) -> list[Path]:
    """Remove the debris of dead processes in ``folder``; return the folders removed."""
    removed = []
    for entry in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if not (match := _DEBRIS.match(entry.name)) or not _real_folder(entry):
            continue
        try:
            os.kill(int(match["pid"]), 0)  # signal 0 sends nothing: it asks whether pid runs
        except (ProcessLookupError, OverflowError):
            with contextlib.suppress(OSError):
                if (is_emasim_folder(entry) or not any(entry.iterdir())) and remove_own(entry):
                    removed.append(entry)
        except PermissionError:  # another user's process runs
            pass
    return removed


@contextlib.contextmanager
def locked(folder: Path):
    """Hold an exclusive lock on ``folder`` (flock on the folder itself: no lock file)."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _rename(src: Path, dst: Path) -> bool:
    """Rename the folder ``src`` to ``dst``; False, nothing replaced, where ``dst`` exists.
    Without renameat2's RENAME_NOREPLACE, rename(2) can replace only an empty folder."""
    if _RENAMEAT2 is not None:  # -100: AT_FDCWD, 1: RENAME_NOREPLACE
        if _RENAMEAT2(-100, os.fsencode(src), -100, os.fsencode(dst), 1) == 0:
            return True
        if (code := ctypes.get_errno()) not in (errno.EINVAL, errno.ENOSYS):  # else: no flag
            if code == errno.EEXIST:
                return False
            raise OSError(code, os.strerror(code), os.fspath(src))
    try:
        os.rename(src, dst)
    except OSError:
        if not os.path.lexists(dst):
            raise
        return False
    return True


@contextlib.contextmanager
def _build(path: Path, kind: str, what: str):
    """Yield a fresh, marked build folder beside ``path`` (the debris there removed first),
    then remove what is left of it; an OSError (a full disk) becomes one line."""
    tmp = _beside(path, "tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        clean_leftovers(path.parent)
        os.mkdir(tmp)  # fails if the name exists: what is removed below is this process's
        try:
            write_marker(tmp, kind)
            yield tmp
        finally:
            remove_own(tmp)
    except OSError as err:
        raise OutputError(f"{what} {path}: cannot write ({err.strerror or err})") from None


def write_folder(path: Path, write: Callable[[Path], None], *, force: bool = False,
                 unique: bool = False, kind: str = "run", what: str = "--out",
                 hints: tuple[str, str] = CLI_HINTS) -> Path:  # fmt: skip
    """Build a result folder with ``write(tmp)``, publish it at ``path`` and return where;
    ``kind`` goes into the marker. ``unique``: a name taken meanwhile moves on to ``-2``..."""
    path = Path(path)
    check_folder(path, force, what, hints)
    with _build(path, kind, what) as tmp:
        write(tmp)
        write_marker(tmp, kind, files=sorted(name for name, own in _owned(tmp).items() if own))
        (tmp / JOURNAL).unlink(missing_ok=True)
        with locked(path.parent):
            for candidate in numbered(path.parent, path.name) if unique else [path]:
                if _publish(tmp, candidate, force, what):
                    return candidate
    raise OutputError(f"{what} {path}: {'no free folder name' if unique else _TAKEN}")


def _publish(tmp: Path, path: Path, force: bool, what: str) -> bool:
    """Rename ``tmp`` to ``path``; False where it is taken. ``force`` swaps an emasim result
    (a program taking its freed name meanwhile leaves the old one aside, as a kill would)."""
    if not (force and is_emasim_folder(path)):
        with contextlib.suppress(OSError):  # one that got a file meanwhile stays, and refuses
            os.rmdir(path)  # an empty folder is taken: rmdir removes nothing else, nor a link
        return _rename(tmp, path)
    _rename(path, old := _beside(path, "old"))
    try:
        _refuse_foreign(old, path, what)
    except BaseException:
        with contextlib.suppress(OSError):
            _rename(old, path)  # put back
        raise
    if published := _rename(tmp, path):
        remove_own(old)
    return published


def write_file(path: Path, content: bytes | str | Path, *, force: bool = False,
               is_ours: Callable[[Path], bool], what: str,
               replace_hint: str = CLI_HINTS[0], listed: bool = False) -> Path:  # fmt: skip
    """Write ``content`` (bytes, text, or a file's path to copy) to the file ``path``, built in
    a build folder, then hard-linked into place or, with ``force``, checked again and replaced;
    ``listed``: into an emasim result, whose manifest then lists it (manifest.list_file)."""
    path = Path(path)
    check_file(path, force, is_ours, what, replace_hint)
    with _build(path, "file", what) as tmp:
        write_new(tmp / path.name, content.read_bytes() if isinstance(content, Path) else content)
        with locked(path.parent):
            placed = True
            if force and os.path.lexists(path):
                check_file(path, force, is_ours, what, replace_hint)  # again, under the lock
                os.replace(tmp / path.name, path)
            else:
                try:
                    os.link(tmp / path.name, path)  # replaces nothing
                except FileExistsError:
                    placed = False
            if placed and listed:
                list_file(path.parent, path.name)
    if not placed:
        raise OutputError(f"{what} {path}: {_TAKEN}")
    return path
