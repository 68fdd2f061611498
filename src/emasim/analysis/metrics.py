"""Performance metrics of actuator responses, each defined exactly once.

All functions are pure and work on 1-D numpy arrays: a time vector ``t`` in seconds
(finite, strictly increasing, not necessarily uniform) and signals of the same length in
any consistent unit, which passes through unchanged (a position in m gives an amplitude
in m, a velocity in rad/s gives a peak in rad/s). Times that are returned are in seconds.

Crossing times are found by linear interpolation between samples, so they are exact for
piecewise-linear signals and accurate to O(dt^2) for smooth ones. Invalid inputs raise
:class:`ValueError` with a message naming the argument and the allowed range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "Chattering",
    "ErrorStats",
    "LoadRecovery",
    "SineFit",
    "SineTracking",
    "chattering",
    "dead_zone_time",
    "error_stats",
    "fluctuation_amplitude",
    "integral_absolute_error",
    "load_recovery",
    "overshoot",
    "peak_value",
    "rise_time",
    "settling_time",
    "sine_fluctuation",
    "sine_tracking",
    "step_info",
    "total_variation_rate",
    "window_mask",
    "window_rows",
]

Window = tuple[float, float] | None

# Detrended residuals whose peak-to-peak is below this fraction of max|y| are round-off,
# so a constant (or, when detrending, a ramp) reads as exactly zero fluctuation.
_ROUNDOFF = 1e3 * np.finfo(float).eps


@dataclass(frozen=True, slots=True)
class ErrorStats:
    """Time-weighted statistics of an error signal (all in the error's unit)."""

    mean: float
    std: float
    rms: float
    max_abs: float


@dataclass(frozen=True, slots=True)
class Chattering:
    """Half peak-to-peak amplitude (signal unit) and dominant frequency (Hz)."""

    amplitude: float
    frequency_Hz: float


@dataclass(frozen=True, slots=True)
class SineTracking:
    """Sine-tracking quality: worst error, gain (-), phase lag (deg) and time lag (s)."""

    max_abs_error: float
    gain: float
    phase_lag_deg: float
    lag_s: float


@dataclass(frozen=True, slots=True)
class LoadRecovery:
    """Response to a load step: largest deviation, its time, the recovery time (s) and the
    recovery band that time was measured against (unit of the output)."""

    dip: float
    dip_time: float
    recovery_time: float
    band: float


# --------------------------------------------------------------------------- validation


def _samples(name: str, values: ArrayLike) -> np.ndarray:
    """``values`` as a finite 1-D float array with at least 2 samples."""
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1 or arr.size < 2:
        raise ValueError(f"{name} must be a 1-D array with at least 2 samples, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must contain only finite values")
    return arr


def _time(t: ArrayLike) -> np.ndarray:
    arr = _samples("t", t)
    if np.any(arr[1:] <= arr[:-1]):  # np.diff(arr) <= 0, without a copy of a long trace
        raise ValueError("t must be strictly increasing")
    return arr


def _signal(name: str, values: ArrayLike, t: np.ndarray) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != t.shape:
        raise ValueError(f"{name} must have the same shape as t {t.shape}, got {arr.shape}")
    return _samples(name, arr)


def _scalar(name: str, value: float) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not np.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return number


def _positive(name: str, value: float) -> float:
    number = _scalar(name, value)
    if number <= 0.0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return number


def _instant(name: str, value: float | None, t: np.ndarray) -> float:
    """A time inside ``[t[0], t[-1])``; ``None`` means ``t[0]``."""
    if value is None:
        return float(t[0])
    value = _scalar(name, value)
    if not t[0] <= value < t[-1]:
        raise ValueError(f"{name} must lie in [t[0], t[-1]) = [{t[0]}, {t[-1]}), got {value}")
    return value


def _step_levels(y: np.ndarray, initial: float | None, final: float | None) -> tuple[float, float]:
    """Initial and final level of a step (defaults ``y[0]`` and ``y[-1]``); must differ."""
    initial = float(y[0]) if initial is None else _scalar("initial", initial)
    final = float(y[-1]) if final is None else _scalar("final", final)
    if final == initial:
        raise ValueError(f"final must differ from initial (both {final}): the step is empty")
    return initial, final


# --------------------------------------------------------------------------- helpers


def window_mask(t: ArrayLike, window: Window) -> np.ndarray:
    """Boolean mask of the samples of ``t`` inside a time window.

    Parameters
    ----------
    t : array_like
        Time in s, finite and strictly increasing, at least 2 samples.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, both ends inclusive, ``t_start <= t_end``;
        ``None`` selects every sample.

    Returns
    -------
    numpy.ndarray of bool
        ``t_start <= t <= t_end``, same shape as ``t``.

    Raises
    ------
    ValueError
        If the window is malformed or selects fewer than 2 samples.
    """
    t = _time(t)
    mask = np.zeros(t.shape, dtype=bool)
    mask[_window_rows(t, window)] = True
    return mask


def window_rows(t: ArrayLike, window: Window) -> slice:
    """The samples of ``t`` inside a time window (:func:`window_mask`: the same arguments and
    errors) as a slice of rows. They are contiguous, so the window of a long trace taken with
    it is a view, never a copy."""
    return _window_rows(_time(t), window)


def _window_rows(t: np.ndarray, window: Window) -> slice:
    """:func:`window_rows` of a ``t`` known to be valid."""
    if window is None:
        return slice(0, t.size)
    try:
        t_start, t_end = (float(edge) for edge in window)
    except (TypeError, ValueError):
        raise ValueError(f"window must be None or (t_start, t_end), got {window!r}") from None
    if not (np.isfinite(t_start) and np.isfinite(t_end) and t_start <= t_end):
        raise ValueError(f"window must be finite with t_start <= t_end, got {window!r}")
    rows = slice(int(np.searchsorted(t, t_start, "left")), int(np.searchsorted(t, t_end, "right")))
    if rows.stop - rows.start < 2:
        raise ValueError(
            f"window {window!r} selects {rows.stop - rows.start} sample(s) of t "
            f"(t spans [{t[0]}, {t[-1]}]); at least 2 are needed"
        )
    return rows


def _windowed(t: np.ndarray, window: Window, *signals: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t`` and each signal restricted to the samples inside ``window``: views."""
    rows = _window_rows(t, window)
    return (t[rows], *(signal[rows] for signal in signals))


def _crossing_time(t: np.ndarray, d: np.ndarray, k: int, level: float) -> float:
    """Time in ``[t[k-1], t[k]]`` where the linear interpolant of ``d`` equals ``level``."""
    return float(t[k - 1] + (t[k] - t[k - 1]) * (level - d[k - 1]) / (d[k] - d[k - 1]))


def _first_reach(t: np.ndarray, d: np.ndarray, level: float) -> float:
    """First time at which ``d >= level`` (interpolated); ``nan`` if never."""
    reached = np.flatnonzero(d >= level)
    if reached.size == 0:
        return np.nan
    k = reached[0]
    return float(t[0]) if k == 0 else _crossing_time(t, d, k, level)


def _outside(d: np.ndarray, tol: float) -> np.ndarray:
    """The rows where ``|d| > tol`` (finite ``d``), without a copy of ``|d|``."""
    return np.flatnonzero((d > tol) | (d < -tol))


def _largest(v: np.ndarray) -> int:
    """The first row of largest ``|v|`` (finite ``v``): ``argmax |v|``, from the first
    largest and the first smallest value, without a copy of ``|v|``."""
    high, low = int(np.argmax(v)), int(np.argmin(v))
    if abs(v[high]) == abs(v[low]):
        return min(high, low)
    return high if abs(v[high]) > abs(v[low]) else low


def _first_exit(t: np.ndarray, d: np.ndarray, tol: float) -> float:
    """First time at which ``|d| > tol`` (interpolated); ``nan`` if never."""
    outside = _outside(d, tol)
    if outside.size == 0:
        return np.nan
    k = outside[0]
    return float(t[0]) if k == 0 else _crossing_time(t, d, k, np.copysign(tol, d[k]))


def _last_exit(t: np.ndarray, d: np.ndarray, tol: float) -> float:
    """Time after which ``|d| <= tol`` up to ``t[-1]`` (interpolated).

    ``t[0]`` if ``d`` is always inside, ``nan`` if it is outside at the last sample.
    """
    outside = _outside(d, tol)
    if outside.size == 0:
        return float(t[0])
    k = outside[-1]
    if k == d.size - 1:
        return np.nan
    return _crossing_time(t, d, k + 1, np.copysign(tol, d[k]))


def _time_average(t: np.ndarray, v: np.ndarray) -> float:
    """Trapezoidal time average of ``v`` over ``[t[0], t[-1]]``."""
    return float(np.trapezoid(v, t) / (t[-1] - t[0]))


def _residual(t: np.ndarray, y: np.ndarray, detrend: bool) -> np.ndarray:
    """``y`` minus its mean, or minus its least-squares line if ``detrend``."""
    if detrend:
        tc = t - t.mean()
        basis = np.column_stack([tc, np.ones_like(tc)])
        coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
        residual = y - basis @ coef
    else:
        residual = y - y.mean()
    if np.ptp(residual) <= _ROUNDOFF * max(abs(float(y.max())), abs(float(y.min()))):
        return np.zeros_like(residual)
    return residual


def _parabolic_peak(spectrum: np.ndarray, k: int) -> float:
    """Fractional index of the peak at bin ``k``: parabola through the log magnitudes."""
    if not 0 < k < spectrum.size - 1:
        return float(k)
    a, b, c = np.log(spectrum[k - 1 : k + 2] + np.finfo(float).tiny)
    curvature = a - 2.0 * b + c
    if curvature >= 0.0:
        return float(k)
    return k + float(np.clip(0.5 * (a - c) / curvature, -0.5, 0.5))


# --------------------------------------------------------------------------- step response


def rise_time(
    t: ArrayLike,
    y: ArrayLike,
    initial: float | None = None,
    final: float | None = None,
    low: float = 0.1,
    high: float = 0.9,
) -> float:
    """Rise time of a step response.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Response, same length as ``t``, any unit.
    initial, final : float, optional
        Levels before and after the step (unit of ``y``); default ``y[0]`` and ``y[-1]``.
        Must differ; a negative step (``final < initial``) is handled symmetrically.
    low, high : float
        Fractions of the step, ``0 <= low < high <= 1``; default 10 % and 90 %.

    Returns
    -------
    float
        ``t_high - t_low`` in s, where ``t_x`` is the first time the progress
        ``p(t) = (y - initial) / (final - initial)`` reaches ``x`` (linear interpolation
        between samples). ``nan`` if either level is never reached.
    """
    t = _time(t)
    y = _signal("y", y, t)
    initial, final = _step_levels(y, initial, final)
    low, high = _scalar("low", low), _scalar("high", high)
    if not 0.0 <= low < high <= 1.0:
        raise ValueError(f"low and high must satisfy 0 <= low < high <= 1, got {low}, {high}")
    progress = (y - initial) / (final - initial)
    return _first_reach(t, progress, high) - _first_reach(t, progress, low)


def settling_time(
    t: ArrayLike,
    y: ArrayLike,
    final: float | None = None,
    initial: float | None = None,
    band: float = 0.02,
    t0: float | None = None,
) -> float:
    """Settling time of a step response.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Response, same length as ``t``, any unit.
    final, initial : float, optional
        Levels after and before the step (unit of ``y``); default ``y[-1]`` and ``y[0]``.
        Must differ.
    band : float
        Half-width of the settling band as a fraction of the step, ``> 0``; default 2 %.
    t0 : float, optional
        Time of the step in s, in ``[t[0], t[-1])``; default ``t[0]``.

    Returns
    -------
    float
        The smallest ``T >= 0`` in s such that
        ``|y(t) - final| <= band * |final - initial|`` for all ``t0 + T <= t <= t[-1]``.
        The last exit from the band is interpolated linearly. 0 if ``y`` is inside the
        band from ``t0`` on; ``nan`` if it is outside at the last sample.
    """
    t = _time(t)
    y = _signal("y", y, t)
    initial, final = _step_levels(y, initial, final)
    band = _positive("band", band)
    t0 = _instant("t0", t0, t)
    deviation = (y - final) / abs(final - initial)
    return float(np.maximum(_last_exit(t, deviation, band) - t0, 0.0))


def overshoot(y: ArrayLike, initial: float | None = None, final: float | None = None) -> float:
    """Percent overshoot of a step response.

    Parameters
    ----------
    y : array_like
        Response, at least 2 samples, any unit.
    initial, final : float, optional
        Levels before and after the step (unit of ``y``); default ``y[0]`` and ``y[-1]``.
        Must differ.

    Returns
    -------
    float
        ``100 * max(0, max(s * (y - final))) / |final - initial|`` in %, with
        ``s = sign(final - initial)``: how far the sampled peak goes beyond ``final``
        in the direction of the step.
    """
    y = _samples("y", y)
    initial, final = _step_levels(y, initial, final)
    step = final - initial
    beyond = np.max(np.sign(step) * (y - final))
    return float(100.0 * max(0.0, beyond) / abs(step))


def dead_zone_time(t: ArrayLike, y: ArrayLike, threshold: float, t0: float | None = None) -> float:
    """Dead-zone time: how long the output stays put after a command at ``t0``.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Output, same length as ``t``, any unit.
    threshold : float
        Movement that ends the dead zone, unit of ``y``, ``> 0``.
    t0 : float, optional
        Time of the command in s, in ``[t[0], t[-1])``; default ``t[0]``.

    Returns
    -------
    float
        Time in s from ``t0`` until ``|y(t) - y(t0)|`` first exceeds ``threshold``,
        with ``y(t0)`` and the crossing interpolated linearly. ``nan`` if never.
    """
    t = _time(t)
    y = _signal("y", y, t)
    threshold = _positive("threshold", threshold)
    t0 = _instant("t0", t0, t)
    y0 = np.interp(t0, t, y)
    after = t > t0
    times = np.concatenate([[t0], t[after]])
    movement = np.concatenate([[0.0], y[after] - y0])
    return _first_exit(times, movement, threshold) - t0


def step_info(
    t: ArrayLike,
    y: ArrayLike,
    initial: float | None = None,
    final: float | None = None,
    band: float = 0.02,
    dead_zone_threshold: float | None = None,
) -> dict[str, float]:
    """Step-response summary, in the spirit of ``control.step_info``.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing; the step is taken to occur at ``t[0]``.
    y : array_like
        Response, same length as ``t``, any unit.
    initial, final : float, optional
        Levels before and after the step; default ``y[0]`` and ``y[-1]``. Must differ.
    band : float
        Settling band as a fraction of the step, ``> 0``; default 2 %.
    dead_zone_threshold : float, optional
        If given (unit of ``y``, ``> 0``), also report the dead-zone time.

    Returns
    -------
    dict of str to float
        ``rise_time_s`` (10-90 %, :func:`rise_time`), ``settling_time_s``
        (:func:`settling_time` from ``t[0]``), ``overshoot_pct`` (:func:`overshoot`),
        ``peak`` (the sample of ``y`` farthest in the direction of the step, unit of
        ``y``), ``peak_time_s`` (its time from ``t[0]``, not interpolated), and
        ``dead_zone_time_s`` (:func:`dead_zone_time` from ``t[0]``) when
        ``dead_zone_threshold`` is given.
    """
    t = _time(t)
    y = _signal("y", y, t)
    initial, final = _step_levels(y, initial, final)
    k = int(np.argmax(np.sign(final - initial) * y))
    info = {
        "rise_time_s": rise_time(t, y, initial, final),
        "settling_time_s": settling_time(t, y, final=final, initial=initial, band=band),
        "overshoot_pct": overshoot(y, initial, final),
        "peak": float(y[k]),
        "peak_time_s": float(t[k] - t[0]),
    }
    if dead_zone_threshold is not None:
        info["dead_zone_time_s"] = dead_zone_time(t, y, dead_zone_threshold)
    return info


def control_step_info(
    t: ArrayLike,
    y: ArrayLike,
    initial: float | None = None,
    final: float | None = None,
    SettlingTimeThreshold: float = 0.02,  # noqa: N803 - python-control's option names
    RiseTimeLimits: tuple[float, float] = (0.1, 0.9),  # noqa: N803
) -> dict[str, float]:
    """:func:`step_info` under python-control's key names and options (``control.step_info``).

    Parameters
    ----------
    t, y : array_like
        Time (s) and response, as :func:`step_info` takes them.
    initial, final : float, optional
        The levels before and after the step, as :func:`step_info` takes them.
    SettlingTimeThreshold : float
        The settling band as a fraction of the step, default 2 %.
    RiseTimeLimits : tuple of float
        The rise time's fractions of the step, default (0.1, 0.9).

    Returns
    -------
    dict of str to float
        ``RiseTime``, ``SettlingTime``, ``SettlingMin`` and ``SettlingMax`` (the extremes of
        ``y`` from the rise's upper limit on), ``Overshoot`` and ``Undershoot`` (% of the
        step, beyond the final level and back past the initial one), ``Peak`` (the largest
        ``|y|``, as python-control reports it), ``PeakTime`` (from ``t[0]``) and
        ``SteadyStateValue`` (``final``). Unlike python-control's, which measures a response
        from 0, the step goes from ``initial`` (default ``y[0]``); from 0 both agree to the
        interpolation between samples (``tests/test_metrics.py``).
    """
    t = _time(t)
    y = _signal("y", y, t)
    initial, final = _step_levels(y, initial, final)
    low, high = RiseTimeLimits
    step = final - initial
    progress = (y - initial) / step
    upper = int(np.argmax(progress >= high)) if np.any(progress >= high) else y.size - 1
    k = int(np.argmax(np.abs(y)))
    return {
        "RiseTime": rise_time(t, y, initial, final, low, high),
        "SettlingTime": settling_time(
            t, y, final=final, initial=initial, band=SettlingTimeThreshold
        ),
        "SettlingMin": float(np.min(y[upper:])),
        "SettlingMax": float(np.max(y[upper:])),
        "Overshoot": overshoot(y, initial, final),
        "Undershoot": float(max(0.0, -100.0 * np.min(progress))),
        "Peak": float(abs(y[k])),
        "PeakTime": float(t[k] - t[0]),
        "SteadyStateValue": float(final),
    }


# --------------------------------------------------------------------------- windowed metrics


def error_stats(t: ArrayLike, error: ArrayLike, window: Window = None) -> ErrorStats:
    """Statistics of a tracking error over a time window.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    error : array_like
        Error signal, same length as ``t``, any unit.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, inclusive (see :func:`window_mask`); ``None`` = all.

    Returns
    -------
    ErrorStats
        ``mean`` = <e>, ``std`` = sqrt(<(e - mean)^2>) (population, no Bessel
        correction), ``rms`` = sqrt(<e^2>), ``max_abs`` = max |e| over the samples, all in
        the unit of ``error``.

    Notes
    -----
    ``<v>`` is the time average ``integral(v dt) / (t_end - t_start)`` by the trapezoidal
    rule over the samples in the window, so non-uniform grids are weighted correctly; on
    a uniform grid it differs from the plain sample mean only by the half weight of the
    two end samples. ``rms**2 == mean**2 + std**2`` up to round-off.
    """
    t = _time(t)
    error = _signal("error", error, t)
    tw, ew = _windowed(t, window, error)
    mean = _time_average(tw, ew)
    return ErrorStats(
        mean=mean,
        std=float(np.sqrt(_time_average(tw, (ew - mean) ** 2))),
        rms=float(np.sqrt(_time_average(tw, ew**2))),
        max_abs=max(abs(float(ew.max())), abs(float(ew.min()))),
    )


def peak_value(t: ArrayLike, y: ArrayLike, window: Window = None) -> float:
    """Signed sample of largest magnitude in a window (e.g. peak velocity).

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Signal, same length as ``t``, any unit.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, inclusive; ``None`` = all samples.

    Returns
    -------
    float
        ``y[k]`` with ``k = argmax |y|`` over the window (first one on ties), unit of ``y``.
    """
    t = _time(t)
    y = _signal("y", y, t)
    _, yw = _windowed(t, window, y)
    return float(yw[_largest(yw)])


def fluctuation_amplitude(
    t: ArrayLike, y: ArrayLike, window: Window = None, detrend: bool = True
) -> float:
    """Fluctuation amplitude (e.g. of velocity) in a window.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Signal, same length as ``t``, any unit.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, inclusive; ``None`` = all samples.
    detrend : bool
        Remove the least-squares line ``a t + b`` fitted to the window's samples first
        (default); otherwise only the mean is removed, which leaves ``max - min`` as is.

    Returns
    -------
    float
        ``(max(r) - min(r)) / 2`` of the residual ``r`` in the window, unit of ``y``.

    Notes
    -----
    The fitted line absorbs a little of a slow oscillation: for a sine of amplitude
    ``A`` and frequency ``f`` in a window of duration ``T``, the result can exceed ``A``
    by up to about ``6 A / (2 pi f T)`` (nothing when the window is symmetric about a
    crest). Residuals with peak-to-peak below ``1e3 * eps * max|y|`` are round-off and
    give 0.
    """
    t = _time(t)
    y = _signal("y", y, t)
    tw, yw = _windowed(t, window, y)
    return float(np.ptp(_residual(tw, yw, detrend)) / 2.0)


def chattering(
    t: ArrayLike, y: ArrayLike, window: Window = None, *, detrend: bool = True
) -> Chattering:
    """Chattering amplitude and dominant frequency in a window.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing, possibly non-uniform.
    y : array_like
        Signal (e.g. control input or velocity), same length as ``t``, any unit.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, inclusive; ``None`` = all samples.
    detrend : bool, keyword-only
        Remove the least-squares line over the window (default) rather than the mean only.

    Returns
    -------
    Chattering
        ``amplitude``: ``(max(r) - min(r)) / 2`` of the residual ``r`` (``y`` minus its
        mean, or minus its linear trend if ``detrend``), unit of ``y``; equal to
        :func:`fluctuation_amplitude`.
        ``frequency_Hz``: the dominant frequency of ``r`` in Hz, 0 if ``r`` is zero
        (constant signal, or a pure ramp when detrending).

    Notes
    -----
    ``r`` is resampled with ``numpy.interp`` onto a uniform grid starting at the first
    sample of the window, with step ``dt`` = the median sample spacing in the window and
    ``n = floor(duration / dt) + 1`` points. It is multiplied by a periodic Hann window
    and transformed with ``numpy.fft.rfft``; the largest magnitude bin ``k >= 1`` is
    refined by a parabola through the log magnitudes of bins ``k-1, k, k+1``, and the
    frequency is ``(k + delta) / (n dt)``. The resolution is about ``1 / duration``
    before refinement, so the window should hold several periods. See
    :func:`fluctuation_amplitude` for the effect of detrending on the amplitude.
    """
    t = _time(t)
    y = _signal("y", y, t)
    tw, yw = _windowed(t, window, y)
    residual = _residual(tw, yw, detrend)
    amplitude = float(np.ptp(residual) / 2.0)
    if amplitude == 0.0:
        return Chattering(amplitude=0.0, frequency_Hz=0.0)
    dt = float(np.median(np.diff(tw)))
    n = int((tw[-1] - tw[0]) // dt) + 1
    uniform = np.interp(tw[0] + dt * np.arange(n), tw, residual)
    spectrum = np.abs(np.fft.rfft(uniform * np.hanning(n + 1)[:-1]))
    k = 1 + int(np.argmax(spectrum[1:]))
    return Chattering(amplitude=amplitude, frequency_Hz=_parabolic_peak(spectrum, k) / (n * dt))


def integral_absolute_error(t: ArrayLike, error: ArrayLike, window: Window = None) -> float:
    """IAE = integral of |error| dt over the window (trapezoidal rule), unit of error times s."""
    t = _time(t)
    error = _signal("error", error, t)
    tw, ew = _windowed(t, window, error)
    return float(np.trapezoid(np.abs(ew), tw))


def total_variation_rate(t: ArrayLike, y: ArrayLike, window: Window = None) -> float:
    """Total variation per second, sum |y[k+1] - y[k]| / duration (unit of y per s).

    A measure of control activity: a steady command scores 0, chattering scores high. It grows
    as the sampling gets finer for a signal that jumps every sample, so compare runs at the same
    sample period.
    """
    t = _time(t)
    y = _signal("y", y, t)
    tw, yw = _windowed(t, window, y)
    return float(np.sum(np.abs(np.diff(yw))) / (tw[-1] - tw[0]))


def sine_basis(t: np.ndarray, frequency_Hz: float) -> np.ndarray:
    """Columns sin(2 pi f t), cos(2 pi f t), 1 for a least-squares sine fit."""
    omega_t = 2.0 * np.pi * frequency_Hz * t
    return np.column_stack([np.sin(omega_t), np.cos(omega_t), np.ones_like(t)])


def sine_fluctuation(
    t: ArrayLike, y: ArrayLike, frequency_Hz: float, window: Window = None
) -> float:
    """Half peak-to-peak of what is left of ``y`` after its best-fitting sine at ``f``.

    The fluctuation of a signal that should be a sine (e.g. a velocity under sine tracking):
    ``y`` is fitted over the window by least squares to ``a sin(2 pi f t) + b cos(2 pi f t)
    + c`` and the result is ``(max(r) - min(r)) / 2`` of the residual ``r`` (unit of ``y``).
    """
    t = _time(t)
    y = _signal("y", y, t)
    frequency_Hz = _positive("frequency_Hz", frequency_Hz)
    tw, yw = _windowed(t, window, y)
    basis = sine_basis(tw, frequency_Hz)
    residual = yw - basis @ np.linalg.lstsq(basis, yw, rcond=None)[0]
    return float(np.ptp(residual) / 2.0)


def sine_tracking(
    t: ArrayLike,
    y: ArrayLike,
    reference: ArrayLike,
    frequency_Hz: float,
    window: Window = None,
) -> SineTracking:
    """Gain and phase of a response tracking a sinusoidal reference.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Response, same length as ``t``.
    reference : array_like
        Sinusoidal reference, same length and unit as ``y``.
    frequency_Hz : float
        Frequency ``f`` of the reference in Hz, ``> 0``.
    window : tuple of float or None
        ``(t_start, t_end)`` in s, inclusive; ``None`` = all samples. Choose it after
        the transient, ideally spanning whole periods.

    Returns
    -------
    SineTracking
        ``max_abs_error`` = max |reference - y| over the window (unit of ``y``);
        ``gain`` = ``A_y / A_ref`` (-); ``phase_lag_deg`` = ``phi_ref - phi_y`` in deg,
        wrapped to (-180, 180], positive when ``y`` lags; ``lag_s`` =
        ``phase_lag_deg / (360 f)`` in s.

    Notes
    -----
    Both signals are fitted by linear least squares (``numpy.linalg.lstsq``) over the
    window to ``a sin(2 pi f t) + b cos(2 pi f t) + c = A sin(2 pi f t + phi) + c``,
    with ``A = hypot(a, b)`` and ``phi = atan2(b, a)``.
    """
    t = _time(t)
    y = _signal("y", y, t)
    reference = _signal("reference", reference, t)
    fit = SineFit(_positive("frequency_Hz", frequency_Hz))
    fit.add(*_windowed(t, window, y, reference))
    return fit.tracking()


class SineFit:
    """:func:`sine_tracking` of samples given a block at a time (a long run's row groups).

    ``add(t, y, reference)`` adds a block; ``tracking()`` is the SineTracking of every sample
    added. The least-squares rows ``[sin(2 pi f t), cos(2 pi f t), 1 | y, reference]`` of
    the blocks are kept as their 5 x 5 triangular factor R (Householder QR, numpy.linalg.qr)
    once a second block comes: the least-squares solution of R's rows is that of the rows it
    replaces, so memory holds one block. One block is solved as it is, as sine_tracking
    always has been."""

    def __init__(self, frequency_Hz: float):
        self.frequency_Hz = frequency_Hz
        self._rows = None
        self._max_abs_error = -np.inf

    def add(self, t: np.ndarray, y: np.ndarray, reference: np.ndarray) -> None:
        rows = np.column_stack([sine_basis(t, self.frequency_Hz), y, reference])
        if self._rows is not None:
            rows = np.linalg.qr(np.vstack([self._rows, rows]), mode="r")
        self._rows = rows
        largest = np.max(np.abs(reference - y))
        self._max_abs_error = float(np.max([self._max_abs_error, largest]))  # NaN stays NaN

    def tracking(self) -> SineTracking:
        rows = self._rows
        (a_y, a_r), (b_y, b_r), _ = np.linalg.lstsq(rows[:, :3], rows[:, 3:], rcond=None)[0]
        amplitude_ref = np.hypot(a_r, b_r)
        if amplitude_ref == 0.0:
            raise ValueError("reference must have a nonzero component at frequency_Hz")
        lag = np.degrees(np.arctan2(b_r, a_r) - np.arctan2(b_y, a_y))
        lag = float(lag - 360.0 * np.ceil((lag - 180.0) / 360.0))
        return SineTracking(
            max_abs_error=self._max_abs_error,
            gain=float(np.hypot(a_y, b_y) / amplitude_ref),
            phase_lag_deg=lag,
            lag_s=lag / (360.0 * self.frequency_Hz),
        )


def load_recovery(
    t: ArrayLike,
    y: ArrayLike,
    reference: ArrayLike | float,
    t_load: float,
    band: float,
    t_end: float | None = None,
    dip_fraction: float = 0.0,
) -> LoadRecovery:
    """Dip and recovery of a regulated output after a load step.

    Parameters
    ----------
    t : array_like
        Time in s, strictly increasing.
    y : array_like
        Regulated output, same length as ``t``.
    reference : array_like or float
        Set point, an array like ``y`` or a scalar, unit of ``y``.
    t_load : float
        Time of the load step in s, in ``[t[0], t[-1])``.
    band : float
        Recovery band, absolute, unit of ``y``, ``> 0``: with ``dip_fraction`` the floor
        of the band.
    t_end : float, optional
        End of the evaluation in s; default ``t[-1]``.
    dip_fraction : float
        Fraction of ``|dip|``, ``>= 0``, that widens the band to the disturbance; default 0
        (the band is ``band``).

    Returns
    -------
    LoadRecovery
        Over the samples with ``t_load <= t <= t_end``, with ``e = y - reference``:
        ``dip`` = the signed ``e`` of largest magnitude (unit of ``y``); ``dip_time`` =
        its time from ``t_load`` in s; ``band`` = ``max(band, dip_fraction * |dip|)``
        (unit of ``y``); ``recovery_time`` = the time in s from ``t_load`` after which
        ``|e| <= band`` up to ``t_end``, last exit interpolated linearly, 0 if ``e`` never
        leaves the band, ``nan`` if ``|e| > band`` at the last sample.
    """
    t = _time(t)
    y = _signal("y", y, t)
    if np.ndim(reference) == 0:
        reference = np.full_like(t, _scalar("reference", reference))
    reference = _signal("reference", reference, t)
    t_load = _instant("t_load", t_load, t)
    band = _positive("band", band)
    dip_fraction = _scalar("dip_fraction", dip_fraction)
    if dip_fraction < 0.0:
        raise ValueError(f"dip_fraction must be a finite number >= 0, got {dip_fraction!r}")
    t_end = float(t[-1]) if t_end is None else _scalar("t_end", t_end)
    if t_end <= t_load:
        raise ValueError(f"t_end must be > t_load = {t_load}, got {t_end}")
    tw, yw, rw = _windowed(t, (t_load, t_end), y, reference)
    ew = yw - rw
    k = _largest(ew)
    band = max(band, dip_fraction * abs(float(ew[k])))
    return LoadRecovery(
        dip=float(ew[k]),
        dip_time=float(tw[k] - t_load),
        recovery_time=_last_exit(tw, ew, band) - t_load,
        band=band,
    )
