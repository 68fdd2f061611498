"""Writing results without ever touching anything emasim did not create.

Every folder emasim writes (a run, a comparison, a report) holds a marker file, ``MARKER``,
written first and rewritten at the end with the manifest of the files emasim put there. While
the folder is built, every file is created through :func:`new_file` (or :func:`write_new`),
which creates it exclusively and only then appends its name to the build's journal,
``JOURNAL``: so at every moment emasim knows which files in a half-built folder are its own,
and a file anyone else puts there is never listed. A folder is *an emasim result* when it
holds the marker. The rules:

* a target that does not exist, or an empty folder, is written;
* an emasim result is replaced only with ``force=True`` (the command line's ``--force``), and
  only while it holds nothing but its manifest's files as emasim wrote them: a file a user
  added, or one of emasim's that a user changed since (its size or modification time is not
  the manifest's), keeps it;
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
import hashlib
import json
import math
import os
import re
import secrets
import shutil
import stat
from collections.abc import Callable
from pathlib import Path

from .errors import DamagedResult, EmasimError

MARKER = ".emasim-result"
JOURNAL = ".emasim-journal"
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
    """The files in an emasim folder that are not emasim's as it wrote them: every file
    neither in the marker's manifest nor in the build journal, and every manifest file changed
    since it was published. [] means emasim may delete the folder."""
    owned = {target.relative_to(folder).as_posix() for target in _owned(folder)}
    return [name for name in _files_in(folder) if name not in owned]


def _files_in(folder: Path) -> list[str]:
    """Relative paths of every file and link under ``folder`` but the marker and journal."""
    names = []
    for root, dirs, files in os.walk(folder):
        for name in files + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            relative = Path(root, name).relative_to(folder).as_posix()
            if relative not in (MARKER, JOURNAL):
                names.append(relative)
    return sorted(names)


def _build_root(path: Path) -> Path | None:
    """The temporary build folder (``.<name>.tmp-<pid>-<token>``) that holds ``path``, the
    nearest one up; None when ``path`` is not being built into one."""
    for parent in Path(path).absolute().parents:
        match = _LEFTOVER.match(parent.name)
        if match is not None and ".tmp-" in parent.name:
            return parent
    return None


@contextlib.contextmanager
def new_file(path: Path, text: bool = False):
    """Open a new file for writing and yield the handle; never opens an existing name.

    Outside a build folder the file is simply created exclusively (``open(path, "x")``).
    Inside one, every step is listed in its journal (one line, one ``O_APPEND`` write: safe
    across threads and processes) so that a kill at any moment leaves nothing the clean-up
    cannot tell is emasim's:

    1. the journal lists ``.<name>.part-<token>``, a name no one else can know, and only
       then is that file created exclusively and written;
    2. it is hard-linked to ``path`` (which fails if the name is taken: nothing is replaced),
       ``path`` is listed, and the part name is removed.

    Killed between the link and its line, ``path`` is unlisted but is the same file (inode) as
    the listed part, which is how :func:`remove_own` knows it. A file someone else put there
    is never listed and never shares that inode.
    """
    path = Path(path)
    mode = "x" if text else "xb"
    root = _build_root(path)
    if root is None:
        with open(path, mode) as handle:
            yield handle
        return
    part = path.with_name(f".{path.name}.part-{secrets.token_hex(4)}")
    _journal(root, part)
    with open(part, mode) as handle:
        yield handle
    os.link(part, path)
    _journal(root, path)
    part.unlink()


def _journal(root: Path, path: Path) -> None:
    """Append ``path`` (relative to the build folder ``root``) to ``root``'s journal."""
    line = (path.absolute().relative_to(root).as_posix() + "\n").encode()
    fd = os.open(root / JOURNAL, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    try:
        os.write(fd, line)
    finally:
        os.close(fd)


def write_new(path: Path, content: str | bytes) -> None:
    """Write ``content`` (text or bytes) to a new file through :func:`new_file`."""
    with new_file(path, text=isinstance(content, str)) as handle:
        handle.write(content)


def _listed(folder: Path) -> dict[str, list | None]:
    """The files emasim created in ``folder``, each with the stamp it was published with
    (:func:`_stamp`; None for a file of the build journal, or of a manifest without stamps):
    its marker's manifest and its build journal."""
    try:
        record = json.loads((folder / MARKER).read_text())
        listed, stamps = record["files"], record.get("stamps", {})
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        listed, stamps = [], {}
    journal = _journal_names(folder)
    if not isinstance(listed, list) or not isinstance(stamps, dict):
        listed, stamps = [], {}
    names = {str(name): stamps.get(str(name)) for name in listed}
    return names | {name: None for name in journal if name not in names}


def _journal_names(folder: Path) -> list[str]:
    """The names a build folder's journal lists ([] for a published folder: it has none)."""
    try:
        return (folder / JOURNAL).read_text().splitlines()
    except OSError:
        return []


def _stamp(st: os.stat_result) -> list[int]:
    """What the manifest keeps of a file it lists: size (bytes) and modification time (ns).
    Both change with any edit, or with a new file saved over it; both stay when the result
    is moved, or copied with its times (``mv``, ``cp -a``)."""
    return [st.st_size, st.st_mtime_ns]


def _owned(folder: Path) -> list[Path]:
    """The files in ``folder`` emasim created: those its manifest or journal lists (inside
    the folder, not through a link; a manifest's file only while its size and modification
    time are those it was published with), and one that is the same file (inode) as a part
    its build journal lists: new_file's final name, linked to its listed part before a kill
    could list it. (A published folder has no journal: a hard link a user made there to one
    of emasim's files is the user's name, and stays.)"""
    base = folder.resolve()
    owned = []
    for name, stamp in _listed(folder).items():
        target = folder / name
        inside = target.parent.resolve() == base.joinpath(name).parent
        if inside and (target.is_symlink() or target.is_file()):
            if stamp is None or _stamp(os.lstat(target)) == stamp:
                owned.append(target)
    parts = [folder / name for name in _journal_names(folder)]
    listed_parts = [target for target in owned if target in parts]
    inodes = {(st.st_dev, st.st_ino) for st in map(os.lstat, listed_parts) if not _is_link(st)}
    for name in _files_in(folder):
        target = folder / name
        with contextlib.suppress(OSError):
            st = os.lstat(target)
            if not _is_link(st) and (st.st_dev, st.st_ino) in inodes and target not in owned:
                owned.append(target)
    return owned


def remove_own(folder: Path) -> bool:
    """Delete from an emasim folder only the files emasim created (:func:`_owned`: what its
    manifest or build journal lists), then the journal, the marker and the folders left
    empty; anything else stays, with the folders that hold it. An entry that leaves the
    folder, or reaches through a link, is skipped. True when the folder is gone."""
    for target in _owned(folder):
        with contextlib.suppress(OSError):
            target.unlink()  # a link itself, never what it points to
    for own in (JOURNAL, MARKER):
        with contextlib.suppress(OSError):
            (folder / own).unlink()
    for root, dirs, _ in os.walk(folder, topdown=False):
        for name in dirs:
            with contextlib.suppress(OSError):
                os.rmdir(Path(root, name))  # only an empty folder (a link is not one)
    with contextlib.suppress(OSError):
        os.rmdir(folder)
    return not os.path.lexists(folder)


def _is_link(st: os.stat_result) -> bool:
    return stat.S_ISLNK(st.st_mode)


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
            f"{what} {path}: holds files emasim did not write, or changed since ({foreign[0]}"
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
    those only: of one that holds the marker (a ``.tmp-`` folder being built, or a ``.old-``
    result being replaced), the files its build journal or manifest lists
    (:func:`remove_own`; a file someone else put there keeps the folder); an empty one
    (``os.rmdir``, which cannot remove a file). A bare file is never removed: nothing could
    prove it emasim's (write_file's temporaries are marker folders).
    """
    removed = []
    if not folder.is_dir():
        return removed
    for entry in folder.iterdir():
        match = _LEFTOVER.match(entry.name)
        if match is None or _alive(int(match["pid"])) or not entry.is_dir() or entry.is_symlink():
            continue
        with contextlib.suppress(OSError):
            if is_emasim_folder(entry):
                if not remove_own(entry):
                    continue  # a file emasim did not create keeps it
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
        write_marker(tmp, kind, files=sorted(set(_listed(tmp)) & set(_files_in(tmp))))
        (tmp / JOURNAL).unlink(missing_ok=True)
        suffixes = range(2, _MAX_SUFFIX) if unique else ()
        candidates = [path, *(path.with_name(f"{path.name}-{n}") for n in suffixes)]
        for candidate in candidates:
            if _move_into_place(tmp, candidate, force, what, refuse=not unique):
                return candidate
        raise OutputError(f"{what} {path}: no free folder name")
    except OSError as err:  # a disk full, say, while writing: one line, cleaned up
        remove_own(tmp)
        raise _os_error(what, path, err) from None
    except BaseException:
        remove_own(tmp)  # what this process created there; anything else stays
        raise


def write_marker(folder: Path, kind: str, files: list[str] | None = None) -> None:
    """The marker that makes ``folder`` an emasim result: written first, then again with the
    manifest of ``files`` emasim wrote (relative paths, from the build journal), which alone
    it may ever delete, each with its stamp (:func:`_stamp`) and its SHA-256 (``sha256``:
    what proves it whole, :func:`verify_files`)."""
    from .version import __version__

    files = files or []
    stamps, sums = {}, {}
    for name in files:
        with contextlib.suppress(OSError):  # a name that is not there has no stamp
            st = os.lstat(folder / name)
            stamps[name] = _stamp(st)
            if stat.S_ISREG(st.st_mode):
                sums[name] = sha256_of(folder / name)
    record = {
        "kind": kind,
        "emasim_version": __version__,
        "files": files,
        "stamps": stamps,
        "sha256": sums,
    }
    (folder / MARKER).write_text(json_text(record))


def sha256_of(path: Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def verify_files(folder: Path, names: list[str]) -> None:
    """Raise DamagedResult unless ``folder`` is an emasim result (or a run folder inside one,
    as a comparison's are) whose manifest lists each of ``names`` with the size and SHA-256
    the file still has. A result written before manifests carried checksums cannot be proven
    whole and is refused too."""
    folder = Path(folder)
    if not folder.is_dir():
        what = "does not exist" if not os.path.lexists(folder) else "is not a folder"
        raise DamagedResult(f"{folder}: {what}; a result is a folder emasim wrote")
    root, prefix = folder, ""
    if not (folder / MARKER).is_file() and (folder.parent / MARKER).is_file():
        root, prefix = folder.parent, folder.name + "/"  # a run of a comparison
    try:
        record = json.loads((root / MARKER).read_text())
        listed, stamps, sums = record["files"], record["stamps"], record.get("sha256")
        version = record.get("emasim_version", "an earlier version")
    except FileNotFoundError:
        raise DamagedResult(f"{folder}: not an emasim result (it has no {MARKER})") from None
    except (OSError, ValueError, KeyError, TypeError, UnicodeDecodeError):
        raise DamagedResult(f"{root / MARKER}: damaged (not emasim's manifest)") from None
    if not isinstance(sums, dict):
        raise DamagedResult(
            f"{root}: written by emasim {version}, whose manifest has no checksums, so it "
            f"cannot be proven whole; run its scenario.toml again"
        )
    for name in names:
        path, key = folder / name, prefix + name
        if key not in listed or key not in sums:
            found = "is not one of the files emasim wrote there" if path.exists() else "missing"
            raise DamagedResult(f"{path}: {found}")
        try:
            size = os.stat(path).st_size
            if size != stamps[key][0]:
                raise DamagedResult(
                    f"{path}: truncated or changed: {size} bytes, emasim wrote {stamps[key][0]}"
                )
            if sha256_of(path) != sums[key]:
                raise DamagedResult(f"{path}: damaged: its SHA-256 is not the one emasim wrote")
        except FileNotFoundError:
            raise DamagedResult(f"{path}: missing") from None
        except OSError as err:
            raise DamagedResult(f"{path}: cannot be read ({err.strerror or err})") from None
        except (KeyError, IndexError, TypeError):
            raise DamagedResult(f"{root / MARKER}: damaged (not emasim's manifest)") from None


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
        write_marker(folder, "file")
        tmp = folder / path.name
        with new_file(tmp) as handle:
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
        remove_own(folder)  # the temporary file (its journal) and the marker
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
