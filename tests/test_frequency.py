"""The frequency-response estimator (emasim.analysis.frequency) on signals with known answers.

A fundamental read from whole periods rejects offsets and harmonics; a pure delay Td
reads as a phase lag of w Td at every frequency; a Bode plot's crossings land where the
closed form puts them.
"""

import math

import numpy as np
import pytest

from emasim.analysis import frequency as fr


def record(f, periods=3, per_period=400):
    return np.arange(periods * per_period) / (per_period * f)


@pytest.mark.parametrize("f", [0.3, 1.0, 17.0])
def test_phasor_rejects_offset_and_harmonics(f):
    t = record(f)
    w = 2 * math.pi * f
    y = 0.7 + 2.0 * np.sin(w * t + 0.4) + 0.3 * np.sin(3 * w * t) + 0.1 * np.cos(2 * w * t)
    y_phasor = fr.phasor(t, y, f)
    # over whole periods of uniform samples every harmonic is orthogonal to the fundamental
    assert abs(abs(y_phasor) - 2.0) < 1e-12
    assert abs(np.angle(y_phasor) - 0.4) < 1e-12


@pytest.mark.parametrize("delay_s", [1e-4, 2e-3, 0.01])
@pytest.mark.parametrize("f", [0.5, 5.0, 20.0])
def test_a_pure_delay_gives_a_phase_lag_of_w_td(f, delay_s):
    t = record(f)
    w = 2 * math.pi * f
    u = 1e-3 * np.sin(w * t)
    y = 1e-3 * np.sin(w * (t - delay_s))
    h = fr.response(t, u, y, f)
    assert abs(abs(h) - 1.0) < 1e-9
    assert abs(-np.angle(h) - w * delay_s) < 1e-9


def test_bode_figures_of_a_pure_delay_and_a_first_order_lag():
    f = np.geomspace(0.1, 100.0, 400)
    s = 2j * np.pi * f
    delay = 0.004
    figures = fr.bode_figures(f, np.exp(-s * delay))
    # phase -w Td: -45 deg at 1 / (8 Td), -90 deg at 1 / (4 Td); the gain never falls
    assert figures["phase_45_Hz"] == pytest.approx(1 / (8 * delay), rel=1e-4)
    assert figures["phase_90_Hz"] == pytest.approx(1 / (4 * delay), rel=1e-4)
    assert figures["bandwidth_Hz"] is None
    corner = 3.0
    lag = fr.bode_figures(f, 1 / (1 + s / (2 * np.pi * corner)))
    # |H| = -3.0103 dB and arg H = -45 deg at the corner; -3 dB a hair below it
    assert lag["phase_45_Hz"] == pytest.approx(corner, rel=1e-4)
    assert lag["bandwidth_Hz"] == pytest.approx(corner * math.sqrt(10**0.3 - 1), rel=1e-4)
    assert lag["phase_90_Hz"] is None


def test_phase_unwraps_past_minus_180():
    h = np.exp(-1j * np.radians([10.0, 100.0, 190.0, 280.0]))
    assert np.allclose(fr.phase_deg(h), [-10.0, -100.0, -190.0, -280.0])


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="frequency_Hz"):
        fr.phasor(np.arange(10.0), np.zeros(10), 0.0)
    with pytest.raises(ValueError, match="no component"):
        fr.response(np.arange(10.0), np.zeros(10), np.zeros(10), 1.0)
    with pytest.raises(ValueError, match="increasing"):
        fr.first_crossing([2.0, 1.0], [0.0, -5.0], -3.0)
