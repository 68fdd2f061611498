"""The digital side: the computation delay, derived (encoder) channels, sample and hold.

* Computation delay Td = d h (emasim.sim.engine): in an open linear loop, a locked-rotor motor
  whose q voltage is a gain times a sampled sine, the recorded iq_A is the response of
  1 / (Lq s + Rs) to the zero-order-held, delayed voltage. Its fundamental is checked against
  the exact sampled-data solution of that law, written here: over a tick [k Ts, (k+1) Ts)
  the previous voltage u_{k-1} acts for Td and u_k for Ts - Td, so

      i_{k+1} = a i_k + g1 u_{k-1} + g2 u_k,   a = exp(-Ts/te), te = Lq/Rs,
      g1 = (1 - exp(-Td/te)) exp(-(Ts - Td)/te) / Rs,   g2 = (1 - exp(-(Ts - Td)/te)) / Rs,

  and the steady-state gain to a sampled sine is H = (g1/z + g2) / (z - a), z = exp(j w Ts).
  The delay shifts the applied voltage by exactly Td, so the continuous response lags by
  exactly w Td; the trace samples it at the ticks, where a whole-tick delay (d = substeps)
  shows as exactly w Ts, and a fraction of a tick as w Td up to an aliasing term of relative
  size about (Rs Ts / 2 Lq)(1 - Td/Ts) (0.4 % here at Td = 3 h), which the exact H carries.
* A derived speed differentiates the encoder's counts: every reading is a whole number of
  counts per sample period, and their mean is the true speed within half a count over the window;
  the first-order filter is the exact discretisation w (1 - exp(-k Ts/tau)) of a step.
* A channel with its own sample period samples every n-th tick and holds its reading between.
"""

import math

import numba
import numpy as np
import pytest
from pydantic import ValidationError

from emasim.config import RPM
from emasim.control.slot import CONTROLLER_SIG, Compiled
from emasim.errors import InputError
from emasim.interface import (
    M_ANGLE,
    M_IQ,
    M_POSITION,
    M_SPEED,
    M_VELOCITY,
    MEASUREMENT_NAMES,
    N_MEAS,
    O_RATE,
    O_UD,
    O_UQ,
    O_VALUE,
    R_VALUE,
)
from emasim.plant import actuator as A
from emasim.plant.parameters import SensorChannel, SensorParams
from emasim.plant.presets import sea805
from emasim.plant.sensors import S_EVERY, S_PERIOD, S_SOURCE, initial_state, measure
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate

TS = 1e-4  # s: the shipped scenarios' controller sample period
H = 1e-5  # s: a sub-step of 10 per tick, set here (the shipped ones are coarser): a fine
# grid of delays to test on

# --- the computation delay ------------------------------------------------------------------


@numba.njit(CONTROLLER_SIG)
def pass_reference_as_current(state, params, meas, ref, ts, out):
    """A user's speed law: the speed reference, read as the q current command (A)."""
    out[O_VALUE] = ref[R_VALUE]
    out[O_RATE] = 0.0


@numba.njit(CONTROLLER_SIG)
def voltage_proportional_to_reference(state, params, meas, ref, ts, out):
    """A user's current law: u_d = 0, u_q = gain * (q current reference)."""
    out[O_UD] = 0.0
    out[O_UQ] = params[0] * ref[R_VALUE]


AMPLITUDE_A = 10.0  # the sine, read as a current command
GAIN_V_PER_A = 0.05
SETTLE_S = 0.25  # 29 electrical time constants (Lq / Rs = 8.6 ms): the transient is gone
WINDOW_S = 0.1


def open_loop_run(frequency_Hz: float, delay_substeps: int):
    """The open loop at one frequency and delay: (scenario, setup, result). The rotor is
    locked (1e6 kg m^2: the speed stays below 1e-6 rad/s, its back-EMF negligible), no friction."""
    scenario = load_scenario(
        "speed-step",
        controllers=["speed=pi"],
        settings=[
            f"duration_s={SETTLE_S + WINDOW_S + 2 * TS}",
            f"solver.record_period_s={TS}",
            "plant.motor.inertia_kgm2=1e6",
            'plant.friction.model="none"',
            "load.motor_torque_Nm=[]",
            f'reference.speed_rpm=[{{type="sine", amplitude={AMPLITUDE_A / RPM}, '
            f"frequency_Hz={frequency_Hz}}}]",
            f"solver.step_s={H}",
            f"loop.computation_delay_s={delay_substeps * H}",
        ],
    )
    setup = scenario.setup()
    assert setup.delay_substeps == delay_substeps and setup.step_s == pytest.approx(H)
    setup = setup.with_(
        speed=Compiled(pass_reference_as_current, np.zeros(1), np.zeros(1)),
        current=Compiled(
            voltage_proportional_to_reference,
            np.array([GAIN_V_PER_A]),
            np.zeros(1),
            commands="voltage",
        ),
    )
    result = simulate(setup)
    assert np.max(np.abs(result["motor_speed_rad_s"])) < 1e-6
    return scenario, setup, result


