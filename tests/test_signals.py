"""Signals: each term against its closed form, derivatives against finite differences."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from emasim.signals import (
    ZERO,
    Chirp,
    Constant,
    Ramp,
    Sine,
    Step,
    Table,
    encode,
    lookup_table,
    signal_derivatives,
    signal_value,
    signal_values,
)


def values(sig, times):
    return np.array([signal_value(sig, t) for t in times])


def test_each_term_matches_its_closed_form():
    t = np.linspace(0.0, 3.0, 301)
    assert np.all(values(encode([Constant(value=2.5)]), t) == 2.5)
    step = values(encode([Step(time_s=1.0, initial=-1.0, final=4.0)], 2.0), t)
    assert np.all(step == np.where(t >= 1.0, 8.0, -2.0))
    sine = Sine(amplitude=3.0, frequency_Hz=0.5, phase_deg=30.0, offset=1.0, start_s=0.5)
    expected = np.where(
        t < 0.5,
        1.0 + 3.0 * math.sin(math.radians(30)),
        1.0 + 3.0 * np.sin(math.pi * (t - 0.5) + math.radians(30)),
    )
    assert np.allclose(values(encode([sine]), t), expected, atol=1e-12)
    ramp = values(encode([Ramp(slope_per_s=2.0, start_s=1.0, end_s=2.0)]), t)
    assert np.allclose(ramp, 2.0 * np.clip(t - 1.0, 0.0, 1.0), atol=1e-12)
    table = Table(time_s=[0.5, 1.0, 2.5], values=[1.0, -1.0, 3.0])
    assert np.allclose(values(encode([table]), t), np.interp(t, table.time_s, table.values))
    assert np.all(values(ZERO, t) == 0.0)


def test_terms_add_up_and_a_lookup_table_maps_any_abscissa():
    a = encode([Step(time_s=0.2, final=1.0), Sine(amplitude=0.5, frequency_Hz=2.0)])
    b = encode([Step(time_s=0.2, final=1.0)])
    c = encode([Sine(amplitude=0.5, frequency_Hz=2.0)])
    t = np.linspace(0, 1, 51)
    assert np.allclose(values(a, t), values(b, t) + values(c, t))
    x = np.array([-0.6, -0.1, 0.4])
    y = np.array([-150.0, -20.0, 110.0])
    grid = np.linspace(-1.0, 1.0, 41)
    assert np.allclose(values(lookup_table(x, y), grid), np.interp(grid, x, y))
    with pytest.raises(ValueError, match="strictly increasing"):
        lookup_table(x[::-1], y)


@settings(max_examples=40, deadline=None)
@given(
    amplitude=st.floats(0.1, 10.0),
    frequency=st.floats(0.05, 5.0),
    phase=st.floats(-180.0, 180.0),
    t=st.floats(0.01, 3.0),
)
def test_sine_derivatives_match_finite_differences(amplitude, frequency, phase, t):
    sig = encode([Sine(amplitude=amplitude, frequency_Hz=frequency, phase_deg=phase)])
    y, dy, ddy = signal_derivatives(sig, t)
    h = 1e-5
    y_minus, y_plus = signal_value(sig, t - h), signal_value(sig, t + h)
    scale = amplitude * (2 * math.pi * frequency) ** 2
    assert dy == pytest.approx((y_plus - y_minus) / (2 * h), abs=1e-6 * scale)
    assert ddy == pytest.approx((y_plus - 2 * y + y_minus) / h**2, abs=1e-3 * scale)


def test_ramp_and_table_rates():
    assert signal_derivatives(encode([Ramp(slope_per_s=2.0)]), 0.5)[1] == 2.0
    table = encode([Table(time_s=[0.0, 1.0], values=[0.0, 3.0])], 2.0)
    assert signal_derivatives(table, 0.5)[:2] == pytest.approx((3.0, 6.0))


@pytest.mark.parametrize(
    "make",
    [
        lambda: Table(time_s=[0.0, 1.0], values=[1.0]),
        lambda: Table(time_s=[1.0, 0.5], values=[1.0, 2.0]),
        lambda: Ramp(slope_per_s=1.0, start_s=2.0, end_s=1.0),
        lambda: Sine(amplitude=1.0, frequency_Hz=0.0),
        lambda: Step(final=math.nan),
        lambda: Step(final=1.0, time_s=-1.0),
        lambda: Chirp(amplitude=1.0, start_Hz=2.0, end_Hz=1.0, duration_s=5.0),
        lambda: Chirp(amplitude=1.0, start_Hz=1.0, end_Hz=2.0, duration_s=0.5),  # < 1 cycle
    ],
)
def test_bad_terms_are_rejected(make):
    with pytest.raises(ValidationError):
        make()


def test_the_numpy_evaluator_agrees_with_the_compiled_one():
    """signal_values (numpy, for checks and plots) and signal_value (compiled, in the loop)
    evaluate the same encoding: every kind of term, summed, before, inside and after its
    active span and on its breakpoints, agree to 1e-12 of the signal's scale."""
    sig = encode(
        [
            Constant(value=0.5),
            Step(time_s=1.0, initial=-1.0, final=4.0),
            Sine(amplitude=3.0, frequency_Hz=0.7, phase_deg=20.0, offset=0.2, start_s=0.5),
            Ramp(slope_per_s=2.0, start_s=0.3, end_s=2.1),
            Table(time_s=[0.2, 0.9, 1.7, 2.5], values=[0.0, 3.0, -1.0, 2.0]),
            Chirp(amplitude=2.0, start_Hz=0.5, end_Hz=4.0, start_s=0.4, duration_s=2.0),
        ],
        1.5,
    )
    t = np.concatenate([np.linspace(-0.5, 3.5, 801), [0.2, 0.3, 0.5, 0.9, 1.0, 1.7, 2.1, 2.5]])
    compiled = values(sig, t)
    assert np.max(np.abs(signal_values(sig, t) - compiled)) <= 1e-12 * np.max(np.abs(compiled))
    assert np.all(signal_values(ZERO, t) == 0.0)


