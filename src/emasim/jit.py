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
"""

import functools

_taught = False


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
