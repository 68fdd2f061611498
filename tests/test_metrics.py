"""Tests of emasim.analysis.metrics against signals with closed-form answers."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import emasim.analysis.metrics as m
from emasim.analysis.metrics import (
    Chattering,
    chattering,
    dead_zone_time,
    error_stats,
    fluctuation_amplitude,
    load_recovery,
    overshoot,
    peak_value,
    rise_time,
    settling_time,
    sine_tracking,
    step_info,
    window_mask,
)

TAU = 0.1  # s, first-order time constant
ZETA, WN = 0.3, 2 * np.pi * 5.0  # second-order damping (-) and natural frequency (rad/s)


def uniform_grid(t_end, dt):
    return np.linspace(0.0, t_end, round(t_end / dt) + 1)


def jittered_grid(t_end, dt, seed=0):
    """Non-uniform grid: a uniform one with each interior sample moved by up to 0.4 dt."""
    t = uniform_grid(t_end, dt)
    t[1:-1] += np.random.default_rng(seed).uniform(-0.4, 0.4, t.size - 2) * dt
    return t


def first_order(t):
    return 1.0 - np.exp(-t / TAU)


def second_order(t):
    wd = WN * math.sqrt(1 - ZETA**2)
    return 1.0 - np.exp(-ZETA * WN * t) / math.sqrt(1 - ZETA**2) * np.sin(wd * t + math.acos(ZETA))


OVERSHOOT_2ND = 100 * math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2))
PEAK_TIME_2ND = math.pi / (WN * math.sqrt(1 - ZETA**2))


# --------------------------------------------------------------------------- step metrics


@pytest.mark.parametrize("grid", [uniform_grid, jittered_grid])
def test_first_order_step(grid):
    t = grid(2.5, 1e-4)  # exp(-25) ~ 1e-11: y[-1] is the final value
    y = first_order(t)
    assert rise_time(t, y) == pytest.approx(TAU * math.log(9), rel=1e-6)
    assert settling_time(t, y) == pytest.approx(TAU * math.log(50), rel=1e-6)
    assert settling_time(t, y, band=0.05) == pytest.approx(TAU * math.log(20), rel=1e-6)
    assert overshoot(y) == 0.0


def test_rise_time_custom_levels_and_explicit_final():
    t = uniform_grid(0.5, 1e-5)  # y[-1] = 0.993: final must be given
    y = first_order(t)
    expected = TAU * math.log(0.95 / 0.05)
    assert rise_time(t, y, initial=0.0, final=1.0, low=0.05, high=0.95) == pytest.approx(
        expected, rel=1e-6
    )
    assert settling_time(t, y, final=1.0, initial=0.0) == pytest.approx(
        TAU * math.log(50), rel=1e-6
    )


@pytest.mark.parametrize("grid", [uniform_grid, jittered_grid])
def test_underdamped_second_order_step(grid):
    t = grid(2.5, 1e-5)
    y = second_order(t)
    assert overshoot(y) == pytest.approx(OVERSHOOT_2ND, abs=1e-5)
    info = step_info(t, y)
    assert info["overshoot_pct"] == pytest.approx(OVERSHOOT_2ND, abs=1e-5)
    assert info["peak"] == pytest.approx(1 + OVERSHOOT_2ND / 100, abs=1e-7)
    assert info["peak_time_s"] == pytest.approx(PEAK_TIME_2ND, abs=1e-5)
    assert info["rise_time_s"] == pytest.approx(rise_time(t, y))
    assert info["settling_time_s"] == pytest.approx(settling_time(t, y))
    assert "dead_zone_time_s" not in info


def test_second_order_settling_time_matches_exact_last_crossing():
    from scipy.optimize import brentq

    t = uniform_grid(2.5, 1e-5)
    y = second_order(t)
    # |y - 1| = 0.02 for the last time: bracket it on a coarse grid, refine exactly.
    coarse = np.linspace(0.0, 2.5, 2501)
    outside = np.flatnonzero(np.abs(second_order(coarse) - 1) > 0.02)[-1]
    sign = np.sign(second_order(coarse[outside]) - 1)
    exact = brentq(
        lambda s: second_order(s) - 1 - 0.02 * sign, coarse[outside], coarse[outside + 1]
    )
    assert settling_time(t, y) == pytest.approx(exact, abs=1e-8)


def test_negative_step_gives_same_times():
    t = uniform_grid(2.5, 1e-5)
    y = second_order(t)
    y_neg = 3.0 - 2.0 * y  # step from 3 down to 1
    assert rise_time(t, y_neg) == pytest.approx(rise_time(t, y), rel=1e-9)
    assert settling_time(t, y_neg) == pytest.approx(settling_time(t, y), rel=1e-9)
    assert overshoot(y_neg) == pytest.approx(OVERSHOOT_2ND, abs=1e-5)
    info = step_info(t, y_neg)
    assert info["peak"] == pytest.approx(1 - 2 * OVERSHOOT_2ND / 100, abs=1e-6)
    assert info["peak_time_s"] == pytest.approx(PEAK_TIME_2ND, abs=1e-5)


def test_step_levels_outside_the_record():
    t = uniform_grid(1.0, 1e-4)
    y = np.full_like(t, 0.5)
    assert math.isnan(rise_time(t, y, initial=0.0, final=1.0))
    assert math.isnan(settling_time(t, y, final=1.0, initial=0.0))
    assert overshoot(y, initial=0.0, final=1.0) == 0.0
    assert overshoot(y, initial=0.0, final=0.25) == pytest.approx(100.0)


def test_settling_time_from_step_time_and_always_inside():
    t = uniform_grid(3.0, 1e-4)
    t_step = 0.5
    y = np.where(t < t_step, 0.0, first_order(t - t_step))
    assert settling_time(t, y, t0=t_step) == pytest.approx(TAU * math.log(50), rel=1e-6)
    assert settling_time(t, y, initial=0.0, final=1.0, band=2.0) == 0.0


def test_dead_zone_then_ramp():
    t = uniform_grid(0.2, 1e-3)
    y = np.where(t < 0.05, 0.0, 2.0 * (t - 0.05))
    assert dead_zone_time(t, y, threshold=0.01) == pytest.approx(0.055, abs=1e-12)
    assert dead_zone_time(t, -y, threshold=0.01) == pytest.approx(0.055, abs=1e-12)
    assert dead_zone_time(t, y, threshold=0.01, t0=0.0125) == pytest.approx(0.0425, abs=1e-12)
    assert math.isnan(dead_zone_time(t, y, threshold=1.0))
    info = step_info(t, y, dead_zone_threshold=0.01)
    assert info["dead_zone_time_s"] == pytest.approx(0.055, abs=1e-12)


def test_dead_zone_time_measured_from_interpolated_start():
    # Moving ramp: from any t0 the output leaves a band of 0.1 after 0.1 / slope.
    t = jittered_grid(1.0, 1e-3)
    y = 4.0 * t
    assert dead_zone_time(t, y, threshold=0.1, t0=0.3137) == pytest.approx(0.025, abs=1e-12)


# --------------------------------------------------------------------------- windowed metrics


def test_error_stats_constant_plus_sine():
    c, a = 0.3, 0.5
    t = uniform_grid(2.0, 1e-4)
    e = c + a * np.sin(2 * np.pi * 5.0 * t)
    stats = error_stats(t, e)
    assert stats.mean == pytest.approx(c, abs=1e-12)
    assert stats.std == pytest.approx(a / math.sqrt(2), rel=1e-9)
    assert stats.rms == pytest.approx(math.sqrt(c**2 + a**2 / 2), rel=1e-9)
    assert stats.max_abs == pytest.approx(c + a, rel=1e-12)


def test_error_stats_window_and_time_weighting():
    # Dense samples in [0, 0.5], sparse in (0.5, 2]; e = t. A plain sample mean would
    # give about 0.31 on the whole record; the time average of t over [0, 2] is 1.
    t = np.concatenate([np.linspace(0.0, 0.5, 501), np.linspace(0.6, 2.0, 15)])
    stats = error_stats(t, t)
    assert stats.mean == pytest.approx(1.0, rel=1e-12)
    assert stats.max_abs == 2.0
    window_stats = error_stats(t, t - 1.0, window=(0.6, 2.0))
    assert window_stats.mean == pytest.approx(0.3, rel=1e-12)
    assert window_stats.max_abs == pytest.approx(1.0)


def test_chattering_sine_on_ramp_symmetric_window():
    # The window is symmetric about a crest of the cosine, so the linear fit takes out
    # exactly the offset and the ramp and the amplitude is exact.
    c, a, f, tc = 0.3, 0.05, 37.0, 1.0
    t = uniform_grid(2.0, 1e-4)
    y = c + a * np.cos(2 * np.pi * f * (t - tc)) + 0.8 * t
    result = chattering(t, y, window=(tc - 0.5, tc + 0.5))
    assert result.amplitude == pytest.approx(a, rel=1e-6)
    assert result.frequency_Hz == pytest.approx(f, abs=0.05)
    assert fluctuation_amplitude(t, y, window=(tc - 0.5, tc + 0.5)) == result.amplitude


@pytest.mark.parametrize("f", [37.0, 37.3, 37.5, 113.7])
@pytest.mark.parametrize("grid", [uniform_grid, jittered_grid])
def test_chattering_sine_on_ramp_any_phase(f, grid):
    c, a, window = 0.3, 0.05, (0.5, 1.5)
    t = grid(2.0, 1e-4)
    y = c + a * np.sin(2 * np.pi * f * t + 0.7) + 0.8 * t
    result = chattering(t, y, window=window)
    # The least-squares line absorbs a little of the sine: at most ~6 a / (2 pi f T).
    assert result.amplitude == pytest.approx(a, abs=6 * a / (2 * np.pi * f * 1.0))
    assert result.frequency_Hz == pytest.approx(f, abs=0.05)


def test_chattering_constant_and_ramp():
    t = uniform_grid(1.0, 1e-3)
    assert chattering(t, np.full_like(t, 5.0)) == Chattering(0.0, 0.0)
    assert chattering(t, 3.0 + 1e3 * t) == Chattering(0.0, 0.0)
    assert chattering(t, 3.0 + 1e3 * t, detrend=False).amplitude == pytest.approx(500.0)
    assert fluctuation_amplitude(t, 3.0 + 1e3 * t) == 0.0
    assert fluctuation_amplitude(t, 3.0 + 1e3 * t, detrend=False) == pytest.approx(500.0)


def test_peak_value_is_signed():
    t = uniform_grid(1.0, 1e-3)
    v = np.sin(2 * np.pi * t) - 0.2  # trough (-1.2 at 0.75 s) deeper than crest (0.8 at 0.25 s)
    assert peak_value(t, v) == pytest.approx(-1.2, abs=1e-12)
    assert peak_value(t, v, window=(0.0, 0.5)) == pytest.approx(0.8, abs=1e-12)


def test_window_mask_inclusive():
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(window_mask(t, (0.1, 0.3)), [False, True, True, True, False])
    assert window_mask(t, None).all()


@pytest.mark.parametrize("phase_deg", [30.0, -45.0, 170.0, 200.0])
def test_sine_tracking(phase_deg):
    gain, f = 0.8, 2.0
    t = uniform_grid(3.0, 1e-4)
    w = 2 * np.pi * f
    reference = np.sin(w * t)
    y = gain * np.sin(w * t - np.radians(phase_deg))
    result = sine_tracking(t, y, reference, f, window=(0.3, 2.9))  # not whole periods
    wrapped = (phase_deg + 180) % 360 - 180
    assert result.gain == pytest.approx(gain, rel=1e-9)
    assert result.phase_lag_deg == pytest.approx(wrapped, abs=1e-7)
    assert result.lag_s == pytest.approx(wrapped / (360 * f), abs=1e-9)
    # |1 - G exp(-j phi)|: amplitude of the error phasor
    max_err = math.sqrt(1 + gain**2 - 2 * gain * math.cos(math.radians(phase_deg)))
    assert result.max_abs_error == pytest.approx(max_err, rel=1e-6)


def test_sine_tracking_half_turn_is_plus_180():
    t = uniform_grid(1.0, 1e-3)
    reference = np.sin(2 * np.pi * 3.0 * t)
    assert sine_tracking(t, -reference, reference, 3.0).phase_lag_deg == pytest.approx(180.0)


@pytest.mark.parametrize("reference", [1.5, "array"])
def test_load_recovery(reference):
    d, tau, t_load, band = 0.2, 0.05, 0.3, 0.01
    t = uniform_grid(1.0, 1e-5)
    ref = 1.5 + 0.1 * t if reference == "array" else reference
    y = ref - np.where(t < t_load, 0.0, d * np.exp(-(t - t_load) / tau))
    result = load_recovery(t, y, ref, t_load=t_load, band=band)
    assert result.dip == pytest.approx(-d, rel=1e-12)
    assert result.dip_time == pytest.approx(0.0, abs=1e-12)
    assert result.recovery_time == pytest.approx(tau * math.log(d / band), rel=1e-6)
    assert result.band == band


@pytest.mark.parametrize(("fraction", "band"), [(0.1, 0.02), (0.01, 0.01), (0.0, 0.01)])
def test_load_recovery_band_sized_to_the_dip(fraction, band):
    """band = max(floor, dip_fraction |dip|): 10 % of a 0.2 dip is 0.02, 1 % is below the floor."""
    d, tau, t_load = 0.2, 0.05, 0.3
    t = uniform_grid(1.0, 1e-5)
    y = -np.where(t < t_load, 0.0, d * np.exp(-(t - t_load) / tau))
    result = load_recovery(t, y, 0.0, t_load=t_load, band=0.01, dip_fraction=fraction)
    assert result.band == pytest.approx(band, rel=1e-12)
    assert result.recovery_time == pytest.approx(tau * math.log(d / band), rel=1e-6)


def test_load_recovery_never_leaves_the_band():
    t = uniform_grid(1.0, 1e-4)
    result = load_recovery(t, 0.001 * np.sin(20 * t), 0.0, t_load=0.2, band=0.01)
    assert result.recovery_time == 0.0


def test_load_recovery_not_recovered_and_positive_dip():
    t = uniform_grid(1.0, 1e-4)
    y = np.where(t < 0.2, 0.0, 0.3 * (t - 0.2) * np.exp(-(t - 0.2) / 0.1) / 0.1 / np.exp(-1))
    result = load_recovery(t, y, 0.0, t_load=0.2, band=0.05, t_end=0.4)
    assert result.dip == pytest.approx(0.3, rel=1e-6)  # peak of s e^(-s/tau) at s = tau
    assert result.dip_time == pytest.approx(0.1, abs=1e-4)
    assert math.isnan(result.recovery_time)


# --------------------------------------------------------------------------- validation

T = np.linspace(0.0, 1.0, 11)
Y = T.copy()


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: rise_time(T, Y[:-1]), "y must have the same shape"),
        (lambda: rise_time(T[::-1], Y), "t must be strictly increasing"),
        (lambda: rise_time(np.zeros(11), Y), "t must be strictly increasing"),
        (lambda: rise_time([0.0], [0.0]), "t must be a 1-D array with at least 2"),
        (lambda: rise_time(T, np.where(T > 0.5, np.nan, Y)), "y must contain only finite"),
        (lambda: rise_time(T, Y, low=0.9, high=0.1), "low and high must satisfy"),
        (lambda: rise_time(T, np.ones(11)), "final must differ from initial"),
        (lambda: settling_time(T, Y, band=0.0), "band must be a finite number > 0"),
        (lambda: settling_time(T, Y, t0=2.0), r"t0 must lie in \[t\[0\], t\[-1\]\)"),
        (lambda: settling_time(T, Y, final=np.inf), "final must be a finite number"),
        (lambda: overshoot([1.0]), "y must be a 1-D array with at least 2"),
        (lambda: dead_zone_time(T, Y, threshold=-1.0), "threshold must be a finite number > 0"),
        (lambda: error_stats(T, Y[:5]), "error must have the same shape"),
        (lambda: error_stats(T, Y, window=(0.31, 0.39)), "window .* selects 0 sample"),
        (lambda: error_stats(T, Y, window=(0.5, 0.4)), "window must be finite with t_start"),
        (lambda: error_stats(T, Y, window=0.5), "window must be None or"),
        (lambda: chattering(T, Y, window=(2.0, 3.0)), "window"),
        (lambda: sine_tracking(T, Y, Y, 0.0), "frequency_Hz must be a finite number > 0"),
        (lambda: sine_tracking(T, Y, Y[:3], 1.0), "reference must have the same shape"),
        (lambda: sine_tracking(T, Y, 0 * Y, 1.0), "reference must have a nonzero component"),
        (lambda: load_recovery(T, Y, 0.0, t_load=-1.0, band=0.1), "t_load must lie in"),
        (lambda: load_recovery(T, Y, 0.0, t_load=0.5, band=0.1, t_end=0.4), "t_end must be >"),
        (lambda: load_recovery(T, Y, "x", t_load=0.5, band=0.1), "reference must be a finite"),
        (lambda: load_recovery(T, Y, Y, t_load=0.5, band=np.nan), "band must be a finite"),
        (
            lambda: load_recovery(T, Y, Y, t_load=0.5, band=0.1, dip_fraction=-0.1),
            "dip_fraction must be a finite number >= 0",
        ),
        (lambda: step_info(T, Y, dead_zone_threshold=0.0), "threshold must be"),
    ],
)
def test_bad_inputs_raise_value_error_naming_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# --------------------------------------------------------------------------- properties

T_PROP = uniform_grid(1.5, 1e-3)
Y_PROP = second_order(T_PROP)


@settings(max_examples=40, deadline=None)
@given(
    scale=st.floats(0.01, 100.0) | st.floats(-100.0, -0.01),
    offset=st.floats(-1e3, 1e3),
)
def test_step_metrics_invariant_to_scale_and_offset(scale, offset):
    y = scale * Y_PROP + offset
    assert rise_time(T_PROP, y) == pytest.approx(rise_time(T_PROP, Y_PROP), rel=1e-6)
    assert settling_time(T_PROP, y) == pytest.approx(settling_time(T_PROP, Y_PROP), rel=1e-6)
    assert overshoot(y) == pytest.approx(overshoot(Y_PROP), rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    gain=st.floats(0.05, 20.0),
    phase_deg=st.floats(-179.0, 179.0),
    offset=st.floats(-5.0, 5.0),
    f=st.floats(0.5, 20.0),
)
def test_sine_tracking_recovers_gain_and_phase(gain, phase_deg, offset, f):
    t = uniform_grid(2.0, 1e-3)
    w = 2 * np.pi * f
    y = gain * np.sin(w * t - np.radians(phase_deg)) + offset
    result = sine_tracking(t, y, np.cos(w * t) + 1.0, f)  # reference leads sin by 90 deg
    expected = (phase_deg + 90.0 + 180.0) % 360.0 - 180.0
    assert result.gain == pytest.approx(gain, rel=1e-6)
    assert math.remainder(result.phase_lag_deg - expected, 360.0) == pytest.approx(0.0, abs=1e-6)
    assert -180.0 < result.phase_lag_deg <= 180.0


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=50))
def test_error_stats_rms_decomposes(values):
    e = np.array(values)
    t = np.arange(e.size, dtype=float)
    stats = error_stats(t, e)
    assert stats.rms**2 == pytest.approx(stats.mean**2 + stats.std**2, rel=1e-9, abs=1e-9)
    assert stats.max_abs == np.max(np.abs(e))
    assert abs(stats.mean) <= stats.max_abs * (1 + 1e-12)


def test_sine_fluctuation_is_the_ripple_left_after_the_fitted_sine():
    t = np.linspace(0.0, 20.0, 20001)
    ripple = 0.3 * np.sin(2 * np.pi * 7.0 * t)
    y = 5.0 + 19.0 * np.sin(2 * np.pi * 0.05 * t + 0.4) + ripple
    assert m.sine_fluctuation(t, y, 0.05) == pytest.approx(0.3, rel=2e-3)
    assert m.sine_fluctuation(t, y - ripple, 0.05) < 1e-9
    with pytest.raises(ValueError, match="frequency_Hz"):
        m.sine_fluctuation(t, y, 0.0)


def test_integral_absolute_error_and_total_variation():
    t = np.linspace(0.0, 2.0, 2001)
    assert m.integral_absolute_error(t, np.sin(np.pi * t)) == pytest.approx(4 / np.pi, rel=1e-6)
    assert m.integral_absolute_error(t, np.ones_like(t), (0.5, 1.5)) == pytest.approx(1.0)
    # sign flips every 0.1 s: 20 jumps of 2 in 2 s (the last sample, t = 2, starts a new one)
    square = np.where(np.floor(np.round(t * 10, 9)) % 2 == 0, 1.0, -1.0)
    assert m.total_variation_rate(t, square) == pytest.approx(20 * 2 / 2.0)
    assert m.total_variation_rate(t, 3 * t) == pytest.approx(3.0)


def test_control_step_info_agrees_with_python_controls_step_info():
    """On a step from 0 (python-control's assumption), every key agrees with
    ``control.step_info`` to the interpolation between samples: within one sample in time,
    within the response's change over one sample in level."""
    import control

    t = np.linspace(0.0, 5.0, 5001)
    dt = t[1] - t[0]
    y = np.asarray(control.step_response(control.tf([25.0], [1.0, 4.0, 25.0]), t).outputs)
    theirs = control.step_info(y, timepts=t, final_output=1.0, SettlingTimeThreshold=0.05,
                               RiseTimeLimits=(0.05, 0.95))  # fmt: skip
    ours = m.control_step_info(t, y, 0.0, 1.0, SettlingTimeThreshold=0.05,
                               RiseTimeLimits=(0.05, 0.95))  # fmt: skip
    assert set(ours) == set(theirs)
    slope = float(np.max(np.abs(np.diff(y))))
    for key in ("RiseTime", "SettlingTime", "PeakTime"):
        assert ours[key] == pytest.approx(theirs[key], abs=1.01 * dt), key
    for key in ("SettlingMin", "SettlingMax", "Peak", "SteadyStateValue"):
        assert ours[key] == pytest.approx(theirs[key], abs=slope), key
    assert ours["Overshoot"] == pytest.approx(theirs["Overshoot"], abs=100 * slope)
    assert ours["Undershoot"] == theirs["Undershoot"] == 0.0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.sampled_from([-3.0, -2.0, -0.0, 0.0, 1.0, 2.0, 3.0]), min_size=1, max_size=12),
    st.sampled_from([0.5, 1.0, 2.0, 2.5]),
)
def test_the_copy_free_magnitude_helpers_agree_with_abs(values, tol):
    """_largest and _outside (which spare a long trace a copy of |v|) pick the same rows as
    argmax |v| and |v| > tol, ties between +a and -a included."""
    v = np.array(values)
    assert m._largest(v) == int(np.argmax(np.abs(v)))
    assert np.array_equal(m._outside(v, tol), np.flatnonzero(np.abs(v) > tol))


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.floats(0.0, 10.0), min_size=2, max_size=2),
    st.integers(2, 40),
)
def test_a_window_selects_the_rows_its_mask_selects(edges, n):
    """window_rows (a view of a window) holds exactly the rows t_start <= t <= t_end."""
    t = np.linspace(0.0, 10.0, n)
    window = (min(edges), max(edges))
    expected = np.flatnonzero((t >= window[0]) & (t <= window[1]))
    if expected.size < 2:
        with pytest.raises(ValueError, match="at least 2 are needed"):
            m.window_mask(t, window)
        return
    rows = m.window_rows(t, window)
    assert np.array_equal(np.arange(t.size)[rows], expected)
    assert np.array_equal(np.flatnonzero(m.window_mask(t, window)), expected)
