"""Time signals as first-class values: constant, step, sine, ramp and table, and sums of them.

References, load torques and disturbances are all signals. A signal is a list of terms that add
up; each term is a small validated model (usable from scripts and from scenario TOML files,
where it is written as ``{type = "step", time_s = 0.4, final = 10.0}``). Values are in the unit
of the key that holds the signal (``torque_Nm``, ``position_mm``, ...); :func:`encode` scales
them to SI and packs them into a flat float array that the compiled loop evaluates with
:func:`signal_value` and :func:`signal_derivatives` (value, first and second time derivative).

Encoding: ``[n_terms, kind, n_params, params..., kind, n_params, params..., ...]``.
"""

import math
from typing import Annotated, Literal

import numba as nb
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .config import STRICT

KIND_CONSTANT = 0.0
KIND_STEP = 1.0
KIND_SINE = 2.0
KIND_RAMP = 3.0
KIND_TABLE = 4.0


MAX_TIME_S = 1e6  # every time of a signal lies in [0, MAX_TIME_S]
MAX_VALUE = 1e9  # every value of a signal, in the unit of its key, lies within +-MAX_VALUE
MAX_TABLE_POINTS = 1_000_000
Time = Annotated[float, Field(ge=0, le=MAX_TIME_S)]
Value = Annotated[float, Field(ge=-MAX_VALUE, le=MAX_VALUE)]


class _Term(BaseModel):
    model_config = ConfigDict(**STRICT, frozen=True)


class Constant(_Term):
    """y(t) = value."""

    type: Literal["constant"] = "constant"
    value: Value

    def packed(self, scale: float) -> list[float]:
        return [KIND_CONSTANT, 1.0, self.value * scale]


class Step(_Term):
    """y(t) = initial for t < time_s, final from time_s on (derivatives taken as zero)."""

    type: Literal["step"] = "step"
    time_s: Time = 0.0
    final: Value
    initial: Value = 0.0

    def packed(self, scale: float) -> list[float]:
        return [KIND_STEP, 3.0, self.time_s, self.initial * scale, self.final * scale]


class Sine(_Term):
    """y(t) = offset + amplitude sin(2 pi f (t - start_s) + phase) from start_s on.

    Before start_s it holds offset + amplitude sin(phase).
    """

    type: Literal["sine"] = "sine"
    amplitude: Value
    frequency_Hz: float = Field(gt=0, le=1e6)
    phase_deg: float = Field(default=0.0, ge=-3600, le=3600)
    offset: Value = 0.0
    start_s: Time = 0.0

    def packed(self, scale: float) -> list[float]:
        return [
            KIND_SINE,
            5.0,
            self.amplitude * scale,
            2.0 * math.pi * self.frequency_Hz,
            math.radians(self.phase_deg),
            self.offset * scale,
            self.start_s,
        ]


class Ramp(_Term):
    """y(t) = slope_per_s (t - start_s) between start_s and end_s, held after end_s, 0 before.

    Without ``end_s`` the ramp never stops.
    """

    type: Literal["ramp"] = "ramp"
    slope_per_s: Value
    start_s: Time = 0.0
    end_s: Time | None = None

    @model_validator(mode="after")
    def _ordered(self):
        if self.end_s is not None and self.end_s <= self.start_s:
            raise ValueError(f"end_s must be > start_s ({self.start_s}), got {self.end_s}")
        return self

    def packed(self, scale: float) -> list[float]:
        end = math.inf if self.end_s is None else self.end_s
        return [KIND_RAMP, 3.0, self.slope_per_s * scale, self.start_s, end]


class Table(_Term):
    """Piecewise-linear through (time_s[i], values[i]), held constant outside the table."""

    type: Literal["table"] = "table"
    time_s: list[Time] = Field(min_length=2, max_length=MAX_TABLE_POINTS)
    values: list[Value] = Field(min_length=2, max_length=MAX_TABLE_POINTS)

    @model_validator(mode="after")
    def _consistent(self):
        if len(self.time_s) != len(self.values):
            raise ValueError(
                f"time_s and values must have the same length, "
                f"got {len(self.time_s)} and {len(self.values)}"
            )
        if any(b <= a for a, b in zip(self.time_s, self.time_s[1:], strict=False)):
            raise ValueError("time_s must be strictly increasing")
        return self

    def packed(self, scale: float) -> list[float]:
        n = len(self.time_s)
        return [KIND_TABLE, 2.0 * n, *self.time_s, *(v * scale for v in self.values)]


Term = Annotated[Constant | Step | Sine | Ramp | Table, Field(discriminator="type")]


def encode(terms: list, scale: float = 1.0) -> np.ndarray:
    """Pack a list of terms into the flat array read by :func:`signal_value` (values * scale)."""
    flat = [float(len(terms))]
    for term in terms:
        flat.extend(term.packed(scale))
    return np.asarray(flat, dtype=np.float64)


def combine(*encoded: np.ndarray) -> np.ndarray:
    """The sum of several encoded signals, as one encoded signal."""
    n_terms = sum(int(sig[0]) for sig in encoded)
    return np.concatenate([[float(n_terms)], *(sig[1:] for sig in encoded)])


ZERO = encode([])  # the signal that is 0 at all times


@nb.njit(cache=True, error_model="numpy")
def _term(kind, q, t):
    """Value, rate and acceleration of one term with parameters q at time t."""
    if kind == KIND_CONSTANT:
        return q[0], 0.0, 0.0
    if kind == KIND_STEP:
        return (q[2] if t >= q[0] else q[1]), 0.0, 0.0
    if kind == KIND_SINE:
        amp, omega, phase, offset, start = q[0], q[1], q[2], q[3], q[4]
        if t < start:
            return offset + amp * math.sin(phase), 0.0, 0.0
        arg = omega * (t - start) + phase
        return (
            offset + amp * math.sin(arg),
            amp * omega * math.cos(arg),
            -amp * omega * omega * math.sin(arg),
        )
    if kind == KIND_RAMP:
        slope, start, end = q[0], q[1], q[2]
        if t <= start:
            return 0.0, 0.0, 0.0
        if t >= end:
            return slope * (end - start), 0.0, 0.0
        return slope * (t - start), slope, 0.0
    # KIND_TABLE: q = [t_0..t_{n-1}, v_0..v_{n-1}]
    n = q.size // 2
    if t <= q[0]:
        return q[n], 0.0, 0.0
    if t >= q[n - 1]:
        return q[2 * n - 1], 0.0, 0.0
    i = np.searchsorted(q[:n], t, side="right") - 1
    slope = (q[n + i + 1] - q[n + i]) / (q[i + 1] - q[i])
    return q[n + i] + slope * (t - q[i]), slope, 0.0


@nb.njit(cache=True, error_model="numpy")
def signal_derivatives(sig, t):
    """(y, dy/dt, d2y/dt2) of an encoded signal at time t (impulses of steps are not counted)."""
    y = 0.0
    dy = 0.0
    ddy = 0.0
    pos = 1
    for _ in range(int(sig[0])):
        kind = sig[pos]
        n = int(sig[pos + 1])
        a, b, c = _term(kind, sig[pos + 2 : pos + 2 + n], t)
        y += a
        dy += b
        ddy += c
        pos += 2 + n
    return y, dy, ddy


@nb.njit(cache=True, error_model="numpy")
def signal_value(sig, t):
    """y(t) of an encoded signal."""
    return signal_derivatives(sig, t)[0]
