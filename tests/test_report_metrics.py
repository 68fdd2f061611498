"""Tests of emasim.analysis.report: every report metric on synthetic traces whose answers are
known in closed form (first-order steps, exponential recoveries, sines of known gain and phase).

The traces are written by hand into a minimal stand-in for a run result: ``t``, the columns
by name and the experiment it made (emasim.sim.result.Experiment), which is all the report
functions read. Every test runs twice: on the trace as one block, and cut into blocks of 997
rows as a long run's row groups are read (emasim.sim.result.seamed_blocks), where the metrics
computed in one pass over the blocks must give the same closed-form answers.
"""

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from emasim.analysis import report as r
from emasim.interface import LIMIT_CURRENT, LIMIT_SPEED, LIMIT_VOLTAGE
from emasim.scenarios.loader import load_scenario
from emasim.sim.result import Experiment, seamed_blocks

RPM = math.pi / 30.0  # rad/s per rpm
DEG = math.pi / 180.0  # rad per deg
ARM_MM = 238.7  # lumped rudder arm of the bench scenarios
MAX_CURRENT_A = 58.0


class FakeResult:
    """What the report reads of a run: the time, the trace columns by name, the experiment;
    the columns a block of ``block_rows`` rows at a time (None: one block)."""

    block_rows = None

    def __init__(self, t, experiment, **columns):
        self.t = np.asarray(t, dtype=float)
        self.description = SimpleNamespace(experiment=experiment)
        self._columns = {name: np.asarray(v, dtype=float) for name, v in columns.items()}

    @property
    def columns(self):
        return list(self._columns)

    @property
    def outer_loop(self):
        return "speed" if self.description.experiment.quantity == "speed" else "position"

    def __getitem__(self, name):
        return self._columns[name]

    @property
    def span(self):
        return float(self.t[0]), float(self.t[-1])

    def blocks(self, *names):
        columns = [self.t if name == "t_s" else self._columns[name] for name in names]
        cuts = range(self.block_rows or self.t.size, self.t.size, self.block_rows or self.t.size)
        return seamed_blocks(zip(*(np.split(c, list(cuts)) for c in columns), strict=True))


@pytest.fixture(autouse=True, params=[None, 997], ids=["one-block", "blocks-997"])
def block_rows(request, monkeypatch):
    monkeypatch.setattr(FakeResult, "block_rows", request.param)


def grid(t_end, dt):
    return np.linspace(0.0, t_end, round(t_end / dt) + 1)


QUANTITY = {"speed_rpm": "speed", "position_mm": "position", "rudder_deg": "rudder"}


def experiment(key, term, t_load=None, arm_mm=None):
    """The experiment of a reference of one term (a step or a sine) of ``key``, a load step at
    ``t_load`` (None: none), the lumped stage's arm (None: the linkage); no stroke check."""
    return Experiment(
        quantity=QUANTITY[key],
        shape=term["type"],
        reference=(term,),
        sine_frequency_Hz=term.get("frequency_Hz"),
        load_step_s=t_load,
        max_speed_rpm=1800.0,
        max_current_A=MAX_CURRENT_A,
        stroke_mm=None,
        rudder_arm_m=None if arm_mm is None else 1e-3 * arm_mm,
    )


def step_scenario(key, final, t_load=None):
    return experiment(key, {"type": "step", "time_s": 0.0, "final": final}, t_load)


def load_error(t, t_load, dip, tau, offset=0.0):
    """Output minus set point after a load step: -dip at t_load, back to -offset with time
    constant tau: e = -(offset + (dip - offset) exp(-(t - t_load) / tau)); 0 before."""
    s = t - t_load
    return np.where(s >= 0.0, -(offset + (dip - offset) * np.exp(-np.maximum(s, 0.0) / tau)), 0.0)


def recovery(dip, band, tau, offset=0.0):
    """Closed form: |e| = offset + (dip - offset) exp(-s / tau) falls to band at s."""
    return tau * math.log((dip - offset) / (band - offset))


# --------------------------------------------------------------------------- speed step

TAU = 0.01  # s, first-order speed response
T_LOAD = 0.4
SPEED_RUN = 2.0
DT = 1e-4


def speed_step_result(dip, tau_r, offset=0.0, pre_offset=0.0, iq_ref=None):
    t = grid(SPEED_RUN, DT)
    y = (1000.0 - pre_offset) * (1.0 - np.exp(-t / TAU))
    y = np.where(t < T_LOAD, y, 1000.0) + load_error(t, T_LOAD, dip, tau_r, offset)
    if iq_ref is None:
        iq_ref = np.full_like(t, 3.0)
    return FakeResult(
        t,
        step_scenario("speed_rpm", 1000.0, T_LOAD),
        motor_speed_rad_s=RPM * y,
        measured_speed_rad_s=RPM * y,  # an ideal speed sensor
        speed_ref_rad_s=np.full_like(t, RPM * 1000.0),
        iq_ref_A=iq_ref,
    )


