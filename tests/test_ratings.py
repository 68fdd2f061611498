"""The drive's rated limits (emasim.plant.elements.ratings) hold whatever a controller commands.

Closed forms checked:

* I^2 t: with the rotor locked, a law asking ten times the peak current gets the peak until
  the heat (iq^2 - I_cont^2) t reaches its capacity (I_peak^2 - I_cont^2) t_peak, that is
  after t_peak plus the current loop's rise, and the continuous current from then on; once
  the command stops, the motor cools at I_cont^2 and the peak returns after
  RECOVERY E_max / I_cont^2;
* rated speed: the same law on a free motor accelerates it to the fold-back band below the
  rated speed, (1 - SPEED_FOLDBACK) w_r .. w_r, where it stays (past a transient overshoot of
  the current loop's lag);
* voltage: a current law asking ten times the inverter's voltage gets Udc / sqrt(3);
* each limit is flagged in limit_flags, and limit_metrics counts the flagged time.
"""

import math

import numba
import numpy as np
import pytest

from emasim.analysis.report import limit_metrics
from emasim.control.slot import CONTROLLER_SIG, Compiled
from emasim.errors import InputError
from emasim.interface import (
    LIMIT_CURRENT,
    LIMIT_SPEED,
    LIMIT_VOLTAGE,
    O_RATE,
    O_UD,
    O_UQ,
    O_VALUE,
    R_VALUE,
)
from emasim.plant.elements.ratings import RECOVERY, SPEED_FOLDBACK
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate

RATED_RPM, CONTINUOUS_A, PEAK_S = 1500.0, 20.0, 0.05
RATINGS = (
    f"plant.ratings={{rated_speed_rpm={RATED_RPM}, continuous_current_A={CONTINUOUS_A}, "
    f"peak_current_s={PEAK_S}}}"
)


@numba.njit(CONTROLLER_SIG)
def ask_current(state, params, meas, ref, ts, out):
    """A user's speed law: a constant current command, params[0] (A)."""
    out[O_VALUE] = params[0]
    out[O_RATE] = 0.0


@numba.njit(CONTROLLER_SIG)
def ask_voltage(state, params, meas, ref, ts, out):
    """A user's current law: a constant q-axis voltage, params[0] (V)."""
    out[O_UD] = 0.0
    out[O_UQ] = params[0]


def greedy_run(duration_s: float, *settings: str):
    """speed-step on the motor stand with ratings, its speed law asking 10 x the peak current."""
    scenario = load_scenario(
        "speed-step",
        settings=[f"duration_s={duration_s}", "load.motor_torque_Nm=[]", RATINGS, *settings],
    )
    i_peak = scenario.plant.motor.max_current_A
    greedy = Compiled(ask_current, np.array([10.0 * i_peak]), np.zeros(1))
    setup = scenario.setup().with_(speed=greedy, record_every=1)
    return scenario, simulate(setup)


@numba.njit(CONTROLLER_SIG)
def pass_through(state, params, meas, ref, ts, out):
    """A user's speed law: its reference, read as a current command (A)."""
    out[O_VALUE] = ref[R_VALUE]
    out[O_RATE] = 0.0


def flagged(result, bit: int) -> np.ndarray:
    return (result["limit_flags"].astype(np.int64) & bit) != 0


def test_the_peak_current_lasts_its_rated_time_then_the_continuous_current_holds():
    scenario, result = greedy_run(3 * PEAK_S, "plant.motor.inertia_kgm2=1e6")  # locked rotor
    t, limit, iq_ref = result.t, result["current_limit_A"], result["iq_ref_A"]
    i_peak = scenario.plant.motor.max_current_A
    switch = t[np.argmax(limit < i_peak)]
    # the heat starts once the measured current exceeds I_cont: within the current loop's rise
    assert PEAK_S <= switch <= PEAK_S + 2e-3
    assert np.all(iq_ref[t < switch] == i_peak)
    assert np.all(iq_ref[t >= switch] == CONTINUOUS_A)  # at I_cont the heat stays at capacity
    assert np.all(flagged(result, LIMIT_CURRENT))
    metrics = limit_metrics(result)
    assert metrics["current_saturation_time_s"] == pytest.approx(t[-1] + t[1], rel=1e-12)
    assert metrics["speed_saturation_time_s"] == 0.0


