"""The rudder shaft's torsion: rocker arm and inertia disk on a torsion spring
(emasim.plant.elements.shaft).

Checked against closed forms, on sea805-stand's lumped stage (rocker angle theta_r = x_L / r,
r the arm) made conservative (no friction, no motor damping, lossless gearing, no contact
damping, no load damping), with the rocker side's inertia J_r = M_L r^2 where M_L is the rod
plus the load section's rudder inertia through the arm (the disk is not in it):

* rod free inside a 10 mm gap (the motor never touches it): the free two-mass mode, omega^2
  = k_t (1/J_d + 1/J_r), started with the centre of inertia at 0 (J_d theta_d = -J_r theta_r)
  and at rest, gives theta_r, theta_d and the torque sensor's k_t (theta_r - theta_d) as
  A cos(omega t); with shaft damping c_t the twist is the closed-form damped oscillator;
* rod held (locked rotor, gap width 0 at 1e8 N/m): the disk rings at the lower root of the
  chain ground -K_b r^2- J_r -k_t- J_d (exactly), close to sqrt(k_t / J_d), and the rocker
  barely moves;
* a constant rudder load T0 on the free stage: the angular momentum J_r omega_r + J_d omega_d
  falls as -T0 t (the load acts on the disk, the shaft's torque is internal), and the shaft
  torque is T0 J_r / (J_r + J_d) (1 - cos omega t);
* on the rhs: J_d domega_d/dt = T_shaft - T_load and M_L r dv_L/dt = -T_shaft, with T_shaft =
  k_t (theta_r - theta_d) + c_t (omega_r - omega_d) also the shaft_torque_Nm output.

Tolerance of the trajectories, TOL = 1e-6 of the amplitude: RK4's phase error, t omega
(omega h)^4 / 120, is below 1e-10 here, and the locked rotor's finite mass at the nut
(J / K^2 = 6e11 kg) shifts the held-rod mode by ~1e-10 (measured errors: 7e-12 to 2e-11
with the rod free, 4e-10 with it held). A wrong inertia, stiffness, arm or sign changes the
frequency by percents and the trajectory by O(1).
"""

import math

import numpy as np
import pytest
from helpers import conservative_stand, integrate_plant, relative_error

from emasim.plant import actuator as A
from emasim.plant.elements.linkage import N_HINGES
from emasim.plant.elements.shaft import ShaftParams
from emasim.signals import ZERO, Constant, encode

K_SHAFT = 2.0e4  # N m/rad: the bench's shaft and torque sensor
J_DISK = 1.45  # kg m^2: the bench's inertia disk
J_ROCKER = 0.05  # kg m^2: the rudder stage less the disk (the rocker arm's side)
K_GAP = 1.0e8  # N/m
LOCKED = 1.0e6  # kg m^2: a locked rotor
THETA = 1e-3  # rad: the rocker's amplitude (0.24 mm of rod, well inside the 5 mm half-gap)
H = 1e-5  # s: omega h <= 0.051 for every mode here (the held rocker's, 5.1e3 rad/s)
TOL = 1e-6  # of the amplitude (module docstring)


def shaft_plant(width_mm=10.0, locked=False, shaft_damping=0.0):
    """sea805-stand made conservative (module docstring) with the rudder shaft's torsion;
    ``locked`` locks the rotor."""
    plant = conservative_stand(width_mm, K_GAP)
    if locked:
        plant.motor.inertia_kgm2 = LOCKED
    plant.load.rudder_inertia_kgm2 = J_ROCKER
    plant.rudder_shaft = ShaftParams(
        stiffness_Nm_per_rad=K_SHAFT, damping_Nms_per_rad=shaft_damping, disk_inertia_kgm2=J_DISK
    )
    return plant


def arm(plant) -> float:
    """The lumped stage's arm r (m)."""
    return plant.load.rudder_arm_mm * 1e-3


def rod_mass(plant) -> float:
    """M_L: the rod plus the rocker side's inertia through the arm (kg); no disk."""
    return plant.load.rod_mass_kg + J_ROCKER / arm(plant) ** 2


def rocker_inertia(plant) -> float:
    """J_r = M_L r^2 (kg m^2): everything that turns rigidly with the rocker arm."""
    return rod_mass(plant) * arm(plant) ** 2