def test_speed_step_first_order_before_the_load():
    out = r.step_metrics(speed_step_result(dip=50.0, tau_r=0.02, pre_offset=0.2), "speed")
    final = 1000.0 - 0.2  # the response's own level; the step is measured to the set point
    rise = TAU * (math.log(1 - 100.0 / final) - math.log(1 - 900.0 / final))
    assert out["rise_time_s"] == pytest.approx(rise, rel=1e-4)
    assert rise == pytest.approx(TAU * math.log(9), rel=1e-3)  # 2.197 tau
    # 2 % of the 1000 rpm set point: 1000 - y = 0.2 + 999.8 exp(-t / tau) = 20
    assert out["settling_time_s"] == pytest.approx(TAU * math.log(999.8 / 19.8), rel=1e-4)
    assert out["overshoot_pct"] == 0.0
    assert out["peak_rpm"] == pytest.approx(final, rel=1e-12)
    assert "dead_zone_time_s" not in out  # position only
    # last STEADY_FRACTION of [0, t_load]: the 0.2 rpm offset, constant
    assert out["steady_error_mean_rpm"] == pytest.approx(0.2, rel=1e-9)
    assert out["steady_error_std_rpm"] == pytest.approx(0.0, abs=1e-9)
    assert out["steady_error_rms_rpm"] == pytest.approx(0.2, rel=1e-9)


def test_speed_step_recovery_into_a_tenth_of_the_dip():
    out = r.step_metrics(speed_step_result(dip=50.0, tau_r=0.02), "speed")
    band = r.RECOVERY_FRACTION * 50.0
    assert band == pytest.approx(5.0)  # 10 % of the dip, wider than the 1 rpm floor
    assert out["load_dip_rpm"] == pytest.approx(-50.0, rel=1e-12)
    assert out["load_recovery_band_rpm"] == pytest.approx(band, rel=1e-12)
    assert out["load_recovery_time_s"] == pytest.approx(0.02 * math.log(10.0), rel=1e-4)
    assert out["load_steady_error_mean_rpm"] == pytest.approx(0.0, abs=1e-9)
    assert out["load_steady_error_rms_rpm"] == pytest.approx(0.0, abs=1e-9)


def test_speed_step_offset_under_load_is_not_recovered():
    """The review's case: a proportional-like law that stays 4.8 rpm off after a 12 rpm dip."""
    out = r.step_metrics(speed_step_result(dip=12.0, tau_r=0.002, offset=4.8), "speed")
    assert out["load_recovery_band_rpm"] == pytest.approx(1.2, rel=1e-12)
    assert math.isnan(out["load_recovery_time_s"])
    # set point minus output over the last STEADY_FRACTION of [t_load, end]
    assert out["load_steady_error_mean_rpm"] == pytest.approx(4.8, rel=1e-9)
    assert out["load_steady_error_rms_rpm"] == pytest.approx(4.8, rel=1e-9)
    assert "load_recovery_time_s" in r.undefined_metrics(out)


def test_speed_step_small_offset_recovers_at_the_band():
    out = r.step_metrics(speed_step_result(dip=50.0, tau_r=0.02, offset=0.5), "speed")
    assert out["load_recovery_time_s"] == pytest.approx(recovery(50.0, 5.0, 0.02, 0.5), rel=1e-4)
    assert out["load_steady_error_mean_rpm"] == pytest.approx(0.5, rel=1e-9)


def test_speed_step_recovery_floor():
    # a 5 rpm dip: 10 % of it is 0.5 rpm, below the 1 rpm floor
    out = r.step_metrics(speed_step_result(dip=5.0, tau_r=0.02), "speed")
    assert r.RECOVERY_FLOOR_RPM == 1.0
    assert out["load_recovery_band_rpm"] == pytest.approx(1.0, rel=1e-12)
    assert out["load_recovery_time_s"] == pytest.approx(0.02 * math.log(5.0), rel=1e-4)
    # a dip inside the floor never leaves the band: recovered at once
    out = r.step_metrics(speed_step_result(dip=0.8, tau_r=0.02), "speed")
    assert out["load_recovery_time_s"] == 0.0


def test_speed_step_without_a_load_step_in_the_run():
    result = speed_step_result(dip=50.0, tau_r=0.02)
    after_the_end = dataclasses.replace(result.description.experiment, load_step_s=5.0)
    result.description.experiment = after_the_end
    out = r.step_metrics(result, "speed")
    assert not any(key.startswith("load_") for key in out)


def test_current_chattering_over_the_last_fifth_of_the_run():
    t = grid(SPEED_RUN, DT)
    tail_mid = SPEED_RUN * (1 - r.STEADY_FRACTION / 2)  # 1.8 s: the tail is [1.6, 2.0]
    # a 50 Hz cosine with its crest at the middle of the tail (no detrending bias), and a
    # large step before the tail that a wrong window would see
    iq_ref = np.where(t < 1.5, 20.0, 3.0 + 0.5 * np.cos(2 * np.pi * 50.0 * (t - tail_mid)))
    out = r.step_metrics(speed_step_result(dip=50.0, tau_r=0.02, iq_ref=iq_ref), "speed")
    assert out["iq_chattering_A"] == pytest.approx(0.5, rel=1e-6)
    assert out["iq_chattering_frequency_Hz"] == pytest.approx(50.0, abs=0.5)


