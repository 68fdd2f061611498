"""PI/PID law and current loop: each against an independent closed form."""

import math

import control as ct
import numpy as np
import pytest
from pydantic import ValidationError
from scipy.signal import lfilter

from emasim.control.pid import KAW, PositionPID, pack_pid, pid
from emasim.errors import InputError
from emasim.interface import M_POSITION, M_SPEED, N_MEAS, N_OUT, N_REF, O_VALUE, R_VALUE
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate

TS = 1e-3


def run_law(compiled, y, r=0.0, r_rate=0.0):
    """Feed the compiled law a measurement sequence y; return its outputs."""
    meas, ref, out = np.zeros(N_MEAS), np.array([r, r_rate, 0.0]), np.zeros(2)
    state = compiled.state.copy()
    channel = int(compiled.params[7])
    outputs = []
    for value in y:
        meas[channel] = value
        compiled.function(state, compiled.params, meas, ref, TS, out)
        outputs.append(out[0])
    return np.array(outputs)


def test_pid_law_matches_its_transfer_function():
    """u = Kp e + Ki * forward-Euler integral of e - Kd s/(1 + Tf s) y (backward Euler)."""
    rng = np.random.default_rng(0)
    y = np.cumsum(rng.normal(size=400)) * 0.01
    kp, ki, kd, tf = 2.0, 30.0, 0.05, 0.01
    law = pack_pid(kp, ki, kd, tf, limit=1e9, kff=0.0, channel=M_SPEED)
    u = run_law(law, y, r=0.3)
    e = 0.3 - y
    integral = np.concatenate([[0.0], np.cumsum(ki * TS * e)[:-1]])
    dy = np.diff(y, prepend=y[0])
    # backward Euler of -Kd s/(1+Tf s): d_k = (Tf d_{k-1} - Kd (y_k - y_{k-1})) / (Tf + TS)
    deriv = lfilter([-kd / (tf + TS)], [1.0, -tf / (tf + TS)], dy)
    np.testing.assert_allclose(u, kp * e + integral + deriv, rtol=1e-12, atol=1e-12)


def test_anti_windup_releases_the_output_as_soon_as_the_error_reverses():
    law = pack_pid(1.0, 50.0, 0.0, 0.01, limit=1.0, kff=0.0, channel=M_SPEED)
    assert law.params[KAW] == pytest.approx(50.0)
    y = np.concatenate([np.zeros(2000), np.full(200, 20.0)])  # long saturation, then overshoot
    u = run_law(law, y, r=10.0)
    assert u[1999] == 1.0
    # with error -10 the proportional part alone would ask -10: the output must leave the
    # limit at once instead of waiting for a wound-up integrator (2000 * 50 * 1e-3 * 10 = 1000)
    assert u[2001] < 0.0
    naive = pack_pid(1.0, 50.0, 0.0, 0.01, limit=1.0, kff=0.0, channel=M_SPEED)
    naive.params[KAW] = 0.0
    assert run_law(naive, y, r=10.0)[2001] == 1.0  # the check can fail: without it, wound up


def test_position_pid_units_and_pi_rejects_kd(tmp_path):
    scenario = load_scenario("position-step")
    assert scenario.controllers.position.name == "pi"
    with pytest.raises(ValidationError):
        PositionPID(name="pi", kd=0.1)
    compiled = scenario.setup().position
    assert int(compiled.params[7]) == M_POSITION


def test_speed_pi_gives_the_designed_double_pole_response():
    """Small step on a rigid drive (no gap, no friction) against the linear loop in
    python-control: PI (Kp s + Ki)/s, current loop alpha_c/(s + alpha_c), inertia kt/(J s).

    With an ideal current loop the design places a double pole at -alpha_s; the linear model
    keeps the 500 Hz current loop, which is the only dynamics the design neglects.
    """
    scenario = load_scenario(
        "speed-step",
        settings=[
            "duration_s=0.1",
            "load.motor_torque_Nm=[]",
            'plant.friction.model="none"',
            "plant.backlash.width_mm=0",
            "plant.load.viscous_Ns_per_m=0",
            "plant.motor.viscous_Nms_per_rad=0",
            "plant.drivetrain.screw_efficiency=1",
            "controllers.speed.bandwidth_Hz=20",
            'reference.speed_rpm=[{type="step", final=10.0}]',
        ],
    )
    result = simulate(scenario.setup())
    plant = scenario.plant
    alpha_s, alpha_c = 2 * math.pi * 20, 2 * math.pi * 500
    j, kt = plant.total_inertia_kgm2, plant.torque_constant_Nm_per_A
    kp, ki = 2 * alpha_s * j / kt, alpha_s**2 * j / kt
    s = ct.tf("s")
    loop = (kp * s + ki) / s * alpha_c / (s + alpha_c) * kt / (j * s)
    t = result.t
    _, expected = ct.step_response(ct.feedback(loop, 1), t)
    y = result["motor_speed_rad_s"] / (10 * math.pi / 30)
    # what remains is sampling (1e-4 s hold, and the sampled current loop is not exactly the
    # first-order lag: see the next test) and the 300 Hz contact mode; measured 1.1 % of the step
    assert np.max(np.abs(y - expected)) < 0.02
    ideal = 1 - np.exp(-alpha_s * t) + alpha_s * t * np.exp(-alpha_s * t)
    assert np.max(np.abs(y - ideal)) < 0.06  # the double-pole design, current loop aside


