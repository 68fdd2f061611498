"""The Python API's checks of its arguments: each wrong type or value one
:class:`emasim.InputError` line naming the argument and what it allows, raised when the
function is called (never a TypeError from deep inside, nor a string read as its characters).

Each check returns the value (a number as a float), so a caller writes
``at_s = number("linearize: at_s", at_s, 0.0, duration)``.
"""

import math
from collections.abc import Sequence

from .errors import InputError


def number(name: str, value, low: float = -math.inf, high: float = math.inf) -> float:
    """``value`` as a float: a real number (not a bool, not a string), finite, low..high."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(value) and low <= value <= high):
        raise InputError(f"{name} must be a finite number from {low:g} to {high:g}, got {value!r}")
    return float(value)


def flag(name: str, value) -> bool:
    """``value``, which must be True or False (a string such as "no" is refused)."""
    if not isinstance(value, bool):
        raise InputError(f"{name} must be True or False, got {value!r}")
    return value


def strings(name: str, value) -> list[str]:
    """``value`` as a list of strings: a list or tuple of them (one string alone is refused,
    never read as its characters)."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputError(f"{name} must be a list of strings, e.g. [{value!r}], got {value!r}")
    if not all(isinstance(item, str) for item in value):
        raise InputError(f"{name} must be a list of strings, got {value!r}")
    return list(value)
