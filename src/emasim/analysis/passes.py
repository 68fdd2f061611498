"""Step-response figures in passes over a trace's blocks (emasim.sim.result.Result.blocks), so
that a long run's metrics hold a row group at a time, not its columns.

An :class:`Interval` cuts each block to the rows inside a span of time: a *piece*. Each piece
after the interval's first begins with the last row of the piece before (the blocks' seam row),
so a crossing between two rows always lies inside one piece. Each accumulator gives exactly the
number that the whole-array function of emasim.analysis.metrics gives on the interval's rows,
because it calls that function on one piece (a crossing, an exit), or takes a maximum, which
does not depend on how the rows are grouped; it never sums across pieces. A window whose
figures are sums (the error statistics, the chattering spectrum) is kept by :class:`Rows` and
handed whole to its metrics function: a window is a fraction of the run.
"""

import math

import numpy as np

from . import metrics as m


class Interval:
    """The rows with ``start <= t <= end`` (``t < end`` when ``open_end``), piece by piece."""

    def __init__(self, start: float, end: float, open_end: bool = False):
        self.start, self.end, self.open_end = start, end, open_end
        self.first_t = math.nan  # t of the interval's first row, once a piece has begun it
        self.rows = 0  # how many rows the pieces so far hold, each counted once

    def piece(self, t: np.ndarray, own_from: int) -> tuple[slice, int] | None:
        """The rows of a block (times ``t``; its own rows from ``own_from``) in the interval,
        and how many of them the piece before held (0 or 1); None if it has none of its own."""
        lo = int(np.searchsorted(t, self.start, "left"))
        hi = int(np.searchsorted(t, self.end, "left" if self.open_end else "right"))
        held = 1 if lo == 0 and own_from == 1 and self.rows else 0
        lo = max(lo, own_from - held)
        if hi - lo - held <= 0:
            return None
        if not self.rows:
            self.first_t = float(t[lo])
        self.rows += hi - lo - held
        return slice(lo, hi), held


def finite(name: str, values: np.ndarray) -> None:
    """Raise as the metrics functions do (emasim.analysis.metrics._samples) on a value that is
    not finite."""
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} must contain only finite values")


class FirstCrossing:
    """The first time ``d`` reaches a level (``metrics._first_reach``) or leaves a band
    (``metrics._first_exit``), interpolated; nan if never."""

    def __init__(self, find, level: float):
        self.find, self.level, self.time = find, level, math.nan

    def add(self, t: np.ndarray, d: np.ndarray) -> None:
        if math.isnan(self.time):
            self.time = self.find(t, d, self.level)


class LastExit:
    """``metrics._last_exit``: the time after which ``|d| <= tol`` up to the interval's end. The
    last piece with a row outside decides: the row after its last one outside, if any, is its
    own (a later piece would begin with that row, and have one outside)."""

    def __init__(self, tol: float):
        self.tol, self.last = tol, None

    def add(self, t: np.ndarray, d: np.ndarray) -> None:
        if np.any((d > self.tol) | (d < -self.tol)):
            self.last = (t, d)

    def time(self, first_t: float) -> float:
        """The exit time; ``first_t`` (the interval's first time) if ``d`` never left."""
        return first_t if self.last is None else m._last_exit(*self.last, self.tol)


class Largest:
    """The first row of largest ``key`` (``key(v)``: ``v`` itself, or ``|v|``), its value and
    time, over the rows added (each once)."""

    def __init__(self, magnitude: bool):
        self.magnitude, self.value, self.time, self.key = magnitude, math.nan, math.nan, -math.inf

    def add(self, t: np.ndarray, v: np.ndarray) -> None:
        k = m._largest(v) if self.magnitude else int(np.argmax(v))
        key = abs(v[k]) if self.magnitude else v[k]
        if key > self.key:
            self.value, self.time, self.key = float(v[k]), float(t[k]), key


class Rows:
    """The rows of some columns inside an Interval, kept (own rows once), then joined."""

    def __init__(self, interval: Interval):
        self.interval, self.parts = interval, []

    def add(self, t: np.ndarray, own_from: int, *columns: np.ndarray) -> None:
        cut = self.interval.piece(t, own_from)
        if cut is not None:
            rows, held = cut
            self.parts.append([c[rows][held:] for c in (t, *columns)])

    def joined(self) -> list[np.ndarray]:
        """Each column's rows in the interval, in order."""
        width = len(self.parts[0]) if self.parts else 0
        return [np.concatenate([part[i] for part in self.parts]) for i in range(width)]