def fundamental(t, y, frequency_Hz):
    """The phasor a + j b of y = a sin(w t) + b cos(w t), least squares over the whole number
    of periods of WINDOW_S after SETTLE_S."""
    w = 2.0 * math.pi * frequency_Hz
    periods = round(WINDOW_S * frequency_Hz)
    assert abs(periods - WINDOW_S * frequency_Hz) < 1e-9 and periods >= 2
    ticks = round(periods / frequency_Hz / TS)
    first = int(np.searchsorted(t, SETTLE_S - 0.5 * TS))
    window = slice(first, first + ticks)
    assert len(t[window]) == ticks
    basis = np.column_stack([np.sin(w * t[window]), np.cos(w * t[window])])
    (a, b), *_ = np.linalg.lstsq(basis, y[window], rcond=None)
    return complex(a, b)


def sampled_data_gain(frequency_Hz, delay_s, resistance, inductance):
    """H of the module docstring: the exact tick-to-tick solution of Lq di/dt = u - Rs i with
    the voltage switching from u_{k-1} to u_k Td into each tick."""
    te = inductance / resistance
    a = math.exp(-TS / te)
    g1 = -math.expm1(-delay_s / te) * math.exp(-(TS - delay_s) / te) / resistance
    g2 = -math.expm1(-(TS - delay_s) / te) / resistance
    z = complex(
        math.cos(2 * math.pi * frequency_Hz * TS), math.sin(2 * math.pi * frequency_Hz * TS)
    )
    return (g1 / z + g2) / (z - a)


@pytest.mark.parametrize("frequency_Hz", [20.0, 50.0, 100.0])
def test_the_computation_delay_is_a_phase_lag_of_the_sampled_data_law(frequency_Hz):
    w = 2.0 * math.pi * frequency_Hz
    substeps = round(TS / H)
    phasors = {}
    for d in (0, 3, substeps):
        scenario, setup, result = open_loop_run(frequency_Hz, d)
        motor = scenario.plant.motor
        measured = fundamental(result.t, result["iq_A"], frequency_Hz)
        expected = (
            sampled_data_gain(frequency_Hz, d * H, motor.resistance_ohm, motor.inductance_q_H)
            * GAIN_V_PER_A
            * AMPLITUDE_A
        )
        # measured 2e-9 .. 4e-8 (the locked rotor's creep: its back-EMF), alike for every d
        assert abs(measured / expected - 1.0) < 2e-7
        phasors[d] = measured
    for d in (3, substeps):
        lag = np.angle(phasors[0]) - np.angle(phasors[d])
        motor = scenario.plant.motor
        exact = np.angle(
            sampled_data_gain(frequency_Hz, 0.0, motor.resistance_ohm, motor.inductance_q_H)
        ) - np.angle(
            sampled_data_gain(frequency_Hz, d * H, motor.resistance_ohm, motor.inductance_q_H)
        )
        assert lag == pytest.approx(exact, abs=1e-9)  # measured below 1e-14
        # w Td itself: exactly for a whole tick; for a fraction of one, up to the aliasing
        # term (its first-order size below; measured 4.10e-3 .. 4.27e-3 of w Td at d = 3)
        aliasing = 0.5 * motor.resistance_ohm * TS / motor.inductance_q_H * (1 - d * H / TS)
        assert abs(lag - w * d * H) <= 1.25 * aliasing * w * d * H + 1e-9
    assert np.angle(phasors[0]) - np.angle(phasors[substeps]) == pytest.approx(w * TS, abs=1e-9)


@pytest.mark.parametrize(
    ("delay_s", "words"),
    [
        (
            1.5e-5,
            r"loop\.computation_delay_s \(1\.5e-05 s\) must be a whole number of solver\.step_s",
        ),
        (2e-4, r"loop\.computation_delay_s \(0\.0002 s\) must not exceed solver\.sample_period_s"),
        (0.02, r"loop\.computation_delay_s: .*less than or equal to 0\.01"),
    ],
)
def test_a_delay_off_the_sub_step_grid_or_beyond_a_tick_is_refused(delay_s, words):
    with pytest.raises(InputError, match=words):
        load_scenario("speed-step", settings=[f"loop.computation_delay_s={delay_s}"])