def test_the_peak_current_returns_once_the_motor_has_cooled():
    stop = 2 * PEAK_S
    command = 3000.0  # rpm as the reference, read as 314 A by the pass-through law
    scenario = load_scenario(
        "speed-step",
        settings=[
            f"duration_s={3 * PEAK_S}",
            "load.motor_torque_Nm=[]",
            RATINGS,
            "plant.motor.inertia_kgm2=1e6",
            f'reference.speed_rpm=[{{type="step", final={command}}}, '
            f'{{type="step", time_s={stop}, final={-command}}}]',
        ],
    )
    plant = scenario.plant
    i_peak = plant.motor.max_current_A
    setup = scenario.setup().with_(speed=Compiled(pass_through, np.zeros(1), np.zeros(1)))
    result = simulate(setup.with_(record_every=1))
    t, limit = result.t, result["current_limit_A"]
    capacity = (i_peak**2 - CONTINUOUS_A**2) * PEAK_S
    cooled = stop + RECOVERY * capacity / CONTINUOUS_A**2
    back = t[(t > stop) & (limit == i_peak)][0]
    assert cooled <= back <= cooled + 1e-3  # the current falls to zero within a millisecond


def test_the_rated_speed_holds_on_a_free_motor():
    scenario, result = greedy_run(0.2)
    w_rated = RATED_RPM * 2.0 * math.pi / 60.0
    speed = result["motor_speed_rad_s"]
    # the current loop takes a millisecond to follow the fold-back at 15000 rad/s^2: 0.8 %
    assert speed.max() <= w_rated * 1.01
    late = result.t > 0.1
    assert np.all((1.0 - SPEED_FOLDBACK) * w_rated <= speed[late])
    assert np.all(speed[late] <= w_rated)
    assert np.all(flagged(result, LIMIT_SPEED)[late])
    assert limit_metrics(result)["speed_saturation_time_s"] > 0.09


def test_the_inverter_voltage_holds_on_a_users_current_law():
    # 1 ms: the full bus voltage drives the current past 1000 A within 1.5 ms (L di/dt = u)
    scenario = load_scenario("speed-step", settings=["duration_s=0.001"])
    u_max = scenario.plant.motor.dc_bus_V / math.sqrt(3.0)
    loud = Compiled(ask_voltage, np.array([10.0 * u_max]), np.zeros(2))
    result = simulate(scenario.setup().with_(current=loud))
    assert np.allclose(np.hypot(result["ud_V"], result["uq_V"]), u_max, rtol=1e-12)
    assert np.all(flagged(result, LIMIT_VOLTAGE))


def test_a_library_law_that_limits_itself_is_counted_at_the_limit():
    """The library's PI limits its own output to the current limit, so the drive never cuts
    it; the time at the limit must still agree with the current command's trace."""
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=["duration_s=0.05"])
    result = simulate(scenario.setup())
    at_limit = np.abs(result["iq_ref_A"]) >= scenario.plant.motor.max_current_A
    assert at_limit.any()
    assert np.array_equal(flagged(result, LIMIT_CURRENT), at_limit)
    dt = result.t[1] - result.t[0]
    assert limit_metrics(result)["current_saturation_time_s"] == pytest.approx(
        np.count_nonzero(at_limit) * dt
    )


@pytest.mark.parametrize(
    "setting, words",
    [
        ("plant.ratings.continuous_current_A=70.0", "continuous_current_A"),
        ("plant.ratings.rated_speed_rpm=4000.0", "rated_speed_rpm"),
    ],
)
def test_ratings_beyond_the_drives_limits_are_refused(setting, words):
    with pytest.raises(InputError, match=words):
        load_scenario("speed-step", settings=[RATINGS, setting])
