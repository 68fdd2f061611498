"""Writing results without ever deleting, renaming or replacing anything emasim did not create.

* A result is a real folder holding emasim's marker (:mod:`emasim.manifest`), whose manifest
  lists each file emasim wrote there with its size and modification time. A new path or an
  empty folder is written; an emasim result is replaced only with ``force``, and only while it
  holds its manifest's files alone, unchanged; a user's folder, file or link never. A file
  follows the same rules, ``is_ours`` telling whether one there is emasim's.
* A write builds in ``.<name>.tmp-<pid>-<token>`` beside the target (mkdir: this process's),
  marked, writes the manifest, then under the parent's lock publishes by a rename that replaces
  nothing. ``force`` moves the old result aside (``.<name>.old-<pid>-<token>``), checks it
  (anything foreign: put back, refused), renames the new one in, deletes the old one's own
  files. A file is hard-linked into place, or with ``force`` checked again under the lock and
  replaced: a file saved there between the two is the race left.
* Others may put files into a build, so :func:`new_file` makes a file without a name
  (O_TMPFILE), journals ``dev:ino name``, then links it to the name, never an existing one: a
  name is emasim's while it keeps that inode, and a kill leaves no file the journal lacks.
  Without O_TMPFILE it opens the name (O_EXCL) and journals after: a kill between leaves the
  file unlisted, which keeps the debris (the safe way round: a name journalled before its open
  may be a user's). Debris, such a folder whose process is
  gone, marked or empty, loses at the next write there only its proven files, marker, journal
  and empty folders. No link is ever followed; modes follow the umask. Users: docs/guide.md.
"""

import contextlib
import ctypes
import errno
import fcntl
import os
import re
import shutil
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import BinaryIO

from .errors import OutputError
from .manifest import MARKER, list_file, manifest_stamps, stamp, write_marker
from .naming import numbered

JOURNAL = ".emasim-journal"
CLI_HINTS = ("add --force to replace it", "or leave --out out for a fresh folder")
_DEBRIS = re.compile(r"^\..+\.(?P<kind>tmp|old)-(?P<pid>\d+)-[0-9a-f]{8}$")
_TAKEN = "another process wrote it meanwhile; nothing was replaced"
_LINE = "{0.st_dev}:{0.st_ino} {1}"  # a journal line: a file's inode, its name
_LIBC = ctypes.CDLL(None, use_errno=True)
_RENAMEAT2 = getattr(_LIBC, "renameat2", None)  # glibc >= 2.28
_LINKAT = getattr(_LIBC, "linkat", None)
# what a new file is written from: see write_new
Content = str | bytes | Iterable[str | bytes] | Path | Callable[[BinaryIO], None]


def _beside(path: Path, kind: str) -> Path:
    return path.with_name(f".{path.name}.{kind}-{os.getpid()}-{os.urandom(4).hex()}")


def _real_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink()


def is_emasim_folder(path: Path) -> bool:
    """True when ``path`` is a real folder (not a link) that holds emasim's marker."""
    return _real_folder(Path(path)) and (Path(path) / MARKER).is_file()


def _records(folder: Path) -> tuple[str, ...]:
    """The record files emasim keeps in ``folder``: its marker, and in a build its journal
    (a published result has none: a file of that name there is a user's)."""
    return (MARKER, JOURNAL) if _DEBRIS.match(folder.name) else (MARKER,)


def _owned(folder: Path) -> dict[str, bool]:
    """Each file or link under ``folder`` -> whether it is emasim's: listed in the manifest with
    its stamp unchanged (a name without a stamp proves nothing), else, in a build, journalled
    with its inode."""
    stamps, journal, found, records = manifest_stamps(folder), set(), {}, _records(folder)
    with contextlib.suppress(OSError):
        if JOURNAL in records:
            journal = set(map(os.fsdecode, (folder / JOURNAL).read_bytes().split(b"\n")))
    for root, dirs, files in os.walk(folder):  # never into a link
        for name in files + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            with contextlib.suppress(OSError):
                found[Path(root, name).relative_to(folder).as_posix()] = os.lstat(Path(root, name))
    return {
        name: stamps[name] == stamp(st) if name in stamps else _LINE.format(st, name) in journal
        for name, st in found.items()
        if name not in records
    }


