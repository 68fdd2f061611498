"""numba's disk cache, in a folder keyed by the package's source, so it can never go stale.

numba invalidates a cached function when the file that defines it changes, but not when a file
it calls or reads constants from changes: after an edit to ``plant/actuator.py`` the cached
machine code of ``sim/engine.run_ticks`` would still hold the old right-hand side. So emasim
points numba's cache (``NUMBA_CACHE_DIR``) at ``<base>/emasim-<hash>``, where the hash covers
every ``.py`` file of the installed package: any change to any source file starts a new cache.

``<base>`` is the user's ``NUMBA_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/emasim/numba``
(``~/.cache/emasim/numba``). :func:`configure` runs when emasim is imported, before any
compiled function is defined; a child process inherits the keyed folder and keeps it.
"""

import hashlib
import os
import sys
from pathlib import Path

PACKAGE = Path(__file__).parent
PREFIX = "emasim-"


def source_hash(root: Path = PACKAGE) -> str:
    """SHA-256 (hex, 16 digits) of every .py file under ``root``: names and bytes."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()[:16]


def default_base() -> Path:
    """Where keyed caches live when NUMBA_CACHE_DIR is not set."""
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "emasim" / "numba"


def keyed_folder(base: Path, digest: str) -> Path:
    """``base/emasim-<digest>``; a base that is already a keyed folder of this source stays."""
    name = f"{PREFIX}{digest}"
    return base if base.name == name else base / name


_configured: list[Path] = []  # the folder configure() chose, once it has run


def configure() -> Path:
    """Point numba's cache at the keyed folder (environment, and numba's live config if numba
    is imported already); return the folder."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    folder = keyed_folder(Path(given) if given else default_base(), source_hash())
    _configured[:] = [folder]
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    if "numba" in sys.modules:
        from numba.core import config

        config.CACHE_DIR = str(folder)
    return folder


def configured_folder() -> Path:
    """The keyed folder :func:`configure` chose (it runs when emasim is imported)."""
    return _configured[0] if _configured else configure()


def engine_subfolder(folder: Path) -> Path:
    """Where numba caches ``sim/engine.py`` of this installation inside ``folder``: numba names
    the sub-folder by the source's folder, ``<name>_<sha1 of its absolute path>`` (its
    user-provided cache locator), so each installed copy has its own."""
    source = os.path.abspath(PACKAGE / "sim")
    return folder / f"sim_{hashlib.sha1(source.encode()).hexdigest()}"


def is_cold(folder: Path | None = None) -> bool:
    """True when ``folder`` (a keyed cache; default the one :func:`configure` set when emasim
    was imported) holds no compiled engine loop of this installation yet: the next run
    compiles the simulation core, once."""
    folder = folder if folder is not None else _configured[0]
    return not any(engine_subfolder(folder).glob("engine.run_ticks-*.nbi"))
