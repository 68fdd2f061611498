"""A result's marker, ``.emasim-result``: what it records, and the proof that a result is whole.

The marker is JSON: the result's ``kind`` ('run', 'comparison', 'report'...), emasim's version,
and the manifest: the ``files`` emasim wrote there (relative paths), each with its ``stamps``
(size and modification time, which tell a file changed since: :mod:`emasim.output`) and, for a
regular file, its ``sha256`` (which proves it whole: :func:`verify_files`).
"""

import contextlib
import hashlib
import json
import os
import stat
from pathlib import Path

from .errors import DamagedResult
from .jsonio import json_text

MARKER = ".emasim-result"


def stamp(st: os.stat_result) -> list[int]:
    """Size and modification time (ns): an edit, or a file saved over, changes them; a move,
    or a copy with its times (``mv``, ``cp -a``), keeps them."""
    return [st.st_size, st.st_mtime_ns]


def write_marker(folder: Path, kind: str, files: list[str] | None = None) -> None:
    """Write ``folder``'s marker, with the manifest of ``files`` (relative paths)."""
    from .version import __version__

    files = files or []
    stamps, sums = {}, {}
    for name in files:
        with contextlib.suppress(OSError):  # a name that is not there has no stamp
            st = os.lstat(folder / name)
            stamps[name] = stamp(st)
            if stat.S_ISREG(st.st_mode):
                sums[name] = sha256_of(folder / name)
    record = {"kind": kind, "emasim_version": __version__, "files": files}
    (folder / MARKER).write_text(json_text(record | {"stamps": stamps, "sha256": sums}))


def list_file(folder: Path, name: str) -> None:
    """Add ``name``, a file emasim wrote into the published result ``folder``, to its manifest
    with its stamp and SHA-256 as they are now; every other entry stays as it was. The marker
    is rewritten atomically (a new file renamed over it)."""
    folder = Path(folder)
    record = json.loads((folder / MARKER).read_text())
    record["files"] = sorted({*record["files"], name})
    record.setdefault("stamps", {})[name] = stamp(os.lstat(folder / name))
    record.setdefault("sha256", {})[name] = sha256_of(folder / name)
    new = folder / f"{MARKER}.new-{os.getpid()}-{os.urandom(4).hex()}"  # never a name there
    with open(os.open(new, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), "w") as handle:
        handle.write(json_text(record))
    os.replace(new, folder / MARKER)  # a kill leaves the old marker whole (and the new file,
    # which no manifest lists: the result is then kept, never pruned)


def manifest_stamps(folder: Path) -> dict[str, list | None]:
    """The files ``folder``'s manifest lists, each with its stamp (None where it has none);
    {} where there is no manifest that can be read."""
    try:
        record = json.loads((Path(folder) / MARKER).read_text())
        return {str(name): record.get("stamps", {}).get(name) for name in record["files"]}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


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
