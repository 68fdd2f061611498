"""The bench's load motor (emasim.plant.elements.load_motor): a first-order torque servo on the
rudder.

    dT/dt = (clamp(T(t) + T_pre + k_aero theta, -T_max, T_max) - T) / tau,  tau = 1/(2 pi f_b)

Checked against closed forms of that law: the step response T_cmd (1 - exp(-t/tau)) through
the engine's trace, the standing preload from t = 0 with no transient, the rating's clamp,
and the settled hinge spring k_aero theta. The rotor is locked (inertia 1e6 kg m^2) so the
rudder is held by the drive while the load motor pushes on it; with k_aero = 0 the law does
not read the angle at all.
"""

import math

import numpy as np
import pytest

from emasim.plant import actuator as A
from emasim.plant.elements.linkage import N_HINGES
from emasim.plant.elements.load_motor import LoadMotorParams
from emasim.plant.elements.shaft import ShaftParams
from emasim.plant.presets import sea805
from emasim.scenarios.loader import load_scenario
from emasim.signals import ZERO, Constant, encode
from emasim.sim.core import new_workspace
from emasim.sim.engine import plant_step, simulate

BANDWIDTH_HZ = 50.0
TAU = 1.0 / (2.0 * math.pi * BANDWIDTH_HZ)  # 3.18 ms
MAX_TORQUE = 500.0  # N m
LOCKED = 1.0e6  # kg m^2: a locked rotor


def locked_plant(spring_Nm_per_deg=0.0, preload_Nm=0.0, backlash_mm=0.1):
    """sea805 (lumped rudder), no friction, the rotor locked, and the load motor."""
    plant = sea805()
    plant.friction.model = "none"
    plant.motor.inertia_kgm2 = LOCKED
    plant.backlash.width_mm = backlash_mm
    plant.load_motor = LoadMotorParams(
        inertia_kgm2=0.01,
        bandwidth_Hz=BANDWIDTH_HZ,
        max_torque_Nm=MAX_TORQUE,
        spring_Nm_per_deg=spring_Nm_per_deg,
        preload_Nm=preload_Nm,
    )
    return plant


def torque_history(plant, x, rudder_load, duration_s, h=1e-5):
    """(times after each sub-step, X_TLM after each) of plant_step from x with u = 0."""
    p, work = plant.pack(), new_workspace()
    n = round(duration_s / h)
    torque = np.empty(n)
    for j in range(n):
        plant_step(j * h, x, 0.0, 0.0, p, ZERO, ZERO, rudder_load, h, work)
        torque[j] = x[A.X_TLM]
    return (np.arange(n) + 1) * h, torque


def locked_scenario(*settings):
    """speed-step with the locked rotor and the load motor, a zero speed reference and no
    motor load: the drive holds the rod while the load motor pushes on the rudder."""
    return load_scenario(
        "speed-step",
        controllers=["speed=pi"],
        settings=[
            f"plant.motor.inertia_kgm2={LOCKED}",
            "plant.load_motor.inertia_kgm2=0.01",
            f"plant.load_motor.bandwidth_Hz={BANDWIDTH_HZ}",
            f"plant.load_motor.max_torque_Nm={MAX_TORQUE}",
            'reference.speed_rpm=[{type="constant", value=0.0}]',
            "load.motor_torque_Nm=[]",
            *settings,
        ],
    )


def test_the_time_constant_is_one_over_two_pi_fb():
    lm = locked_plant().load_motor
    assert lm.time_constant_s == pytest.approx(TAU, rel=1e-15)
    assert locked_plant().pack()[A.P_LM_TAU] == lm.time_constant_s


def test_a_torque_step_is_a_first_order_response_in_the_trace():
    """100 N m stepped at 10 ms: the trace's load_motor_torque_Nm is 100 (1 - exp(-(t -
    0.01)/tau)) at every recorded tick (RK4 at h = 1e-5 s, h / tau = 3e-3: its error, about
    (h/tau)^5 / 120 a step, is far below the 1e-9 of 100 N m allowed)."""
    scenario = locked_scenario(
        "duration_s=0.05",
        'load.rudder_torque_Nm=[{type="step", time_s=0.01, final=100.0}]',
    )
    assert scenario.plant.load_motor.spring_Nm_per_deg == 0.0  # the law ignores the angle
    result = simulate(scenario.setup())
    t, torque = result.t, result["load_motor_torque_Nm"]
    expected = np.where(t <= 0.01, 0.0, 100.0 * -np.expm1(-(t - 0.01) / TAU))
    assert len(t) == 500
    assert np.max(np.abs(torque - expected)) < 1e-7  # N m; measured about 1e-11
    assert torque[-1] > 99.9  # the step went through (12 tau)
    assert np.array_equal(result["rudder_load_Nm"], np.where(t >= 0.01, 100.0, 0.0))


