"""Time signals as first-class values: constant, step, sine, ramp, table and chirp, and sums of
them.

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

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .config import STRICT
from .jit import njit

KIND_CONSTANT = 0.0
KIND_STEP = 1.0
KIND_SINE = 2.0
KIND_RAMP = 3.0
KIND_TABLE = 4.0
KIND_CHIRP = 5.0


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


class Chirp(_Term):
    """A logarithmic sweep, from start_s on:

        y(t) = amplitude sin(phi(t)),  phi(t) = 2 pi start_Hz L (exp((t - start_s) / L) - 1),

    with L = T / ln(end_Hz / start_Hz): its frequency start_Hz exp((t - start_s) / L) rises
    from start_Hz to end_Hz over the sweep's length T, and it spends the same time in each
    decade. T is the longest whole number of cycles within duration_s (phi(T) = 2 pi L
    (end_Hz - start_Hz), a multiple of 2 pi), so y starts and ends at 0; y is 0 outside the
    sweep.
    """

    type: Literal["chirp"] = "chirp"
    amplitude: Value
    start_Hz: float = Field(gt=0, le=1e6)
    end_Hz: float = Field(gt=0, le=1e6)
    start_s: Time = 0.0
    duration_s: float = Field(gt=0, le=MAX_TIME_S)

    @model_validator(mode="after")
    def _sweeps(self):
        if self.end_Hz <= self.start_Hz:
            raise ValueError(f"end_Hz must be > start_Hz ({self.start_Hz}), got {self.end_Hz}")
        if self.cycles < 1:
            raise ValueError(
                f"duration_s must hold one whole cycle of the sweep, at least "
                f"{self.log_ratio / (self.end_Hz - self.start_Hz):.6g} s, got {self.duration_s}"
            )
        return self

    @property
    def log_ratio(self) -> float:
        return math.log(self.end_Hz / self.start_Hz)

    @property
    def cycles(self) -> int:
        """The sweep's whole cycles: L (end_Hz - start_Hz) at T = duration_s, rounded down."""
        return math.floor(self.duration_s * (self.end_Hz - self.start_Hz) / self.log_ratio)

    @property
    def sweep_s(self) -> float:
        """T: the sweep's length (s), its whole cycles' time."""
        return self.cycles * self.log_ratio / (self.end_Hz - self.start_Hz)

    def packed(self, scale: float) -> list[float]:
        length = self.sweep_s / self.log_ratio
        return [
            KIND_CHIRP,
            5.0,
            self.amplitude * scale,
            2.0 * math.pi * self.start_Hz,
            length,
            self.start_s,
            self.start_s + self.sweep_s,
        ]


Term = Annotated[Constant | Step | Sine | Ramp | Table | Chirp, Field(discriminator="type")]
TERM_TYPES = frozenset(
    member.model_fields["type"].default for member in (Constant, Step, Sine, Ramp, Table, Chirp)
)