def test_a_chirp_sweeps_its_band_in_whole_cycles():
    """The log sweep against its definition: its phase is the integral of its frequency
    start_Hz exp((t - start_s) / L), which reaches end_Hz at the sweep's end; it lasts the
    longest whole number of cycles within duration_s, so it starts and ends at 0, and it is 0
    outside the sweep. Derivatives against finite differences of the compiled value."""
    chirp = Chirp(amplitude=2.0, start_Hz=0.5, end_Hz=20.0, start_s=1.0, duration_s=10.0)
    sweep = chirp.sweep_s
    cycles = 10.0 * 19.5 / math.log(40.0)
    assert chirp.cycles == math.floor(cycles) and 10.0 - sweep < 10.0 / cycles
    sig = encode([chirp], 3.0)
    t = np.linspace(1.0, 1.0 + sweep, 20001)
    frequency = 0.5 * np.exp((t - 1.0) * math.log(40.0) / sweep)
    phase = np.concatenate(([0.0], np.cumsum(np.diff(t) * 0.5 * (frequency[1:] + frequency[:-1]))))
    expected = 6.0 * np.sin(2 * math.pi * phase)
    assert np.max(np.abs(values(sig, t) - expected)) < 1e-5 * 6.0
    assert frequency[-1] == pytest.approx(20.0)
    assert phase[-1] == pytest.approx(chirp.cycles, abs=1e-6)
    assert values(sig, [0.5, 1.0 + sweep, 1.0 + sweep + 1e-3]) == pytest.approx(0.0, abs=1e-9)
    h = 1e-6
    for time in (1.3, 4.0, 1.0 + 0.9 * sweep):
        y, dy, ddy = signal_derivatives(sig, time)
        minus, plus = signal_value(sig, time - h), signal_value(sig, time + h)
        scale = 6.0 * (2 * math.pi * 20.0) ** 2
        assert dy == pytest.approx((plus - minus) / (2 * h), abs=1e-6 * scale)
        assert ddy == pytest.approx((plus - 2 * y + minus) / h**2, abs=1e-3 * scale)
