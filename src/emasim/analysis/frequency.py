"""Frequency responses from stepped-sine records: the fundamental, crossings of a Bode plot.

A stepped-sine run excites one frequency f; after the transient has settled, the record holds a
whole number of periods. Its fundamental is the least-squares fit

    y(t) ~ c0 + a cos(2 pi f t) + b sin(2 pi f t)

(the constant absorbs an offset), and its phasor Y = b + j a is the complex amplitude of
y = |Y| sin(2 pi f t + arg Y). The frequency response of a system driven by u is H(f) = Y / U,
from the same window. Over whole periods of uniform samples the fit is the DFT bin of f: it
rejects every harmonic exactly, and so reads the describing function of a nonlinearity. (A
trend term would absorb a drift, but it is not orthogonal to the harmonics and lets them leak
into the fundamental: the runs settle before the window instead.)

A swept run (a chirp: emasim.signals.Chirp) excites a band at once; :func:`sweep_response`
reads H(f) = Y(f) / U(f) from the Fourier transforms of the whole record.

Gains are in dB (20 log10 |H|), phases in degrees, unwrapped from the lowest frequency on.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .metrics import sine_basis


def phasor(t: ArrayLike, y: ArrayLike, frequency_Hz: float) -> complex:
    """The fundamental's complex amplitude Y of y(t) at ``frequency_Hz``, y ~ |Y| sin(wt + arg Y)
    (least squares with a constant; t in s, Y in the unit of y)."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 4:
        raise ValueError("phasor needs t and y of the same length, at least 4 samples")
    if not frequency_Hz > 0:
        raise ValueError(f"frequency_Hz must be > 0, got {frequency_Hz}")
    sine, cosine, _ = np.linalg.lstsq(sine_basis(t, frequency_Hz), y, rcond=None)[0]
    return complex(sine, cosine)


def response(t: ArrayLike, u: ArrayLike, y: ArrayLike, frequency_Hz: float) -> complex:
    """H(f) = Y / U: the fundamental of the output over that of the input, same window."""
    u_phasor = phasor(t, u, frequency_Hz)
    if u_phasor == 0:
        raise ValueError(f"the input has no component at {frequency_Hz:g} Hz")
    return phasor(t, y, frequency_Hz) / u_phasor


def sweep_response(
    t: ArrayLike, u: ArrayLike, y: ArrayLike, frequencies_Hz: ArrayLike
) -> np.ndarray:
    """H(f) = Y(f) / U(f) at each of ``frequencies_Hz`` from one record of a swept input:

        U(f) = sum_i u(t_i) exp(-j 2 pi f t_i),  Y(f) likewise,

    the Fourier transforms of the whole record at exactly f (not on an FFT's grid; the sample
    period cancels in the ratio). u and y are deviations from rest that start and end at rest
    (the sweep starts and ends at 0, the response has died out): then no window is needed,
    and for a linear system H is its frequency response wherever the sweep put energy, U(f)
    far from 0. For a nonlinear one it is the best linear approximation for this sweep, not
    the describing function a stepped sine of one amplitude reads (module docstring)."""
    t, u, y = (np.asarray(a, dtype=float) for a in (t, u, y))
    if t.ndim != 1 or t.shape != u.shape or t.shape != y.shape or t.size < 4:
        raise ValueError("sweep_response needs t, u and y of the same length, at least 4")
    out = []
    for f in np.asarray(frequencies_Hz, dtype=float):
        kernel = np.exp(-2j * np.pi * f * t)
        u_f = np.dot(u, kernel)
        if u_f == 0:
            raise ValueError(f"the input has no component at {f:g} Hz")
        out.append(np.dot(y, kernel) / u_f)
    return np.array(out)


def gain_dB(h: ArrayLike) -> np.ndarray:
    """20 log10 |H| (dB); -inf for H = 0."""
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(np.abs(np.asarray(h)))


def phase_deg(h: ArrayLike) -> np.ndarray:
    """arg H in degrees, unwrapped along the array (from its first, lowest frequency, taken in
    (-180, 180]): a lag grows below -180 deg instead of jumping to +180."""
    return np.degrees(np.unwrap(np.angle(np.asarray(h))))


def first_crossing(frequencies_Hz: ArrayLike, values: ArrayLike, level: float) -> float | None:
    """The lowest frequency at which ``values`` falls to ``level`` or below, interpolated
    linearly in log frequency between the two points around it; None if it never does. A
    first value already at or below the level gives the first frequency (no extrapolation)."""
    f, v = np.asarray(frequencies_Hz, dtype=float), np.asarray(values, dtype=float)
    if f.ndim != 1 or f.shape != v.shape or f.size < 1 or np.any(np.diff(f) <= 0) or f[0] <= 0:
        raise ValueError("first_crossing needs positive, strictly increasing frequencies")
    below = np.flatnonzero(v <= level)
    if below.size == 0:
        return None
    k = int(below[0])
    if k == 0:
        return float(f[0])
    fraction = (v[k - 1] - level) / (v[k - 1] - v[k])
    return float(np.exp(np.log(f[k - 1]) + fraction * (np.log(f[k]) - np.log(f[k - 1]))))


def bode_figures(frequencies_Hz: ArrayLike, h: ArrayLike) -> dict[str, float | None]:
    """The datasheet's figures of a closed-loop response H(f): the -3 dB bandwidth (the first
    frequency where |H| falls 3 dB below 0 dB, unity), the frequencies of -45 and -90 deg phase
    lag, the peak gain (dB) and where it occurs. None where the band never reaches a level."""
    f = np.asarray(frequencies_Hz, dtype=float)
    gains, phases = gain_dB(h), phase_deg(h)
    peak = int(np.argmax(gains))
    return {
        "bandwidth_Hz": first_crossing(f, gains, -3.0),
        "phase_45_Hz": first_crossing(f, phases, -45.0),
        "phase_90_Hz": first_crossing(f, phases, -90.0),
        "peak_gain_dB": float(gains[peak]),
        "peak_frequency_Hz": float(f[peak]),
    }