def test_a_delay_on_the_grid_is_a_whole_number_of_sub_steps():
    for delay_s, substeps in ((0.0, 0), (3e-5, 3), (7e-5, 7), (1e-4, 10)):
        setup = load_scenario(
            "speed-step", settings=[f"solver.step_s={H}", f"loop.computation_delay_s={delay_s}"]
        ).setup()
        assert setup.delay_substeps == substeps


# --- derived channels ----------------------------------------------------------------------


def readings(sensors: SensorParams, states, channel):
    """Channel ``channel``'s reading at ticks 0, 1, ... of the plant states ``states`` (each
    a function of the tick filling x), through emasim.plant.sensors.measure."""
    p = sea805().pack()
    table = sensors.pack(TS)
    x = np.zeros(A.N_STATE)
    states(x, 0)
    state = initial_state(x, p)
    meas = np.zeros(N_MEAS)
    out = []
    for k in range(states.ticks):
        states(x, k)
        measure(x, p, table, state, meas, k)
        out.append(meas[channel])
    return np.array(out)


class Turning:
    """The motor angle theta0 + w (k Ts) + a (k Ts)^2 / 2 at tick k, over ``ticks`` ticks."""

    def __init__(self, ticks, speed, acceleration=0.0, start=0.0):
        self.ticks, self.speed, self.acceleration, self.start = ticks, speed, acceleration, start

    def angle(self, k):
        t = k * TS
        return self.start + self.speed * t + 0.5 * self.acceleration * t * t

    def __call__(self, x, k):
        x[A.X_THETA] = self.angle(k)


COUNT = 2.0 * math.pi / 4096  # rad: a 12-bit encoder


def test_an_encoder_speed_counts_whole_counts_and_averages_to_the_speed():
    """At 100 rad/s an encoder of 4096 counts turns 6.52 counts a tick: each reading is a
    whole number of counts per Ts, exactly the counts gained since the last tick, and the mean
    over N ticks is the speed within half a count over N Ts (the window's two ends)."""
    speed, ticks = 100.0, 1000
    turning = Turning(ticks + 1, speed)
    sensors = SensorParams(speed=SensorChannel(derived=True), angle=SensorChannel(resolution=COUNT))
    assert sensors.pack(TS)[M_SPEED, S_SOURCE] == M_ANGLE
    speeds = readings(sensors, turning, M_SPEED)
    counts = speeds * TS / COUNT
    assert np.max(np.abs(counts - np.round(counts))) < 1e-9
    assert set(np.round(counts[1:]).astype(int)) == {6, 7}
    gained = np.diff(np.round([turning.angle(k) / COUNT for k in range(ticks + 1)]))
    assert np.array_equal(np.round(counts[1:]), gained)
    assert counts[0] == 0.0  # at tick 0 from rest
    mean = speeds[1:].mean()
    assert abs(mean - speed) <= 0.5 * COUNT / (ticks * TS) * (1 + 1e-9)
    assert abs(mean - speed) > 0.0  # a count does not divide the travel: not trivially exact


def test_the_derived_speeds_filter_is_the_exact_discretisation_of_its_lag():
    """Resolution 0, tau = 1 ms: a speed step read through the lag gives w (1 - exp(-k Ts /
    tau)) at tick k, i.e. w (1 - (1 - alpha)^k) with alpha = 1 - exp(-Ts / tau)."""
    speed, tau, ticks = 100.0, 1e-3, 200
    sensors = SensorParams(speed=SensorChannel(derived=True, filter_time_constant_s=tau))
    filtered = readings(sensors, Turning(ticks, speed), M_SPEED)
    k = np.arange(ticks)
    assert np.max(np.abs(filtered - speed * -np.expm1(-k * TS / tau))) < 1e-10 * speed
    alpha = 1.0 - math.exp(-TS / tau)
    assert np.allclose(filtered, speed * (1.0 - (1.0 - alpha) ** k), rtol=0, atol=1e-10 * speed)