def test_current_chattering_frequency_zero_below_a_micro_ampere():
    t = grid(SPEED_RUN, DT)
    iq_ref = 3.0 + 0.4e-6 * np.cos(2 * np.pi * 50.0 * (t - 1.8))
    out = r.step_metrics(speed_step_result(dip=50.0, tau_r=0.02, iq_ref=iq_ref), "speed")
    assert out["iq_chattering_A"] == pytest.approx(0.4e-6, rel=1e-5)
    assert out["iq_chattering_frequency_Hz"] == 0.0


# --------------------------------------------------------------------------- position step

POS_TAU = 0.03  # s
DELAY = 0.005  # s before the rod moves
POS_LOAD = 1.0
POS_RUN = 2.0
HUNT_HZ = 3.25  # Hz, a limit cycle after the load step


def position_step_result(dip, tau_r, offset=0.0, hunting=0.0, pre_offset=0.0):
    """Rod position in m: still until DELAY, then a first-order step to 120 mm - pre_offset;
    after the load a dip recovering with tau_r, plus a hunting sine of amplitude ``hunting``."""
    t = grid(POS_RUN, DT)
    moving = np.maximum(t - DELAY, 0.0)
    y = (120.0 - pre_offset) * (1.0 - np.exp(-moving / POS_TAU))
    after = t >= POS_LOAD
    y = np.where(after, 120.0, y) + load_error(t, POS_LOAD, dip, tau_r, offset)
    # 3.25 Hz: the run ends on a crest of the hunting
    y = y + np.where(after, hunting * np.sin(2 * np.pi * HUNT_HZ * (t - POS_LOAD)), 0.0)
    return FakeResult(
        t,
        step_scenario("position_mm", 120.0, POS_LOAD),
        actuator_position_m=1e-3 * y,
        position_ref_m=np.full_like(t, 0.12),
        iq_ref_A=np.full_like(t, 1.0),
    )


def test_position_step_dead_zone_rise_settling_and_steady_error():
    out = r.step_metrics(position_step_result(1.0, 0.05, pre_offset=0.003), "position")
    level = 120.0 - 0.003
    # moved DEAD_ZONE_MM = 10 um: level (1 - exp(-x / tau)) = 0.01
    assert r.DEAD_ZONE_MM == 0.01
    dead = DELAY - POS_TAU * math.log(1 - 0.01 / level)
    assert out["dead_zone_time_s"] == pytest.approx(dead, rel=1e-4)
    rise = POS_TAU * (math.log(1 - 12.0 / level) - math.log(1 - 108.0 / level))
    assert out["rise_time_s"] == pytest.approx(rise, rel=1e-4)
    # inside 2 % of 120 mm: 0.003 + level exp(-x / tau) = 2.4
    settle = DELAY + POS_TAU * math.log(level / (2.4 - 0.003))
    assert out["settling_time_s"] == pytest.approx(settle, rel=1e-4)
    assert out["overshoot_pct"] == 0.0
    assert out["steady_error_mean_mm"] == pytest.approx(0.003, rel=1e-6)
    assert out["steady_error_rms_mm"] == pytest.approx(0.003, rel=1e-6)


def test_position_step_recovery_not_within_two_percent_of_the_step():
    """The review's case: a 1 mm dip 'recovered in 0 s' against 2 % of 120 mm = 2.4 mm."""
    out = r.step_metrics(position_step_result(dip=1.0, tau_r=0.05), "position")
    assert out["load_dip_mm"] == pytest.approx(-1.0, rel=1e-9)
    assert out["load_recovery_band_mm"] == pytest.approx(0.1, rel=1e-9)
    assert out["load_recovery_time_s"] == pytest.approx(0.05 * math.log(10.0), rel=1e-4)


def test_position_step_hunting_wider_than_the_band_is_not_recovered():
    out = r.step_metrics(position_step_result(dip=0.5, tau_r=0.05, hunting=0.08), "position")
    assert out["load_recovery_band_mm"] == pytest.approx(0.05, rel=1e-9)
    assert math.isnan(out["load_recovery_time_s"])
    # the last fifth of [1, 2] s is [1.8, 2.0]: 0.65 periods of the hunting, so the mean is
    # that of -0.08 sin(w (t - 1)) over it, the RMS that of its square
    w = 2 * np.pi * HUNT_HZ
    a, b = 0.8, 1.0  # the window, from the load step
    mean = -0.08 * (math.cos(w * a) - math.cos(w * b)) / (w * (b - a))
    mean_sq = 0.08**2 * (0.5 - (math.sin(2 * w * b) - math.sin(2 * w * a)) / (4 * w * (b - a)))
    assert out["load_steady_error_mean_mm"] == pytest.approx(mean, rel=1e-4)
    assert out["load_steady_error_rms_mm"] == pytest.approx(math.sqrt(mean_sq), rel=1e-4)