def test_current_loop_matches_its_discrete_closed_loop():
    """Locked rotor (huge inertia): Lq diq/dt = uq - Rs iq, sampled PI with ZOH.

    The exact discrete model, written here independently of the package:
    i[k+1] = a i[k] + (1 - a) u[k] / Rs, a = exp(-Rs Ts / Lq); u[k] = Kp e[k] + I[k];
    I[k+1] = I[k] + Ts Ki e[k]. The engine's RK4 must reproduce it to round-off level, and the
    design makes it close to a first-order lag of bandwidth alpha_c = 2 pi 500 rad/s.
    """
    scenario = load_scenario(
        "speed-step",
        settings=[
            "duration_s=0.004",
            "solver.record_period_s=1e-4",
            "plant.motor.inertia_kgm2=1e6",
            'plant.friction.model="none"',
        ],
    )
    setup = scenario.setup()
    hold = pack_pid(0.0, 0.0, 0.0, 1e-3, limit=10.0, kff=10.0, channel=M_SPEED)
    hold.params[4] = 10.0  # lower limit = upper limit: a 10 A command from the first tick
    result = simulate(setup.with_(speed=hold))
    m = scenario.plant.motor
    ts, rs, lq = setup.sample_period_s, m.resistance_ohm, m.inductance_q_H
    alpha = 2 * math.pi * 500
    kp, ki = alpha * lq, alpha * rs
    a = math.exp(-rs * ts / lq)
    i, integ, expected = 0.0, 0.0, []
    for _ in range(len(result.t)):
        expected.append(i)
        e = 10.0 - i
        u = kp * e + integ
        integ += ts * ki * e
        i = a * i + (1 - a) * u / rs
    np.testing.assert_allclose(result["iq_A"], expected, atol=1e-6)
    lag = 10.0 * (1 - np.exp(-alpha * result.t))
    assert np.max(np.abs(result["iq_A"] - lag)) < 1.0  # sampled at alpha Ts = 0.31
    assert np.max(np.abs(result["id_A"])) < 1e-9


def test_the_derivative_on_the_error_kicks_at_a_set_point_step_and_the_measurements_does_not():
    """The PID law driven directly: measurement held at 0, a unit set-point step at the second
    sample. On the error, D jumps by Kd / (Tf + Ts) and decays by Tf / (Tf + Ts) a sample (the
    backward-Euler filter); on the measurement it stays 0 and the output is Kp e + I alone."""
    kp, ki, kd, tf, ts = 2.0, 0.0, 0.3, 2e-3, 1e-4
    outputs = {}
    for weight in (0.0, 1.0):
        compiled = pack_pid(kp, ki, kd, tf, 1e9, 0.0, M_POSITION, derivative_weight=weight)
        state, meas, out = compiled.state.copy(), np.zeros(N_MEAS), np.zeros(N_OUT)
        seen = []
        for r in (0.0, 1.0, 1.0, 1.0):
            ref = np.zeros(N_REF)
            ref[R_VALUE] = r
            pid(state, compiled.params, meas, ref, ts, out)
            seen.append(out[O_VALUE])
        outputs[weight] = np.array(seen)
    np.testing.assert_array_equal(outputs[0.0], [0.0, kp, kp, kp])
    kick = kd / (tf + ts) * (tf / (tf + ts)) ** np.arange(3)
    np.testing.assert_allclose(outputs[1.0], [0.0, *(kp + kick)], rtol=1e-12)


def test_on_a_step_at_the_first_sample_the_pid_variants_run_the_same_trace():
    """Why bench-step compares one PID and bench-sine two: bench-step's reference is a step at
    t = 0, so its rate is zero (no feed-forward) and the derivative state starts on the first
    sample's error (no kick). Feed-forward on, or the derivative on the error, changes the run
    by round-off alone (the same sums in another order: 1e-14 of the angle, where a kick or a
    feed-forward would move it by a count); on bench-sine's moving reference each changes the
    run."""
    traces = {}
    for name in ("bench-step", "bench-sine"):
        for variant in ("", "velocity_feedforward=true", 'derivative_on="error"'):
            settings = ["duration_s=0.3", 'controllers.cascade="pid"']
            if variant:
                settings.append(f"controllers.position.{variant}")
            sc = load_scenario(name, settings=settings)
            traces[name, variant] = simulate(sc.setup())["rudder_angle_rad"]
    plain = traces["bench-step", ""]
    round_off = 1e-12 * np.max(np.abs(plain))
    for variant in ("velocity_feedforward=true", 'derivative_on="error"'):
        np.testing.assert_allclose(traces["bench-step", variant], plain, rtol=0, atol=round_off)
    moving = traces["bench-sine", ""]
    for variant in ("velocity_feedforward=true", 'derivative_on="error"'):
        changed = np.max(np.abs(traces["bench-sine", variant] - moving))
        assert changed > 1e6 * round_off  # the setting bites


def test_a_bandwidth_beside_both_explicit_gains_is_refused_not_ignored():
    """A tuned PID set holds its gains; a --set of its bandwidth would be overridden by them,
    so it is refused in one line; replacing the whole table designs by bandwidth again."""
    with pytest.raises(InputError, match="bandwidth_Hz and the gains kp_A_s_per_rad"):
        load_scenario("bench-step", label="PID", settings=["controllers.speed.bandwidth_Hz=50"])
    redesigned = load_scenario(
        "bench-step", label="PID", settings=["controllers.speed={name = 'pi', bandwidth_Hz = 50}"]
    )
    assert redesigned.controllers.speed.kp_A_s_per_rad is None
    assert redesigned.controllers.speed.bandwidth_Hz == 50
