"""The base of every validated configuration model, and the unit factors used at the edges.

Validation is strict: a number field takes a TOML integer or float, never a string or a bool
(``duration_s = "0.05"`` and ``duration_s = true`` are refused, not coerced); no unknown keys,
no NaN or infinity. Every number has both a lower and an upper bound (a test walks the models
to keep it so). A fixed-length tuple of numbers, such as a point, is written in TOML as an
array: :func:`numbers` declares one, each element strictly typed and bounded.
"""

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field
from pydantic import Strict as StrictType

RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
MM = 1e-3  # m per mm

STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True, defer_build=True)


class Strict(BaseModel):
    """Base of every configuration model: strict types, no unknown keys, no NaN/inf,
    assignment validated."""

    model_config = ConfigDict(**STRICT, validate_assignment=True)


def numbers(count: int, **bounds):
    """A tuple of ``count`` floats, each strictly typed and within ``bounds`` (Field's ge, gt,
    le, lt), given in TOML as an array (the tuple itself accepts a list)."""
    element = Annotated[float, StrictType(), Field(**bounds)]
    return Annotated[tuple[(element,) * count], Field(strict=False)]


def hard_limits(config, field: str) -> tuple[float, float]:
    """The open interval a config field's validation admits (its gt/ge and lt/le), as
    (lower, upper); a log search needs lower > 0."""
    low, high = 0.0, math.inf
    for rule in type(config).model_fields[field].metadata:
        low = max(low, getattr(rule, "gt", None) or getattr(rule, "ge", None) or low)
        high = min(high, getattr(rule, "lt", None) or getattr(rule, "le", None) or high)
    return low, high