def foreign_files(folder: Path) -> list[str]:
    """The files under ``folder`` that are not emasim's as written: [] lets emasim delete it."""
    return sorted(name for name, own in _owned(Path(folder)).items() if not own)


def remove_own(folder: Path, failures: list[OSError] | None = None) -> bool:
    """Delete emasim's files under the real folder ``folder`` (a link itself, never its target),
    its journal, marker and emptied folders; True when ``folder`` is gone. An own file that
    could not be removed (a read-only file system, a permission) is added to ``failures``."""
    if not _real_folder(folder):
        return False
    for name in [name for name, own in _owned(folder).items() if own] + [*_records(folder)]:
        try:
            os.unlink(folder / name)
        except FileNotFoundError:
            pass
        except OSError as err:
            if failures is not None:
                failures.append(err)
    for root, _, _ in os.walk(folder, topdown=False):  # the deepest first, ``folder`` last
        with contextlib.suppress(OSError):
            os.rmdir(root)  # an empty folder only
    return not os.path.lexists(folder)


@contextlib.contextmanager
def new_file(path: Path):
    """Yield a handle writing bytes to a new file: never an existing name, nor through a link.
    In a build the file is made without a name (O_TMPFILE), journalled with its inode (one
    O_APPEND write), then linked to its name (linkat, which replaces nothing): a kill at any
    moment leaves no file the journal lacks. Where no unnamed file can be made (not Linux, a
    file system without it), it is opened by name and journalled after; an error between
    removes it, a kill leaves it unlisted (the debris then stays: the safe way round)."""
    path = Path(path).absolute()
    builds = (p for p in path.parents if (m := _DEBRIS.match(p.name)) and m["kind"] == "tmp")
    build = next(builds, None)
    fd = _unnamed(path.parent) if build else None
    with os.fdopen(fd, "wb") if fd is not None else open(path, "xb") as handle:
        st = os.fstat(handle.fileno())
        try:
            if build:
                _journal(build, _LINE.format(st, path.relative_to(build).as_posix()))
            if fd is not None:  # -100: AT_FDCWD, 0x400: AT_SYMLINK_FOLLOW
                if _LINKAT(-100, f"/proc/self/fd/{fd}".encode(), -100, os.fsencode(path), 0x400):
                    code = ctypes.get_errno()  # EEXIST: a FileExistsError, as open's "x"
                    raise OSError(code, os.strerror(code), os.fspath(path))
        except BaseException:  # a full disk, a Ctrl-C: a named file, never listed, goes
            if fd is None and os.path.samestat(os.lstat(path), st):
                os.unlink(path)
            raise
        yield handle


def _unnamed(folder: Path) -> int | None:
    """A descriptor of a new file without a name in ``folder``, where it can be made and then
    named (linkat through /proc/self/fd); else None."""
    if _LINKAT is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        return os.open(folder, os.O_TMPFILE | os.O_WRONLY, 0o666)  # the umask applies
    except (AttributeError, OSError):  # no O_TMPFILE here, or not on this file system
        return None


def _journal(build: Path, line: str) -> None:
    with open(build / JOURNAL, "ab", buffering=0) as journal:
        journal.write(os.fsencode(f"{line}\n"))


def write_new(path: Path, content: Content) -> None:
    """Write ``content`` (text, as UTF-8, or bytes, or an iterable of them written one block at
    a time, or a file's path to copy, or a function that writes to the binary handle it is
    given) to a new file through :func:`new_file`. A file is copied a block at a time."""
    with new_file(path) as handle:
        if isinstance(content, Path):
            with open(content, "rb") as source:
                shutil.copyfileobj(source, handle, 1 << 20)
        elif callable(content):
            content(handle)
        else:
            for block in [content] if isinstance(content, str | bytes) else content:
                handle.write(block.encode() if isinstance(block, str) else block)