def test_the_preload_stands_from_t0_with_no_transient_and_acts_on_the_rudder():
    """The state starts at T_pre and stays there (no profile, k_aero = 0) bit for bit; the
    drive holds the rudder against it: the nut pushes the rod with T_pre / arm (positive:
    the load motor opposes positive deflection)."""
    preload = 200.0
    plant = locked_plant(preload_Nm=preload)
    assert plant.initial_state()[A.X_TLM] == preload
    scenario = locked_scenario("duration_s=0.3", f"plant.load_motor.preload_Nm={preload}")
    result = simulate(scenario.setup())
    assert np.all(result["load_motor_torque_Nm"] == preload)
    late = result.t > 0.2  # the rod has settled on the nut (contact decay time 5 ms)
    force = result["drivetrain_force_N"][late]
    arm = scenario.plant.load.rudder_arm_mm * 1e-3
    assert np.max(np.abs(force / (preload / arm) - 1.0)) < 1e-6


@pytest.mark.parametrize(
    ("profile", "preload", "settled"),
    [(800.0, 0.0, MAX_TORQUE), (-800.0, 0.0, -MAX_TORQUE), (400.0, 300.0, MAX_TORQUE)],
)
def test_a_command_beyond_the_rating_settles_at_the_rating(profile, preload, settled):
    """T_cmd beyond T_max: the torque goes first order from T_pre to +-T_max, never beyond."""
    plant = locked_plant(preload_Nm=preload)
    x = plant.initial_state()
    t, torque = torque_history(plant, x, encode([Constant(value=profile)]), 0.05)
    expected = settled + (preload - settled) * np.exp(-t / TAU)
    assert np.max(np.abs(torque - expected)) < 1e-9 * MAX_TORQUE
    assert np.max(np.abs(torque)) <= MAX_TORQUE
    assert torque[-1] == pytest.approx(settled, rel=1e-6)


def test_the_hinge_spring_settles_at_k_aero_times_the_rudder_angle():
    """k_aero = 5 N m/deg, the rudder held at 10 deg by the locked drive (no backlash): the
    torque settles at k_aero * degrees(theta) at the rudder angle theta where it rests, and
    that angle is where the contact's spring k_b balances it, theta0 - T / (k_b arm^2)."""
    spring = 5.0  # N m/deg
    plant = locked_plant(spring_Nm_per_deg=spring, backlash_mm=0.0)
    arm = plant.load.rudder_arm_mm * 1e-3
    k = plant.ratio_m_per_rad
    theta0 = math.radians(10.0)
    x = plant.initial_state()
    x[A.X_XL] = theta0 * arm
    x[A.X_THETA] = x[A.X_XL] / k  # the nut there: the contact unloaded at the start
    torque_history(plant, x, ZERO, 0.2)
    theta = x[A.X_XL] / arm
    assert x[A.X_TLM] == pytest.approx(spring * math.degrees(theta), rel=1e-9)
    per_rad = spring * 180.0 / math.pi
    compliance = 1.0 / (plant.backlash.stiffness_N_per_m * arm**2)  # rad per N m at the rudder
    nut_theta = k * x[A.X_THETA] / arm  # the locked nut's rudder angle (moves by 1e-11)
    assert x[A.X_TLM] == pytest.approx(per_rad * nut_theta / (1.0 + per_rad * compliance), rel=1e-9)
    assert x[A.X_TLM] == pytest.approx(50.0, rel=1e-3)


def test_the_spring_reads_the_disk_behind_the_shaft_and_the_rudder_without():
    """dT/dt from the plant's rhs at a state where the rocker arm and the disk differ: the law
    with theta the disk's angle when the shaft's torsion carries it, the rudder's otherwise;
    and the rotor's inertia joins the disk, or the rudder."""
    spring, preload, profile, torque = 2.0, 30.0, 40.0, 10.0
    lumped = locked_plant(spring_Nm_per_deg=spring, preload_Nm=preload)
    shafted = lumped.model_copy(
        update={
            "rudder_shaft": ShaftParams(
                stiffness_Nm_per_rad=2e4, damping_Nms_per_rad=10.0, disk_inertia_kgm2=1.0
            )
        }
    )
    arm = lumped.load.rudder_arm_mm * 1e-3
    rocker, disk = math.radians(12.0), math.radians(7.0)
    for plant, angle in ((lumped, rocker), (shafted, disk)):
        p = plant.pack()
        x = plant.initial_state()
        x[A.X_XL], x[A.X_DISK], x[A.X_TLM] = rocker * arm, disk, torque
        dx = np.zeros(A.N_STATE)
        A.rhs(x, 0.0, 0.0, 0.0, 0.0, profile, p, dx, np.zeros((N_HINGES, 2)))
        command = profile + preload + spring * math.degrees(angle)
        assert dx[A.X_TLM] == pytest.approx((command - torque) / TAU, rel=1e-12)
    assert shafted.pack()[A.P_JD] == 1.0 + 0.01
    rudder = lumped.load.rudder_inertia_kgm2 + 0.01
    assert lumped.pack()[A.P_ML] == pytest.approx(lumped.load.rod_mass_kg + rudder / arm**2)
