"""Writing results without ever touching anything emasim did not create.

A result is a folder that holds emasim's marker (:mod:`emasim.manifest`), which lists the files
emasim wrote there, each with its size and modification time. The rules:

* a target that does not exist, or an empty folder, is written;
* an emasim result is replaced only with ``force`` (``--force``), and only while it holds
  nothing but its manifest's files, unchanged: a file a user added, or one of emasim's that a
  user changed, keeps it;
* anything else (a user's folder, a file, a link) is refused, with or without ``force``. A file
  follows the same rules, ``is_ours`` telling whether an existing one is emasim's.

:func:`write_folder` builds in a fresh folder beside the target, ``.<name>.tmp-<pid>-<token>``,
that holds the marker from the start; every file there is made by :func:`new_file`, which lists
it in the build's journal before it exists. It writes the manifest, then, holding the parent
folder's lock (emasim's writers there take turns), publishes by a rename that replaces nothing
(:func:`_rename`). With ``force`` it moves the old result aside, ``.<name>.old-<pid>-<token>``,
checks it against its manifest (anything else in it: put back and refused), renames the new one
into place, and deletes of the old one its manifest's files. :func:`write_file` hard-links the
file it built into place (``link(2)`` replaces nothing); with ``force`` it checks the file there
again under the lock and replaces it: another program's file saved there between the two is
the one race left.

A kill leaves the target complete or absent, and beside it debris: a real folder named as above
whose process is gone, holding the marker or empty. The next write there removes from it the
files its journal or manifest lists as emasim wrote them, then the marker, the journal and the
folders left empty; any other file stays, and so does its folder. No link is followed, and a
bare file is never removed. Modes follow the umask.
"""

import contextlib
import ctypes
import errno
import fcntl
import os
import re
import secrets
import shutil
import stat
from collections.abc import Callable
from pathlib import Path

from .errors import OutputError
from .manifest import MARKER, manifest_stamps, stamp, write_marker
from .naming import numbered

JOURNAL = ".emasim-journal"
_DEBRIS = re.compile(r"^\..+\.(tmp|old)-(?P<pid>\d+)-[0-9a-f]{8}$")
_TAKEN = "another process wrote it meanwhile; nothing was replaced"
_RENAMEAT2 = getattr(ctypes.CDLL(None, use_errno=True), "renameat2", None)  # glibc >= 2.28


def is_emasim_folder(path: Path) -> bool:
    """True when ``path`` is a real folder (not a link) that holds emasim's marker."""
    path = Path(path)
    return path.is_dir() and not path.is_symlink() and (path / MARKER).is_file()


def _owned(folder: Path) -> dict[str, bool]:
    """Each file or link under ``folder`` (no link followed) -> whether it is emasim's: in the
    manifest with its stamp unchanged, in the build's journal, or the same inode as a file the
    journal lists (new_file killed between link and line). A published result has no journal:
    a hard link a user made there is the user's."""
    stamps = manifest_stamps(folder)
    try:
        journal = set((folder / JOURNAL).read_text().splitlines())
    except (OSError, ValueError):
        journal = set()
    found = {}
    for root, dirs, files in os.walk(folder):
        for name in files + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            with contextlib.suppress(OSError):
                found[Path(root, name).relative_to(folder).as_posix()] = os.lstat(Path(root, name))
    inode = {n: (st.st_dev, st.st_ino) for n, st in found.items() if not stat.S_ISLNK(st.st_mode)}
    parts = {inode[name] for name in journal if name in inode}
    return {
        name: stamps[name] in (None, stamp(st))
        if name in stamps
        else name in journal or inode.get(name) in parts
        for name, st in found.items()
        if name not in (MARKER, JOURNAL)
    }


def foreign_files(folder: Path) -> list[str]:
    """The files under ``folder`` that are not emasim's as it wrote them: [] means emasim may
    delete the folder."""
    return sorted(name for name, own in _owned(Path(folder)).items() if not own)


def remove_own(folder: Path) -> bool:
    """Delete emasim's files under ``folder`` (a link itself, never what it points to), its
    journal and marker, then the folders left empty. True when the folder is gone."""
    for name in [name for name, own in _owned(folder).items() if own] + [JOURNAL, MARKER]:
        with contextlib.suppress(OSError):
            os.unlink(folder / name)
    for root, _, _ in os.walk(folder, topdown=False):  # the deepest first, ``folder`` last
        with contextlib.suppress(OSError):
            os.rmdir(root)  # an empty folder only
    return not os.path.lexists(folder)