def test_position_step_recovery_floor():
    assert r.RECOVERY_FLOOR_MM == 0.01
    out = r.step_metrics(position_step_result(dip=0.05, tau_r=0.05), "position")
    assert out["load_recovery_band_mm"] == pytest.approx(0.01, rel=1e-9)
    assert out["load_recovery_time_s"] == pytest.approx(0.05 * math.log(5.0), rel=1e-4)
    out = r.step_metrics(position_step_result(dip=0.005, tau_r=0.05), "position")
    assert out["load_recovery_time_s"] == 0.0


# --------------------------------------------------------------------------- speed sine

SINE_F = 0.5  # Hz: the reference reverses at 1 s, 2 s, ...
SINE_RUN = 3.0


def sine_scenario(t_load=None):
    sine = {"type": "sine", "amplitude": 1000.0, "frequency_Hz": SINE_F}
    return experiment("speed_rpm", sine, t_load)


def test_speed_sine_gain_phase_and_max_error():
    t = grid(SINE_RUN + 1.0, DT)  # two whole periods
    w = 2 * np.pi * SINE_F
    gain, lag = 0.98, math.radians(2.0)
    ref = 1000.0 * np.sin(w * t)
    y = gain * 1000.0 * np.sin(w * t - lag)
    result = FakeResult(t, sine_scenario(), motor_speed_rad_s=RPM * y, speed_ref_rad_s=RPM * ref)
    out = r.sine_metrics(result)
    assert out["gain"] == pytest.approx(gain, rel=1e-9)
    assert out["phase_lag_deg"] == pytest.approx(2.0, rel=1e-9)
    expected = 1000.0 * math.sqrt(1 + gain**2 - 2 * gain * math.cos(lag))
    assert out["max_error_rpm"] == pytest.approx(expected, rel=1e-6)
    assert not any(key.startswith("load_") for key in out)


def test_a_position_sine_gets_the_position_sine_metrics_in_mm():
    """A position loop with a sine reference used to reach the speed sine's metrics and stop
    with a KeyError; it gets the same figures on the rod position, in mm."""
    t = grid(SINE_RUN + 1.0, DT)
    w = 2 * np.pi * SINE_F
    gain, lag = 0.95, math.radians(5.0)
    ref = 5.0 * np.sin(w * t)
    y = gain * 5.0 * np.sin(w * t - lag)
    sine = experiment("position_mm", {"type": "sine", "amplitude": 5.0, "frequency_Hz": SINE_F})
    result = FakeResult(t, sine, actuator_position_m=1e-3 * y, position_ref_m=1e-3 * ref)
    out = r.sine_metrics(result, "position")
    assert out["gain"] == pytest.approx(gain, rel=1e-9)
    assert out["phase_lag_deg"] == pytest.approx(5.0, rel=1e-9)
    expected = 5.0 * math.sqrt(1 + gain**2 - 2 * gain * math.cos(lag))
    assert out["max_error_mm"] == pytest.approx(expected, rel=1e-6)


def speed_sine_result(dip, tau_r, offset=0.0, spike=8.0):
    """A load dip at 0.4 s, and after the reversal at 1 s a friction spike of ``spike`` rpm."""
    t = grid(SINE_RUN, DT)
    ref = 1000.0 * np.sin(2 * np.pi * SINE_F * t)
    e = load_error(t, T_LOAD, dip, tau_r, offset)
    e = e - np.where((t > 1.0 + 1e-9) & (t < 1.02), spike, 0.0)
    return FakeResult(
        t, sine_scenario(T_LOAD), motor_speed_rad_s=RPM * (ref + e), speed_ref_rad_s=RPM * ref
    )


def test_next_reversal():
    t = grid(3.0, DT)
    ref = np.sin(np.pi * t)  # sign changes at 1 s and 2 s
    assert r.next_reversal(t, ref, 0.4) == pytest.approx(1.0, abs=DT)
    assert r.next_reversal(t, ref, 1.5) == pytest.approx(2.0, abs=DT)
    assert r.next_reversal(t, ref, 1.5) < 2.0 + 1e-12  # the last sample before the flip
    assert r.next_reversal(t, 2.0 + ref, 0.4) == t[-1]  # never changes sign
    assert r.next_reversal(t, 0.0 * ref, 0.4) == t[-1]


def test_speed_sine_recovery_up_to_the_reversal():
    out = r.sine_metrics(speed_sine_result(dip=30.0, tau_r=0.01, offset=0.5))
    assert out["load_dip_rpm"] == pytest.approx(-30.0, rel=1e-9)
    assert out["load_recovery_band_rpm"] == pytest.approx(3.0, rel=1e-9)
    # the 8 rpm spike after the reversal at 1 s is outside the load's interval
    assert out["load_recovery_time_s"] == pytest.approx(recovery(30.0, 3.0, 0.01, 0.5), rel=1e-4)
    # steady window: the last STEADY_FRACTION of [0.4, 1.0]
    assert out["load_steady_error_mean_rpm"] == pytest.approx(0.5, rel=1e-6)
    assert out["load_steady_error_rms_rpm"] == pytest.approx(0.5, rel=1e-6)
    assert out["max_error_rpm"] == pytest.approx(30.0, rel=1e-9)  # the whole run