@pytest.mark.parametrize(
    "angle", [SensorChannel(offset=0.01), SensorChannel(resolution=COUNT)], ids=["offset", "count"]
)
def test_a_plant_at_rest_reads_zero_speed_from_the_first_tick(angle):
    """A plant at rest reads zero rate from tick 0 on, whatever the source's offset, or
    wherever between two counts the encoder stands (the first sample differences nothing)."""
    at_rest = Turning(3, 0.0, start=0.3)  # at rest at 0.3 rad, between two counts
    sensors = SensorParams(speed=SensorChannel(derived=True), angle=angle)
    speeds = readings(sensors, at_rest, M_SPEED)
    assert np.all(speeds == 0.0), speeds


# --- sample and hold -----------------------------------------------------------------------


class Moving:
    """Rod position 1 mm * (k + 1) and iq 0.1 A * k at tick k; and the motor angle."""

    def __init__(self, ticks, acceleration=0.0):
        self.ticks = ticks
        self.turning = Turning(ticks, 0.0, acceleration)

    def __call__(self, x, k):
        x[A.X_XL] = 1e-3 * (k + 1)
        x[A.X_IQ] = 0.1 * k
        self.turning(x, k)


def test_a_slower_channel_samples_every_nth_tick_and_holds_between():
    every, ticks = 5, 23
    sensors = SensorParams(position=SensorChannel(sample_period_s=every * TS))
    table = sensors.pack(TS)
    assert table[M_POSITION, S_EVERY] == every and table[M_POSITION, S_PERIOD] == every * TS
    moving = Moving(ticks)
    position = readings(sensors, moving, M_POSITION)
    k = np.arange(ticks)
    assert np.array_equal(position, 1e-3 * (every * (k // every) + 1))
    assert np.array_equal(readings(sensors, moving, M_IQ), 0.1 * k)  # the others every tick


def test_a_slower_derived_channel_differentiates_over_its_own_period():
    """A derived speed sampled every 5 ticks, the angle at a constant acceleration a: at tick
    5m it reads (theta(5m Ts) - theta(5(m-1) Ts)) / (5 Ts) = a (5m - 2.5) Ts, held between."""
    every, ticks, accel = 5, 26, 2000.0
    sensors = SensorParams(speed=SensorChannel(derived=True, sample_period_s=every * TS))
    speed = readings(sensors, Moving(ticks, accel), M_SPEED)
    k = np.arange(ticks)
    m = k // every
    expected = np.where(m == 0, 0.0, accel * (every * m - 0.5 * every) * TS)
    assert np.allclose(speed, expected, rtol=1e-9, atol=1e-12)
    assert speed[-1] > 0.9  # rad/s: it did move


def test_the_engine_holds_a_slower_channel_between_its_samples():
    scenario = load_scenario(
        "speed-step",
        controllers=["speed=pi"],
        settings=["duration_s=0.02", f"sensors.position.sample_period_s={5 * TS}"],
    )
    result = simulate(scenario.setup())
    assert scenario.solver.record_period_s == TS  # a row per tick
    measured, true = result["measured_position_m"], result["actuator_position_m"]
    k = np.arange(len(measured))
    sampled = k % 5 == 0
    assert np.array_equal(measured[sampled], true[sampled])
    assert np.array_equal(measured[~sampled], measured[(k - k % 5)[~sampled]])
    assert np.ptp(true) > 1e-4 and np.all(np.diff(true[200:]) > 0)  # the rod moves each tick


@pytest.mark.parametrize("period_s", [2.5e-4, 5e-5, 1.5e-4])
def test_a_sample_period_off_the_controllers_multiple_is_refused(period_s):
    with pytest.raises(InputError, match=r"sensors\.velocity\.sample_period_s .*whole multiple"):
        load_scenario("speed-step", settings=[f"sensors.velocity.sample_period_s={period_s}"])


@pytest.mark.parametrize("name", [n for n in MEASUREMENT_NAMES if n not in ("speed", "velocity")])
def test_only_speed_and_velocity_can_be_derived(name):
    with pytest.raises(ValidationError, match=rf"{name}\.derived: only speed and velocity"):
        SensorParams(**{name: SensorChannel(derived=True)})
    with pytest.raises(InputError, match=rf"{name}\.derived"):
        load_scenario("speed-step", settings=[f"sensors.{name}.derived=true"])


def test_speed_derives_from_the_angle_and_velocity_from_the_position():
    table = SensorParams(
        speed=SensorChannel(derived=True), velocity=SensorChannel(derived=True)
    ).pack(TS)
    assert table[M_SPEED, S_SOURCE] == M_ANGLE
    assert table[M_VELOCITY, S_SOURCE] == M_POSITION
    assert all(table[i, S_SOURCE] == -1 for i in range(N_MEAS) if i not in (M_SPEED, M_VELOCITY))