def free_start(plant, theta_r):
    """At rest, the rocker at theta_r and the disk where the centre of inertia stays at 0."""
    x = plant.initial_state()
    x[A.X_XL] = theta_r * arm(plant)
    x[A.X_DISK] = -rocker_inertia(plant) * theta_r / J_DISK
    return x


def run(plant, x0, duration_s, rudder_load=ZERO, h=H):
    """Integrate the plant from x0; returns (t, states)."""
    return integrate_plant(plant, x0, duration_s, h, rudder_load)


def angles(plant, states):
    """Columns theta_r = x_L / r and theta_d (rad)."""
    return np.column_stack((states[:, A.X_XL] / arm(plant), states[:, A.X_DISK]))


def sensor_torques(plant, states):
    """The torque sensor's reading, shaft_torque_of, along a trajectory (N m)."""
    p = plant.pack()
    return np.array([A.output("shaft_torque_Nm")(x, p) for x in states])


def assert_no_contact(plant, states):
    """The motor never moved and the gap never closed: the stage was free."""
    p = plant.pack()
    assert np.all(states[:, [A.X_THETA, A.X_WM]] == 0.0)
    assert all(A.drivetrain_force(x, p) == 0.0 for x in states)


def test_the_free_stage_rings_in_the_two_mass_torsion_mode():
    """omega^2 = k_t (1/J_d + 1/(M_L r^2)); the sensor reads k_t (theta_r0 - theta_d0) cos."""
    plant = shaft_plant()
    j_r = rocker_inertia(plant)
    omega = math.sqrt(K_SHAFT * (1.0 / J_DISK + 1.0 / j_r))
    x0 = free_start(plant, THETA)
    t, states = run(plant, x0, duration_s=4 * 2 * math.pi / omega)
    shape = np.array([THETA, x0[A.X_DISK]])
    wave = np.cos(omega * t)
    assert relative_error(angles(plant, states), np.outer(wave, shape)) < TOL
    twist = K_SHAFT * (shape[0] - shape[1])
    assert relative_error(sensor_torques(plant, states), twist * wave) < TOL
    assert_no_contact(plant, states)
    with_disk_at_rod = math.sqrt(K_SHAFT / J_DISK)  # the rocker side's inertia matters
    assert omega / with_disk_at_rod > 2.0


def test_the_shaft_damping_gives_the_closed_form_damped_twist():
    """The twist q = theta_r - theta_d of the free stage obeys J q'' + c_t q' + k_t q = 0,
    J = J_r J_d / (J_r + J_d), while the centre of inertia stays at 0: theta_r = q J_d /
    (J_r + J_d), theta_d = -q J_r / (J_r + J_d). zeta = 0.05 of that mode."""
    zeta = 0.05
    probe = shaft_plant()
    j_r = rocker_inertia(probe)
    j_eff = j_r * J_DISK / (j_r + J_DISK)
    plant = shaft_plant(shaft_damping=2.0 * zeta * math.sqrt(K_SHAFT * j_eff))
    omega = math.sqrt(K_SHAFT / j_eff)
    x0 = free_start(plant, THETA)
    t, states = run(plant, x0, duration_s=4 * 2 * math.pi / omega)
    q0 = THETA - x0[A.X_DISK]
    w_d = omega * math.sqrt(1.0 - zeta**2)
    q = (
        q0
        * np.exp(-zeta * omega * t)
        * (np.cos(w_d * t) + zeta / math.sqrt(1.0 - zeta**2) * np.sin(w_d * t))
    )
    expected = np.outer(q, [J_DISK / (j_r + J_DISK), -j_r / (j_r + J_DISK)])
    assert relative_error(angles(plant, states), expected) < TOL
    assert_no_contact(plant, states)
    assert abs(q[-1]) < 0.5 * q0  # it did decay: the damper acts


