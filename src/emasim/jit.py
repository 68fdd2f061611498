"""Compiled functions that import numba only when they are first used.

Importing numba takes about half a second, and checking a scenario, listing what emasim has or
printing its help needs none of it. So emasim's compiled functions are declared with
:func:`njit`, which takes numba's options and returns a :class:`Deferred`: the Python function,
waiting. The first use (a call, or any attribute of a numba dispatcher, such as ``overloads``
or ``compile``) imports numba and makes the dispatcher, ``numba.njit(*signature,
**options)(function)``; everything after that goes to the dispatcher.

Compiled code that calls a Deferred sees the dispatcher: numba is taught (:func:`_teach_numba`)
to type a Deferred as its dispatcher, and numba's inliner (``inline="always"``) reads the
options and the Python function through the attributes, as it does from a dispatcher.

numba's first compile or cache load in a process imports its array library
(``numba.np.arraymath``), which checks once that BLAS is there by importing ``scipy.linalg``:
0.15 to 0.25 s of every run, for a module none of emasim's compiled code calls into.
:func:`_spare_scipy_linalg` answers that one check from scipy's files instead (the answer is
the same); every later check, such as the compile of a function that calls ``np.dot``, is
numba's own.
"""

import functools
import importlib.machinery
import importlib.util
import sys
from pathlib import Path

_taught = False
_spared = False


def _teach_numba() -> None:
    """Register with numba's ``typeof``: a Deferred has the type of its dispatcher."""
    global _taught
    if _taught:
        return
    from numba.core import types
    from numba.core.typing.typeof import typeof_impl

    @typeof_impl.register(Deferred)
    def _typeof_deferred(value, context):
        return types.Dispatcher(value.dispatcher)

    _taught = True


def _scipy_ships_cython_blas() -> bool:
    """Whether scipy's ``linalg/cython_blas`` extension is installed, found without importing
    it (importing it imports all of ``scipy.linalg``)."""
    scipy = sys.modules.get("scipy")
    if scipy is not None:
        places = list(getattr(scipy, "__path__", ()))
    else:
        spec = importlib.util.find_spec("scipy")
        places = list(spec.submodule_search_locations or ()) if spec is not None else []
    return any(
        (Path(place) / "linalg" / f"cython_blas{suffix}").is_file()
        for place in places
        for suffix in importlib.machinery.EXTENSION_SUFFIXES
    )


def _spare_scipy_linalg() -> None:
    """Let numba's import-time BLAS check (``numba.np.arraymath._check_blas``, run by the
    first compile or cache load) find ``scipy.linalg.cython_blas`` on disk rather than import
    all of ``scipy.linalg`` (module docstring). Only that first check is answered so: it puts
    numba's own ``ensure_blas`` back before it returns, and when the extension is not on disk
    it runs numba's check, which raises as before. numba's check that scipy's BLAS integers
    are as wide as numba's still runs."""
    global _spared
    if _spared:
        return
    _spared = True
    if "numba.np.arraymath" in sys.modules:  # numba has checked already
        return
    from numba.np import linalg

    numbas_check = getattr(linalg, "ensure_blas", None)
    if numbas_check is None:  # a numba that checks otherwise: its own way, untouched
        return

    def first_check() -> None:
        linalg.ensure_blas = numbas_check
        if not _scipy_ships_cython_blas():
            numbas_check()  # raises ImportError, as numba's check does without scipy's BLAS
            return
        getattr(linalg, "_check_lapack_int_width", lambda: None)()

    linalg.ensure_blas = first_check


class Deferred:
    """A function to be compiled by numba on first use (module docstring)."""

    def __init__(self, function, signature: tuple, options: dict):
        functools.update_wrapper(self, function)
        self.py_func = function
        self._signature = signature
        self._options = options
        self._dispatcher = None

    @property
    def dispatcher(self):
        """numba's dispatcher of the function, made (and numba imported) on first use."""
        if self._dispatcher is None:
            import numba

            _teach_numba()
            _spare_scipy_linalg()
            self._dispatcher = numba.njit(*self._signature, **self._options)(self.py_func)
        return self._dispatcher

    def __call__(self, *args):
        return self.dispatcher(*args)

    def __getattr__(self, name):
        # only reached for what a Deferred does not hold itself: the dispatcher's attributes
        if name.startswith("__") or name in ("_signature", "_options", "_dispatcher"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self) -> str:
        state = "compiled" if self._dispatcher is not None else "deferred"
        return f"<emasim.jit.Deferred {self.__qualname__} ({state})>"


def njit(*signature, **options):
    """``numba.njit`` with the same arguments (an optional signature, then options), deferred
    until first use: ``@njit(cache=True, error_model="numpy")``."""

    def decorate(function) -> Deferred:
        return Deferred(function, signature, options)

    return decorate