def test_speed_sine_offset_under_load_is_not_recovered():
    out = r.sine_metrics(speed_sine_result(dip=11.0, tau_r=0.002, offset=2.7))
    assert out["load_recovery_band_rpm"] == pytest.approx(1.1, rel=1e-9)
    assert math.isnan(out["load_recovery_time_s"])
    assert out["load_steady_error_mean_rpm"] == pytest.approx(2.7, rel=1e-9)


def test_a_sine_that_never_reverses_is_judged_to_the_end_of_the_run():
    """Offset above its amplitude, the reference keeps its sign: the load's interval runs to
    the end, so the 8 rpm spike at 1 s is in it, and the error is back within the 3 rpm band
    only when the spike ends, at 1.02 s."""
    t = grid(SINE_RUN, DT)
    ref = 2000.0 + 1000.0 * np.sin(2 * np.pi * SINE_F * t)
    e = load_error(t, T_LOAD, 30.0, 0.01, 0.5) - np.where((t > 1.0 + 1e-9) & (t < 1.02), 8.0, 0.0)
    result = FakeResult(
        t, sine_scenario(T_LOAD), motor_speed_rad_s=RPM * (ref + e), speed_ref_rad_s=RPM * ref
    )
    out = r.sine_metrics(result)
    assert out["load_dip_rpm"] == pytest.approx(-30.0, rel=1e-9)
    assert out["load_recovery_time_s"] == pytest.approx(1.02 - T_LOAD, abs=DT)
    # steady window: the last STEADY_FRACTION of [0.4, 3.0], where the error is the offset
    assert out["load_steady_error_mean_rpm"] == pytest.approx(0.5, rel=1e-6)


def test_a_tuning_cost_of_a_non_finite_trace_is_refused():
    result = speed_step_result(dip=50.0, tau_r=0.02)
    result._columns["measured_speed_rad_s"][5000] = np.nan
    with pytest.raises(ValueError, match="error must contain only finite values"):
        r.tuning_terms(result, MAX_CURRENT_A)


# --------------------------------------------------------------------------- bench step

BENCH_TAU = 0.1  # s
CHATTER_DEG, CHATTER_HZ = 0.01, 5.0
FLUCT_DEG_S = 0.3


def bench_step_result(linkage=False, run=10.0):
    """Rudder step to 4.72 deg, first order; from the steady window on a 5 Hz cosine on the
    angle and, independently, on the rate, each with its crest at the middle of the window
    its figures read (the rate's: the steady window less its one-sided end, r.centred)."""
    t = grid(run, 1e-3)
    start, end = r.steady_window(t[-1])
    in_window = t >= start
    phase = 2 * np.pi * CHATTER_HZ * (t - 0.5 * (start + end))
    angle = 4.72 * (1 - np.exp(-t / BENCH_TAU)) + np.where(
        in_window, CHATTER_DEG * np.cos(phase), 0
    )
    rate_phase = 2 * np.pi * CHATTER_HZ * (t - 0.5 * sum(r.centred(t, (start, end))))
    rate = 4.72 / BENCH_TAU * np.exp(-t / BENCH_TAU) + np.where(
        in_window, FLUCT_DEG_S * np.cos(rate_phase), 0.0
    )
    step = {"type": "step", "time_s": 0.0, "final": 4.72}
    scenario = experiment("rudder_deg", step, arm_mm=None if linkage else ARM_MM)
    columns = {"rudder_angle_rad": DEG * angle}
    if linkage:
        columns["linkage_rudder_rate_rad_s"] = DEG * rate
        columns["actuator_velocity_m_s"] = np.full_like(t, 1e3)  # must not be read
    else:
        columns["actuator_velocity_m_s"] = DEG * rate * ARM_MM * 1e-3
    return FakeResult(t, scenario, **columns)


def test_bench_figures_are_on_the_encoder_reading_with_the_true_ones_beside():
    """With the encoder's reading recorded, each bench figure is the reading's (the rate
    differenced over RATE_WINDOW_S) and ``true_<figure>`` the true angle's: a reading that
    sits 0.01 deg below the target (an accuracy error) and holds still in the steady window
    has an RMS error of 0.01 deg, no vibration and no rate."""
    result = bench_step_result(linkage=True)
    t = result.t
    start = r.steady_window(t[-1])[0]
    true_angle = result["rudder_angle_rad"] / DEG
    reading = np.where(t >= start - r.RATE_WINDOW_S, 4.71, true_angle)  # its jump before it
    result._columns["measured_rudder_rad"] = DEG * reading
    out = r.bench_step_metrics(result)
    true = r.bench_step_metrics(bench_step_result(linkage=True))
    assert {k.removeprefix(r.TRUE_PREFIX) for k in out if k.startswith(r.TRUE_PREFIX)} == set(true)
    assert all(out[r.TRUE_PREFIX + k] == v for k, v in true.items())
    assert out["steady_error_rms_deg"] == pytest.approx(0.01, rel=1e-9)
    assert out["chatter_amplitude_deg"] == 0.0
    assert out["velocity_fluctuation_deg_s"] == pytest.approx(0.0, abs=1e-9)