def test_with_the_rod_held_the_disk_rings_at_sqrt_kt_over_jd():
    """The rod on the locked nut through the stiff gap: the chain ground -K_b r^2- J_r -k_t-
    J_d. Started on its lower eigenvector, theta_r and theta_d stay A cos(omega_1 t); omega_1
    is within 0.5 % of sqrt(k_t / J_d) and the rocker moves < 1 % of the disk."""
    plant = shaft_plant(width_mm=0.0, locked=True)
    j_r, r = rocker_inertia(plant), arm(plant)
    stiffness = np.array([[K_GAP * r**2 + K_SHAFT, -K_SHAFT], [-K_SHAFT, K_SHAFT]])
    scale = np.diag(1.0 / np.sqrt([j_r, J_DISK]))
    squared, vectors = np.linalg.eigh(scale @ stiffness @ scale)
    omega = math.sqrt(squared[0])
    shape = scale @ vectors[:, 0]
    shape *= THETA / shape[1]  # the disk's amplitude THETA
    x0 = plant.initial_state()
    x0[A.X_XL], x0[A.X_DISK] = shape[0] * r, shape[1]
    t, states = run(plant, x0, duration_s=3 * 2 * math.pi / omega)
    simulated = angles(plant, states)
    assert relative_error(simulated, np.outer(np.cos(omega * t), shape)) < TOL
    assert omega == pytest.approx(math.sqrt(K_SHAFT / J_DISK), rel=5e-3)
    assert np.max(np.abs(simulated[:, 0])) < 1e-2 * np.max(np.abs(simulated[:, 1]))


def test_a_constant_rudder_load_turns_the_stage_through_the_shaft():
    """T0 on the disk of the free stage from rest: d/dt (J_r omega_r + J_d omega_d) = -T0
    (RK4 keeps a linear invariant to round-off), and the twist rises to the torque that
    accelerates the rocker side with the disk, T_shaft = T0 J_r / (J_r + J_d) (1 - cos w t)."""
    load = 10.0  # N m, opposing positive deflection
    plant = shaft_plant()
    j_r = rocker_inertia(plant)
    omega = math.sqrt(K_SHAFT * (1.0 / J_DISK + 1.0 / j_r))
    t, states = run(
        plant, plant.initial_state(), duration_s=0.05, rudder_load=encode([Constant(value=load)])
    )
    momentum = j_r * states[:, A.X_VL] / arm(plant) + J_DISK * states[:, A.X_DISK_RATE]
    assert np.max(np.abs(momentum + load * t)) < 1e-12 * load * t[-1]
    steady = load * j_r / (j_r + J_DISK)
    expected = steady * (1.0 - np.cos(omega * t))
    assert relative_error(sensor_torques(plant, states), expected) < TOL
    assert_no_contact(plant, states)
    assert states[-1, A.X_XL] < -1e-3  # the stage turned against the load, by over 1 mm


def test_the_disk_and_the_rocker_feel_the_shaft_torque_in_the_rhs():
    """J_d domega_d/dt = T_shaft - T_load and M_L r dv_L/dt = -T_shaft (gap open), with
    T_shaft = k_t (theta_r - theta_d) + c_t (omega_r - omega_d), also the trace's output.
    A few states of both twist signs and both rate signs; round-off tolerance."""
    damping = 30.0  # N m s/rad
    load = -7.0  # N m
    plant = shaft_plant(shaft_damping=damping)
    p, r = plant.pack(), arm(plant)
    dx, hinges, out = np.zeros(A.N_STATE), np.zeros((N_HINGES, 2)), np.zeros(A.N_OUTPUTS)
    for x_l, v_l, theta_d, omega_d in [
        (1e-3, 0.02, 2e-3, -0.5),
        (-2e-3, -0.1, 1e-3, 0.3),
        (4e-4, 0.3, -5e-3, 2.0),
    ]:
        x = plant.initial_state()
        x[A.X_XL], x[A.X_VL], x[A.X_DISK], x[A.X_DISK_RATE] = x_l, v_l, theta_d, omega_d
        torque = K_SHAFT * (x_l / r - theta_d) + damping * (v_l / r - omega_d)
        A.rhs(x, 0.0, 0.0, 0.0, 0.0, load, p, dx, hinges)
        A.plant_outputs(x, p, out)
        assert A.drivetrain_force(x, p) == 0.0
        assert dx[A.X_DISK] == omega_d
        assert J_DISK * dx[A.X_DISK_RATE] == pytest.approx(torque - load, rel=1e-12)
        assert rod_mass(plant) * r * dx[A.X_VL] == pytest.approx(-torque, rel=1e-12)
        assert out[A.PLANT.outputs.index("shaft_torque_Nm")] == pytest.approx(torque, rel=1e-14)
        assert A.output("shaft_torque_Nm")(x, p) == pytest.approx(torque, rel=1e-14)