def lookup_table(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The piecewise-linear map y(x), held constant outside [x[0], x[-1]], encoded as a signal
    whose "time" is x (read with signal_value(table, x)); x strictly increasing, any sign."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if x.shape != y.shape or x.size < 2 or np.any(np.diff(x) <= 0.0):
        raise ValueError("lookup_table needs x strictly increasing and y of the same length")
    return np.concatenate(([1.0, KIND_TABLE, 2.0 * x.size], x, y))


def encode(terms: list, scale: float = 1.0) -> np.ndarray:
    """Pack a list of terms into the flat array read by :func:`signal_value` (values * scale)."""
    flat = [float(len(terms))]
    for term in terms:
        flat.extend(term.packed(scale))
    return np.asarray(flat, dtype=np.float64)


ZERO = encode([])  # the signal that is 0 at all times


def signal_values(sig: np.ndarray, t) -> np.ndarray:
    """y(t) of an encoded signal at every time of ``t``, with numpy: the terms of the compiled
    :func:`signal_value` (tests/test_signals.py holds the two equal), for the checks of a
    scenario and for plots, which must not wait for numba to load (emasim.jit)."""
    t = np.asarray(t, dtype=np.float64)
    y = np.zeros_like(t)
    pos = 1
    for _ in range(int(sig[0])):
        kind, n = sig[pos], int(sig[pos + 1])
        q = sig[pos + 2 : pos + 2 + n]
        if kind == KIND_CONSTANT:
            y += q[0]
        elif kind == KIND_STEP:
            y += np.where(t >= q[0], q[2], q[1])
        elif kind == KIND_SINE:
            amp, omega, phase, offset, start = q
            arg = np.where(t < start, phase, omega * (t - start) + phase)
            y += offset + amp * np.sin(arg)
        elif kind == KIND_RAMP:
            slope, start, end = q
            y += slope * (np.clip(t, start, end) - start)
        elif kind == KIND_CHIRP:
            amp, omega, length, start, end = q
            inside = (t >= start) & (t <= end)
            x = np.where(inside, t - start, 0.0)
            y += np.where(inside, amp * np.sin(omega * length * np.expm1(x / length)), 0.0)
        else:
            m = n // 2
            y += np.interp(t, q[:m], q[m:])
        pos += 2 + n
    return y


# The compiled evaluators index the encoded array in place (no slices, no tuple-returning
# helpers that stay out of line): signal_value runs three times per RK4 sub-step, and the
# sliced form cost 70-90 ns a call against 4 ns (benchmarks/bench_engine.py, in one process).


@njit(cache=True, error_model="numpy")
def _table(sig, j, n, t):
    """(value, slope) of the table term whose n times and n values start at sig[j]."""
    if t <= sig[j]:
        return sig[j + n], 0.0
    if t >= sig[j + n - 1]:
        return sig[j + 2 * n - 1], 0.0
    lo, hi = 0, n - 1  # bisection: sig[j + lo] <= t < sig[j + hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if sig[j + mid] <= t:
            lo = mid
        else:
            hi = mid
    i = lo
    slope = (sig[j + n + i + 1] - sig[j + n + i]) / (sig[j + i + 1] - sig[j + i])
    return sig[j + n + i] + slope * (t - sig[j + i]), slope


@njit(cache=True, error_model="numpy")
def _term_value(kind, sig, j, n, t):
    """y(t) of the term of the given kind whose n parameters start at sig[j]."""
    if kind == KIND_CONSTANT:
        return sig[j]
    if kind == KIND_STEP:
        return sig[j + 2] if t >= sig[j] else sig[j + 1]
    if kind == KIND_SINE:
        amp, omega, phase, offset, start = sig[j], sig[j + 1], sig[j + 2], sig[j + 3], sig[j + 4]
        if t < start:
            return offset + amp * math.sin(phase)
        return offset + amp * math.sin(omega * (t - start) + phase)
    if kind == KIND_RAMP:
        slope, start, end = sig[j], sig[j + 1], sig[j + 2]
        if t <= start:
            return 0.0
        if t >= end:
            return slope * (end - start)
        return slope * (t - start)
    if kind == KIND_CHIRP:
        return _chirp(sig, j, t)[0]
    return _table(sig, j, n // 2, t)[0]


@njit(cache=True, error_model="numpy")
def _chirp(sig, j, t):
    """(y, dy/dt, d2y/dt2) of the chirp term whose parameters (amplitude, 2 pi start_Hz, L,
    start, end) start at sig[j]: phi = w0 L (exp(x / L) - 1), phi' = w0 exp(x / L),
    phi'' = phi' / L, x = t - start; 0 outside the sweep."""
    amp, omega, length, start, end = sig[j], sig[j + 1], sig[j + 2], sig[j + 3], sig[j + 4]
    if t < start or t > end:
        return 0.0, 0.0, 0.0
    rate = omega * math.exp((t - start) / length)
    phase = omega * length * math.expm1((t - start) / length)
    s, c = math.sin(phase), math.cos(phase)
    return amp * s, amp * c * rate, amp * (c * rate / length - s * rate * rate)


@njit(cache=True, error_model="numpy")
def _term_derivatives(kind, sig, j, n, t):
    """(y, dy/dt, d2y/dt2) of the term of the given kind whose n parameters start at sig[j]."""
    y = _term_value(kind, sig, j, n, t)
    if kind == KIND_SINE:
        amp, omega, phase, start = sig[j], sig[j + 1], sig[j + 2], sig[j + 4]
        if t >= start:
            arg = omega * (t - start) + phase
            return y, amp * omega * math.cos(arg), -amp * omega * omega * math.sin(arg)
    elif kind == KIND_RAMP:
        if sig[j + 1] < t < sig[j + 2]:
            return y, sig[j], 0.0
    elif kind == KIND_TABLE:
        return y, _table(sig, j, n // 2, t)[1], 0.0
    elif kind == KIND_CHIRP:
        return _chirp(sig, j, t)
    return y, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def signal_derivatives(sig, t):
    """(y, dy/dt, d2y/dt2) of an encoded signal at time t (impulses of steps are not counted)."""
    y = 0.0
    dy = 0.0
    ddy = 0.0
    pos = 1
    for _ in range(int(sig[0])):
        n = int(sig[pos + 1])
        a, b, c = _term_derivatives(sig[pos], sig, pos + 2, n, t)
        y += a
        dy += b
        ddy += c
        pos += 2 + n
    return y, dy, ddy


@njit(cache=True, error_model="numpy")
def signal_value(sig, t):
    """y(t) of an encoded signal."""
    y = 0.0
    pos = 1
    for _ in range(int(sig[0])):
        n = int(sig[pos + 1])
        y += _term_value(sig[pos], sig, pos + 2, n, t)
        pos += 2 + n
    return y


@njit(cache=True, error_model="numpy")
def signal_samples(sig, t):
    """signal_value(sig, t[i]) at every time of the array ``t``, in one compiled call: the
    values the loop reads, bit for bit, without a Python call per sample."""
    y = np.empty(t.size)
    for i in range(t.size):
        y[i] = signal_value(sig, t[i])
    return y