def test_differenced_rate_is_the_change_over_the_window():
    """A ramp reads its slope; a single count of q reads q / T for the T = RATE_WINDOW_S
    around it and 0 elsewhere."""
    t = grid(2.0, 1e-3)
    assert np.allclose(r.differenced_rate(t, 3.0 * t), 3.0)
    q = 0.088
    step = np.where(t >= 1.0, q, 0.0)
    rate = r.differenced_rate(t, step)
    window = r.RATE_WINDOW_S
    assert rate.max() == pytest.approx(q / window)
    assert np.count_nonzero(rate) == round(window / 1e-3)
    assert rate[np.abs(t - 1.0) > window].max() == 0.0


def test_no_steady_rate_figure_reads_the_one_sided_end_of_the_differenced_rate():
    """A reading still on the 4.72 deg step but for one count in the last 30 ms. A centred
    difference reads that count as q / T, so the rate fluctuation (half peak-to-peak) is
    q / (2 T); the one-sided differences of the last T / 2 divided it by as little as T / 2,
    twice that, which the steady rate figures no longer read."""
    experiment = load_scenario("bench-step").experiment()
    t = grid(10.0, 1e-3)
    q, window = 0.088, r.RATE_WINDOW_S
    reading = np.where(t > t[-1] - 0.03, 4.72 + q, 4.72)
    assert r.differenced_rate(t, reading).max() == pytest.approx(q / (0.5 * window))
    out = r.reading_figures(experiment, t, reading)
    assert out["velocity_fluctuation_deg_s"] == pytest.approx(0.5 * q / window, rel=1e-4)
    assert r.centred(t, (2.0, t[-1])) == pytest.approx((2.0, t[-1] - 0.5 * window))


def test_steady_window():
    assert r.BENCH_STEADY_S == 2.0
    assert r.steady_window(10.0) == (2.0, 10.0)
    assert r.steady_window(3.0) == (1.5, 3.0)  # half the run when shorter


@pytest.mark.parametrize("linkage", [False, True])
def test_bench_step(linkage):
    out = r.bench_step_metrics(bench_step_result(linkage))
    assert out["rise_time_s"] == pytest.approx(BENCH_TAU * math.log(9), rel=1e-4)
    # BENCH_SETTLING_BAND = 5 %: 4.72 exp(-t / tau) = 0.05 * 4.72
    assert r.BENCH_SETTLING_BAND == 0.05
    assert out["settling_time_s"] == pytest.approx(BENCH_TAU * math.log(20), rel=1e-4)
    assert out["chatter_amplitude_deg"] == pytest.approx(CHATTER_DEG, rel=1e-6)
    assert out["chatter_frequency_Hz"] == pytest.approx(CHATTER_HZ, abs=0.05)
    # error = 4.72 - angle = -0.01 cos(...) over 40 whole periods (the exponential is ~1e-8)
    assert out["steady_error_mean_deg"] == pytest.approx(0.0, abs=1e-6)
    assert out["steady_error_std_deg"] == pytest.approx(CHATTER_DEG / math.sqrt(2), rel=1e-3)
    assert out["steady_error_rms_deg"] == pytest.approx(CHATTER_DEG / math.sqrt(2), rel=1e-3)
    assert out["peak_velocity_deg_s"] == pytest.approx(4.72 / BENCH_TAU, rel=1e-9)
    # (to the discretisation: both ends of the period are samples)
    assert out["velocity_fluctuation_deg_s"] == pytest.approx(FLUCT_DEG_S, rel=1e-3)
    # the reference is constant: the rate error is minus the rate
    # over the rate's window, 7.95 s of 5 Hz centred on a crest: the cosine's mean there is
    # sin(pi f L) / (pi f L) of its amplitude (to the 1 ms samples: 2 % of it a sample of L)
    span = math.pi * CHATTER_HZ * 7.95
    expected = -FLUCT_DEG_S * math.sin(span) / span
    assert out["velocity_error_mean_deg_s"] == pytest.approx(expected, rel=3e-2)
    # and its mean square (1 + sin(2 pi f L) / (2 pi f L)) / 2 of the amplitude squared
    square = FLUCT_DEG_S**2 * 0.5 * (1.0 + math.sin(2 * span) / (2 * span))
    rms = math.sqrt(square)
    assert out["velocity_error_rms_deg_s"] == pytest.approx(rms, rel=1e-3)
    assert out["velocity_error_std_deg_s"] == pytest.approx(
        math.sqrt(square - expected**2), rel=1e-3
    )