def check_target(path: Path, force: bool, what: str = "--out", hints=CLI_HINTS, is_ours=None,
                 at: Path | None = None) -> None:  # fmt: skip
    """Raise OutputError unless a result folder (or, given ``is_ours``, a file) may be written
    at ``path``, its old result now ``at`` (moved aside) if given: not under a file, nor in a
    folder that cannot be written; ``hints`` say how to replace it (and get a fresh one)."""
    path, folder, at = Path(path), is_ours is None, Path(at or path)
    parent = next(p for p in path.absolute().parents if os.path.lexists(p))
    if not parent.is_dir():
        raise OutputError(f"{what} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: cannot write in {parent}")
    if not os.path.lexists(at) or folder and _real_folder(at) and not any(at.iterdir()):
        return
    never = "emasim never replaces it (choose another path)"
    if folder and not is_emasim_folder(at):
        kind = "a link" if at.is_symlink() else "a folder" if at.is_dir() else "a file"
        raise OutputError(f"{what} {path}: is {kind} that emasim did not write; {never}")
    if not folder and not (at.is_file() and not at.is_symlink() and is_ours(at)):
        raise OutputError(f"{what} {path}: exists and emasim did not write it; {never}")
    if not force:
        told = "holds an emasim result already" if folder else "exists (written by emasim)"
        raise OutputError(f"{what} {path}: {told}; {', '.join(hints)}")
    if foreign := foreign_files(at):  # a file holds none
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
        yield fcntl.flock(fd, fcntl.LOCK_EX)
    finally:
        os.close(fd)


def _rename(src: Path, dst: Path) -> bool:
    """Rename the folder ``src`` to ``dst``; False, nothing replaced, where ``dst`` exists.
    Without renameat2's RENAME_NOREPLACE, rename(2) can replace only an empty folder."""
    try:  # -100: AT_FDCWD, 1: RENAME_NOREPLACE
        if _RENAMEAT2 is None or _RENAMEAT2(-100, os.fsencode(src), -100, os.fsencode(dst), 1):
            code = ctypes.get_errno() if _RENAMEAT2 else errno.ENOSYS
            if code not in (errno.EINVAL, errno.ENOSYS):  # else: no such flag here
                raise OSError(code, os.strerror(code), os.fspath(src))
            os.rename(src, dst)
    except OSError:
        if not os.path.lexists(dst):
            raise
        return False
    return True


@contextlib.contextmanager
def _build(path: Path, kind: str, what: str, write: Callable[[Path], None]):
    """Build with ``write`` in a fresh, marked folder beside ``path`` (the debris there removed
    first), give it its manifest, yield it under the parent's lock, then remove what is left of
    it; an OSError (a full disk) becomes one line."""
    tmp = _beside(path, "tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        clean_leftovers(path.parent)
        os.mkdir(tmp)  # fails if the name exists: what is removed below is this process's
        try:
            write_marker(tmp, kind)
            write(tmp)
            write_marker(tmp, kind, files=sorted(name for name, own in _owned(tmp).items() if own))
            (tmp / JOURNAL).unlink(missing_ok=True)
            with locked(path.parent):
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
    check_target(path, force, what, hints)
    with _build(path, kind, what, write) as tmp:
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
        check_target(path, force, what, at=old)
    except BaseException:
        with contextlib.suppress(OSError):
            _rename(old, path)  # put back
        raise
    if published := _rename(tmp, path):
        remove_own(old)
    return published


def write_file(path: Path, content: Content, *, force: bool = False,
               is_ours: Callable[[Path], bool], what: str,
               replace_hint: str = CLI_HINTS[0], listed: bool = False) -> Path:  # fmt: skip
    """Write ``content`` (as :func:`write_new` takes it) to the file ``path`` as the module
    docstring says; ``listed``: into an emasim result, whose manifest then lists it."""
    path, hints = Path(path), (replace_hint,)
    check_target(path, force, what, hints, is_ours)
    with _build(path, "file", what, lambda tmp: write_new(tmp / path.name, content)) as tmp:
        try:
            if force and os.path.lexists(path):
                check_target(path, force, what, hints, is_ours)  # again, under the lock
                os.replace(tmp / path.name, path)
            else:
                os.link(tmp / path.name, path)  # replaces nothing
        except FileExistsError:
            raise OutputError(f"{what} {path}: {_TAKEN}") from None
        if listed:
            list_file(path.parent, path.name)
    return path
