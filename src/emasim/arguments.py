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
        if math.isfinite(high):
            span = f" from {low:g} to {high:g}"
        else:
            span = f" of at least {low:g}" if math.isfinite(low) else ""
        raise InputError(f"{name} must be a finite number{span}, got {value!r}")
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


def positive(name: str, value, high: float = math.inf) -> float:
    """``value`` as a float: a real number, finite, above 0 and at most ``high``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(value) and 0 < value <= high):
        most = f" and at most {high:g}" if math.isfinite(high) else ""
        raise InputError(f"{name} must be a finite number above 0{most}, got {value!r}")
    return float(value)


def integer(name: str, value, low: int, high: float = math.inf) -> int:
    """``value``, a whole number (an int, not a bool nor a float) from ``low`` to ``high``."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        most = f"from {low} to {high:g}" if math.isfinite(high) else f"of at least {low}"
        raise InputError(f"{name} must be a whole number {most}, got {value!r}")
    return value


def positive_numbers(name: str, value) -> tuple[float, ...]:
    """``value`` as a tuple of floats: a non-empty list or tuple of finite numbers above 0."""
    if (
        isinstance(value, str)
        or not isinstance(value, Sequence)
        or not value
        or not all(
            not isinstance(item, bool)
            and isinstance(item, int | float)
            and math.isfinite(item)
            and item > 0
            for item in value
        )
    ):
        raise InputError(
            f"{name} must be a non-empty list of finite numbers above 0, got {value!r}"
        )
    return tuple(float(item) for item in value)


def choice(name: str, value, allowed) -> str:
    """``value``, one of the strings ``allowed`` (anything else, a list included, refused)."""
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
    return value


def optional_string(name: str, value) -> str | None:
    """``value``, a string or None."""
    if value is not None and not isinstance(value, str):
        raise InputError(f"{name} must be a string or None, got {value!r}")
    return value


def function_or_none(name: str, value, what: str = "a function"):
    """``value``, a callable or None."""
    if value is not None and not callable(value):
        raise InputError(f"{name} must be {what} or None, got {value!r}")
    return value


def client_or_none(name: str, value):
    """``value``, a Dask client (anything with a ``submit`` method) or None."""
    if value is not None and not callable(getattr(value, "submit", None)):
        raise InputError(f"{name} must be a dask.distributed.Client or None, got {value!r}")
    return value
