"""The package's version, read from the installed metadata when first asked for.

Importing importlib.metadata costs 70 ms, a seventh of a command that only checks a scenario,
so ``__version__`` is made on first use (a module ``__getattr__``). Every module reads it from
here, not from the package's ``__init__``, so that no module imports the package root, which
loads the command-level API when asked (no import cycle).
"""

import functools


@functools.cache
def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("emasim")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "0.0.0+unknown"


def __getattr__(name: str):
    if name == "__version__":
        return _version()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