@contextlib.contextmanager
def new_file(path: Path, text: bool = False):
    """Open a new file for writing and yield the handle; never opens an existing name. In a
    build folder (from any process) it lists ``.<name>.part-<token>``, a name no one else can
    know, in the journal, then creates and writes it, hard-links it to ``path`` (which fails if
    the name is taken), lists ``path``, and removes the part."""
    path = Path(path)
    mode = "x" if text else "xb"
    builds = [p for p in path.absolute().parents if _DEBRIS.match(p.name) and ".tmp-" in p.name]
    if not builds:
        with open(path, mode) as handle:
            yield handle
        return
    part = path.with_name(f".{path.name}.part-{secrets.token_hex(4)}")
    _journal(builds[0], part)
    handle = open(part, mode)
    try:
        with handle:
            yield handle
        os.link(part, path)
        _journal(builds[0], path)
    finally:
        part.unlink()


def _journal(root: Path, path: Path) -> None:
    """List ``path`` in the journal of the build folder ``root``: one line, one ``O_APPEND``
    write, safe across threads and processes."""
    fd = os.open(root / JOURNAL, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        os.write(fd, (path.absolute().relative_to(root).as_posix() + "\n").encode())
    finally:
        os.close(fd)


def write_new(path: Path, content: str | bytes) -> None:
    """Write ``content`` (text or bytes) to a new file through :func:`new_file`."""
    with new_file(path, text=isinstance(content, str)) as handle:
        handle.write(content)


def check_parents(path: Path, what: str) -> None:
    """Refuse a target under a file, or in a folder that cannot be written."""
    parent = next(p for p in Path(path).absolute().parents if os.path.lexists(p))
    if not parent.is_dir():
        raise OutputError(f"{what} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: cannot write in {parent}")


CLI_HINTS = ("add --force to replace it", "or leave --out out for a fresh folder")


def check_folder(
    path: Path, force: bool, what: str = "--out", hints: tuple[str, str] = CLI_HINTS
) -> None:
    """Raise OutputError unless a result folder may be written at ``path`` (module rules);
    ``hints`` say how to replace it and how to get a fresh folder (the command line's
    options, or a Python API's arguments)."""
    path = Path(path)
    check_parents(path, what)
    if is_emasim_folder(path) and force:
        _refuse_foreign(path, path, what)
    elif is_emasim_folder(path):
        raise OutputError(f"{what} {path}: holds an emasim result already; {hints[0]}, {hints[1]}")
    elif os.path.lexists(path) and not _is_empty_folder(path):
        kind = "a link" if path.is_symlink() else "a file" if not path.is_dir() else "a folder"
        raise OutputError(
            f"{what} {path}: is {kind} that emasim did not write; emasim never replaces it "
            "(choose another path)"
        )


def _refuse_foreign(folder: Path, path: Path, what: str) -> None:
    """Refuse to replace ``path``, an emasim result (now at ``folder``) holding foreign files."""
    if foreign := foreign_files(folder):
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise OutputError(
            f"{what} {path}: holds files emasim did not write, or changed since ({foreign[0]}"
            f"{more}); move them out first, or choose another path"
        )


def check_file(
    path: Path,
    force: bool,
    is_ours: Callable[[Path], bool],
    what: str,
    replace_hint: str = CLI_HINTS[0],
) -> None:
    """Raise OutputError unless a file may be written at ``path`` (module rules)."""
    path = Path(path)
    check_parents(path, what)
    if not os.path.lexists(path):
        return
    if not (path.is_file() and not path.is_symlink() and is_ours(path)):
        raise OutputError(
            f"{what} {path}: exists and emasim did not write it; emasim never replaces it "
            "(choose another path)"
        )
    if not force:
        raise OutputError(f"{what} {path}: exists (written by emasim); {replace_hint}")


def _is_empty_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink() and not any(path.iterdir())


def _gone(name: str) -> bool:
    """Whether ``name`` is of the debris pattern and its process no longer runs."""
    match = _DEBRIS.match(name)
    if match is None:
        return False
    try:
        os.kill(int(match["pid"]), 0)
    except (ProcessLookupError, OverflowError):
        return True
    except PermissionError:  # another user's process
        pass
    return False


def clean_leftovers(folder: Path) -> list[Path]:
    """Remove the debris in ``folder`` (module docstring); return the folders removed."""
    removed = []
    for entry in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if _gone(entry.name) and entry.is_dir() and not entry.is_symlink():
            with contextlib.suppress(OSError):
                if (is_emasim_folder(entry) or not any(entry.iterdir())) and remove_own(entry):
                    removed.append(entry)
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
    """Rename ``src`` to ``dst``; False, and nothing replaced, where ``dst`` exists. Linux's
    renameat2(RENAME_NOREPLACE) checks and renames in one step; without it (another system, a
    file system without the flag) rename(2), which for a folder can replace an empty folder
    only: one the rules take anyway."""
    if _RENAMEAT2 is not None:  # -100: AT_FDCWD, 1: RENAME_NOREPLACE
        if _RENAMEAT2(-100, os.fsencode(src), -100, os.fsencode(dst), 1) == 0:
            return True
        code = ctypes.get_errno()
        if code not in (errno.EINVAL, errno.ENOSYS):
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
    """Yield a fresh build folder beside ``path``, after removing the debris there; afterwards
    remove what is left of it. An OSError (a full disk) becomes one line naming ``path``."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
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


def write_folder(
    path: Path,
    write: Callable[[Path], None],
    *,
    force: bool = False,
    unique: bool = False,
    kind: str = "run",
    what: str = "--out",
    hints: tuple[str, str] = CLI_HINTS,
) -> Path:
    """Build a result folder with ``write(tmp)`` and publish it at ``path``; return where.
    ``kind`` goes into the marker. ``unique``: ``path`` is a fresh name (:func:`fresh_folder`),
    and one another process takes meanwhile moves it on to the next suffix (``-2``...).
    ``what`` and ``hints`` word a refusal (:func:`check_folder`)."""
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
        if not unique:
            raise OutputError(f"{what} {path}: {_TAKEN}")
    raise OutputError(f"{what} {path}: no free folder name")


def _publish(tmp: Path, path: Path, force: bool, what: str) -> bool:
    """Rename the build ``tmp`` to ``path`` (the caller holds the lock); False where it is taken.
    ``force`` swaps an emasim result (module docstring); a program that takes its freed name in
    that moment leaves the old result aside, as a kill would."""
    if force and is_emasim_folder(path):
        old = path.with_name(f".{path.name}.old-{os.getpid()}-{secrets.token_hex(4)}")
        _rename(path, old)
        try:
            _refuse_foreign(old, path, what)
        except BaseException:
            with contextlib.suppress(OSError):
                _rename(old, path)  # put back
            raise
        if not _rename(tmp, path):
            return False
        remove_own(old)
        return True
    if _is_empty_folder(path):
        with contextlib.suppress(OSError):  # one that got a file meanwhile stays, and refuses
            os.rmdir(path)  # an empty folder is taken: rmdir removes nothing else
    return _rename(tmp, path)


def write_file(
    path: Path,
    content: bytes | str | Path,
    *,
    force: bool = False,
    is_ours: Callable[[Path], bool],
    what: str,
    replace_hint: str = CLI_HINTS[0],
) -> Path:
    """Write ``content`` (bytes, text, or the path of a file to copy) to the file ``path``,
    built in a build folder and hard-linked into place; ``force``: module docstring."""
    path = Path(path)
    check_file(path, force, is_ours, what, replace_hint)
    with _build(path, "file", what) as tmp:
        with new_file(tmp / path.name) as handle:
            if isinstance(content, Path):
                with open(content, "rb") as source:
                    shutil.copyfileobj(source, handle)
            else:
                handle.write(content.encode() if isinstance(content, str) else content)
        with locked(path.parent):
            if force and os.path.lexists(path):
                check_file(path, force, is_ours, what, replace_hint)  # again, under the lock
                os.replace(tmp / path.name, path)
            else:
                try:
                    os.link(tmp / path.name, path)
                except FileExistsError:
                    raise OutputError(f"{what} {path}: {_TAKEN}") from None
    return path