# --------------------------------------------------------------------------- bench sine

BENCH_F = 0.05  # Hz; the rate's steady window [2, 22] s (r.centred) is one whole period
LAG_S = 0.2  # s: the rudder starts late, and first backs off


def bench_sine_result(reverse_deg, gain=0.98, run=22.05):
    t = grid(run, 1e-3)
    w = 2 * np.pi * BENCH_F
    late = t >= LAG_S
    angle = np.where(
        late, gain * 19.0 * np.sin(w * (t - LAG_S)), -reverse_deg * np.sin(np.pi * t / LAG_S)
    )
    rate = np.where(
        late,
        gain * 19.0 * w * np.cos(w * (t - LAG_S)),
        -reverse_deg * np.pi / LAG_S * np.cos(np.pi * t / LAG_S),
    )
    rate = rate + np.where(t >= 2.0, FLUCT_DEG_S * np.cos(2 * np.pi * 2.0 * t), 0.0)
    sine = {"type": "sine", "amplitude": 19.0, "frequency_Hz": BENCH_F}
    scenario = experiment("rudder_deg", sine, arm_mm=ARM_MM)
    return FakeResult(
        t,
        scenario,
        rudder_angle_rad=DEG * angle,
        actuator_velocity_m_s=DEG * rate * ARM_MM * 1e-3,
    )


def test_bench_sine_tracking_and_fluctuation():
    gain = 0.98
    out = r.bench_sine_metrics(bench_sine_result(reverse_deg=0.05, gain=gain))
    lag = 2 * math.pi * BENCH_F * LAG_S
    assert out["phase_lag_deg"] == pytest.approx(360 * BENCH_F * LAG_S, rel=1e-6)  # 3.6 deg
    assert out["lag_s"] == pytest.approx(LAG_S, rel=1e-6)
    expected = 19.0 * math.sqrt(1 + gain**2 - 2 * gain * math.cos(lag))
    assert out["tracking_error_deg"] == pytest.approx(expected, rel=1e-6)
    # in the first second the largest rate is the sine's crest at LAG_S
    assert out["peak_velocity_deg_s"] == pytest.approx(
        gain * 19.0 * 2 * math.pi * BENCH_F, rel=1e-6
    )
    # 2 Hz ripple over whole periods of both: the fitted 0.05 Hz sine leaves exactly it
    # (to the discretisation: both ends of the period are samples)
    assert out["velocity_fluctuation_deg_s"] == pytest.approx(FLUCT_DEG_S, rel=1e-3)


@pytest.mark.parametrize(
    ("reverse_deg", "flag"),
    [(0.05, 1.0), (0.5 * r.REVERSE_DEG, 0.0), (0.0, 0.0)],
)
def test_bench_sine_reverse_motion(reverse_deg, flag):
    assert r.REVERSE_DEG == 0.01
    out = r.bench_sine_metrics(bench_sine_result(reverse_deg))
    assert out["initial_reverse_motion"] == flag
    assert out["reverse_motion_deg"] == pytest.approx(reverse_deg, rel=1e-9, abs=1e-15)


# --------------------------------------------------------------------------- limits, dispatch


def test_limit_metrics_and_warnings():
    t = grid(1.0, 1e-3)  # 1001 rows of 1 ms
    flags = np.zeros(t.size, dtype=np.int64)
    flags[100:200] |= LIMIT_CURRENT  # 100 rows
    flags[150:180] |= LIMIT_VOLTAGE  # 30 rows, 20 of them with the current too
    flags[900:905] |= LIMIT_SPEED  # 5 rows
    force = np.zeros(t.size)
    force[500:525] = -3000.0  # 25 rows against the lower stop
    force[510] = -5000.0
    torque = np.zeros(t.size)
    result = FakeResult(
        t, {}, limit_flags=flags, end_stop_force_N=force, rudder_stop_torque_Nm=torque
    )
    out = r.limit_metrics(result)
    assert out["current_saturation_time_s"] == pytest.approx(0.100, rel=1e-9)
    assert out["voltage_saturation_time_s"] == pytest.approx(0.030, rel=1e-9)
    assert out["speed_saturation_time_s"] == pytest.approx(0.005, rel=1e-9)
    assert out["end_stop_contact_time_s"] == pytest.approx(0.025, rel=1e-9)
    assert out["end_stop_peak_force_N"] == 5000.0
    assert out["rudder_stop_contact_time_s"] == 0.0
    assert out["rudder_stop_peak_torque_Nm"] == 0.0
    (line,) = r.run_warnings(out)
    assert "rod's end stops" in line and "0.025 s" in line and "5000 N" in line
    # a plant without stops or flags reports neither
    assert r.limit_metrics(FakeResult(t, None)) == {}
    assert r.run_warnings({}) == []


