"""A controller law that raises or returns a non-finite command stops the run in one line.

The compiled loop calls a law through its first-class function pointer, numba's C wrapper
of it. An exception raised in the law cannot cross that wrapper: numba hands it to
``sys.unraisablehook`` ("Exception ignored in ...") and the call returns as if it had
succeeded. While a thread runs the loop (:func:`watching`), emasim's hook takes such an
exception instead of printing it, remembers it and fills the law's output with NaN; the loop's
finite check on every law's output (``engine.control_tick``) then stops the run at that tick,
and :func:`law_failure` words the error: the law, its loop, the time and the value.
"""

import math
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from ..errors import LawFailed

SLOT_NAMES = ("position", "speed", "current")
OUTPUTS = {  # what each slot's law writes that the loop uses (emasim.interface O_*)
    "position": ("out[0] (speed or current command)", "out[1] (its rate)"),
    "speed": ("out[0] (current command)",),
    "current": ("out[0] (d-axis voltage)", "out[1] (q-axis voltage)"),
}

_watched: dict[int, tuple[np.ndarray, list[BaseException]]] = {}
_lock = threading.Lock()
_previous_hook = None


def _hook(unraisable) -> None:
    """sys.unraisablehook: an exception of a law in a watched thread is kept, not printed."""
    watch = _watched.get(threading.get_ident())
    if watch is None or unraisable.exc_value is None:
        return _previous_hook(unraisable)
    out, raised = watch
    if not raised:
        raised.append(unraisable.exc_value)
    out[:] = np.nan  # the loop's finite check stops the run after this call


def _install() -> None:
    global _previous_hook
    with _lock:
        if _previous_hook is None:
            _previous_hook = sys.unraisablehook
            sys.unraisablehook = _hook


@contextmanager
def watching(out: np.ndarray) -> Iterator[list[BaseException]]:
    """While the calling thread runs the loop, the exceptions its laws raise (the list) and
    ``out`` (the laws' output array) filled with NaN when one raises."""
    _install()
    raised: list[BaseException] = []
    ident = threading.get_ident()
    _watched[ident] = (out, raised)
    try:
        yield raised
    finally:
        del _watched[ident]


def law_failure(setup, slot: int, t: float, out: np.ndarray, raised: list) -> LawFailed:
    """The error of law ``slot`` (0 position, 1 speed, 2 current) failing at time ``t``."""
    loop = SLOT_NAMES[slot]
    compiled = getattr(setup, loop)
    name = getattr(compiled.function, "__name__", type(compiled.function).__name__)
    where = f"the {loop} loop's law '{name}'"
    if raised:
        err = raised[0]
        return LawFailed(f"{where} raised {type(err).__name__}: {err} at t = {t:.6g} s")
    values = zip(OUTPUTS[loop], out.tolist(), strict=False)
    bad = ", ".join(f"{what} = {v!r}" for what, v in values if not math.isfinite(v))
    return LawFailed(f"{where} returned {bad} at t = {t:.6g} s; a command must be finite")