class StepInfo:
    """:func:`emasim.analysis.metrics.step_info` (band 2 %) of the rows with ``t < end``, its
    ``initial`` and ``final`` levels given, fed block by block (:meth:`add`)."""

    def __init__(self, initial: float, final: float, end: float, dead_zone: float | None):
        self.initial, self.final = m._step_levels(np.empty(0), initial, final)
        self.step = self.final - self.initial
        self.sign = np.sign(self.step)
        self.interval = Interval(-math.inf, end, open_end=True)
        self.low = FirstCrossing(m._first_reach, 0.1)
        self.high = FirstCrossing(m._first_reach, 0.9)
        self.settle = LastExit(0.02)
        self.beyond, self.peak = Largest(magnitude=False), Largest(magnitude=False)
        self.moved = None if dead_zone is None else FirstCrossing(m._first_exit, dead_zone)
        self.y0 = math.nan  # the interval's first y, from which the dead zone's movement counts

    def add(self, t: np.ndarray, y: np.ndarray, own_from: int) -> None:
        """A block's times ``t`` and outputs ``y`` (its own rows from ``own_from``)."""
        cut = self.interval.piece(t, own_from)
        if cut is None:
            return
        rows, held = cut
        t, y = t[rows], y[rows]
        finite("t", t[held:])
        finite("y", y[held:])
        if np.any(t[1:] <= t[:-1]):
            raise ValueError("t must be strictly increasing")
        progress = (y - self.initial) / self.step
        self.low.add(t, progress)
        self.high.add(t, progress)
        self.settle.add(t, (y - self.final) / abs(self.step))
        self.beyond.add(t[held:], self.sign * (y[held:] - self.final))
        self.peak.add(t[held:], self.sign * y[held:])
        if self.moved is not None:
            self.y0 = y[0] if math.isnan(self.y0) else self.y0
            self.moved.add(t, y - self.y0)

    def info(self) -> dict:
        """The figures, keyed as step_info keys them."""
        rows, t0 = self.interval.rows, self.interval.first_t
        if rows < 2:
            raise ValueError(f"t must be a 1-D array with at least 2 samples, got ({rows},)")
        info = {
            "rise_time_s": self.high.time - self.low.time,
            "settling_time_s": float(np.maximum(self.settle.time(t0) - t0, 0.0)),
            "overshoot_pct": float(100.0 * max(0.0, self.beyond.value) / abs(self.step)),
            "peak": self.sign * self.peak.value,
            "peak_time_s": self.peak.time - t0,
        }
        if self.moved is not None:
            info["dead_zone_time_s"] = self.moved.time - t0
        return info


def load_recovery(read, t_load: float, t_end: float, band: float, dip_fraction: float, *also):
    """:func:`emasim.analysis.metrics.load_recovery` of the rows ``t_load <= t <= t_end`` of
    ``read()``, a new iterable at each call of blocks ``(own_from, (t, y, reference))`` (as
    Result.blocks gives them): one pass for the dip, in which each of ``also`` (a :class:`Rows`
    of t and reference - y) keeps its rows too, and a second for the last exit from the band
    the dip sets. None if the interval holds fewer than 2 rows."""
    interval, dip = Interval(t_load, t_end), Largest(magnitude=True)
    for own_from, (t, y, reference) in read():
        for rows in also:
            rows.add(t, own_from, reference - y)
        for t_piece, error, held in _pieces(interval, t, y, reference, own_from):
            dip.add(t_piece[held:], error[held:])
    if interval.rows < 2:
        return None
    band = max(band, dip_fraction * abs(dip.value))
    settle, again = LastExit(band), Interval(t_load, t_end)
    for own_from, (t, y, reference) in read():
        for t_piece, error, _ in _pieces(again, t, y, reference, own_from):
            settle.add(t_piece, error)
    return m.LoadRecovery(
        dip=dip.value,
        dip_time=dip.time - t_load,
        recovery_time=settle.time(interval.first_t) - t_load,
        band=band,
    )


def _pieces(interval: Interval, t, y, reference, own_from: int):
    """(t, y - reference, held) of the piece of ``interval`` in one block, if it has one."""
    cut = interval.piece(t, own_from)
    if cut is not None:
        rows, held = cut
        t, error = t[rows], y[rows] - reference[rows]
        finite("t", t[held:])
        finite("y - reference", error[held:])
        yield t, error, held