def test_limit_times_when_every_block_holds_one_row(monkeypatch):
    """The recording period comes from the first two rows, across a seam if need be."""
    monkeypatch.setattr(FakeResult, "block_rows", 1)
    t = grid(0.1, 1e-3)
    flags = np.where(t < 0.05, LIMIT_CURRENT, 0)
    out = r.limit_metrics(FakeResult(t, {}, limit_flags=flags))
    assert out["current_saturation_time_s"] == pytest.approx(0.050, rel=1e-9)


def test_a_non_finite_stop_force_is_a_non_finite_peak():
    t = grid(1.0, 1e-3)
    force, torque = np.zeros(t.size), np.zeros(t.size)
    force[700] = np.nan
    result = FakeResult(t, {}, end_stop_force_N=force, rudder_stop_torque_Nm=torque)
    assert math.isnan(r.limit_metrics(result)["end_stop_peak_force_N"])


def test_run_metrics_dispatch_and_limits():
    result = speed_step_result(dip=50.0, tau_r=0.02)
    result._columns["limit_flags"] = np.zeros_like(result.t)
    out = r.run_metrics(result)
    assert out["load_recovery_time_s"] == pytest.approx(0.02 * math.log(10.0), rel=1e-4)
    assert out["current_saturation_time_s"] == 0.0
    # tuning cost: IAE = 1000 rpm * TAU (the rise) + 50 rpm * 0.02 s (the dip), over
    # T * max|ref| = 2 s * 1000 rpm; the current command is constant, so no chattering price
    iae = 1000.0 * TAU * (1 - math.exp(-T_LOAD / TAU)) + 50.0 * 0.02
    assert out["tuning_cost"] == pytest.approx(iae / (SPEED_RUN * 1000.0), rel=1e-3)


def test_tuning_cost_is_on_the_reading_and_covers_the_steady_window():
    """J = IAE(e) / (T R) + RMS_s(e) / R + A_s(e) / R on the reading: a 2 rpm, 50 Hz ripple
    that only the sensor reads, in the steady window before the load step (the last 20 % of
    [0, 0.4] s, four whole periods), adds its mean |.| to the IAE, 2 / sqrt(2) rpm of RMS and
    2 rpm of half peak-to-peak; the true speed does not enter."""
    result = speed_step_result(dip=50.0, tau_r=0.02)
    t = result.t
    assert r.cost_window(result) == pytest.approx((0.32, 0.4))  # the load step's row excluded
    ripple = np.where((t >= 0.32) & (t <= 0.4), 2.0 * np.sin(2 * np.pi * 50.0 * t), 0.0)
    result._columns["measured_speed_rad_s"] = result["motor_speed_rad_s"] + RPM * ripple
    result._columns["motor_speed_rad_s"] = np.zeros_like(t)  # must not be read
    iae = 1000.0 * TAU * (1 - math.exp(-T_LOAD / TAU)) + 50.0 * 0.02 + 2.0 * (2 / math.pi) * 0.08
    tracking, chatter = r.tuning_terms(result, MAX_CURRENT_A)
    expected = iae / (SPEED_RUN * 1000.0) + (2.0 / math.sqrt(2) + 2.0) / 1000.0
    assert tracking == pytest.approx(expected, rel=2e-3)
    assert chatter == 0.0  # a constant current command


def test_a_scenario_states_its_experiment():
    """What the metrics read of a scenario, from its typed fields: the shipped scenarios'
    references, load steps, limits and arm (their TOML files give these figures)."""
    speed = load_scenario("speed-step").experiment()
    assert (speed.quantity, speed.shape, speed.load_step_s) == ("speed", "step", 0.4)
    assert (speed.max_current_A, speed.max_speed_rpm, speed.stroke_mm) == (58.0, 3000.0, 250.0)
    assert speed.rudder_arm_m == pytest.approx(1e-3 * ARM_MM, rel=1e-3)
    sine = load_scenario("speed-sine").experiment()
    assert (sine.quantity, sine.shape, sine.sine_frequency_Hz) == ("speed", "sine", 0.318)
    position = load_scenario("position-step").experiment()
    assert (position.quantity, position.shape, position.load_step_s) == ("position", "step", 3.0)
    assert position.stroke_mm is None  # its end stops hold the rod
    bench = load_scenario("bench-step").experiment()
    assert (bench.quantity, bench.reference[0]["final"], bench.max_speed_rpm) == (
        "rudder",
        4.72,
        1800.0,
    )
    assert bench.rudder_arm_m is None  # the linkage: the rudder's rate is a state
    no_change = 'load.motor_torque_Nm=[{type="step", time_s=1.0, initial=2.0, final=2.0}]'
    assert load_scenario("speed-step", settings=[no_change]).experiment().load_step_s is None


def test_undefined_metrics():
    reasons = r.undefined_metrics({"load_recovery_time_s": math.nan, "gain": math.inf, "x": 1.0})
    assert set(reasons) == {"load_recovery_time_s", "gain"}
    assert reasons["load_recovery_time_s"].startswith("never reached")
    assert reasons["gain"].startswith("not defined")
