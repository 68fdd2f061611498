"""End stops (emasim.plant.elements.stops): the rod's at both ends of the stroke, the rudder's
limits.

Every check is against a reference built here, apart from the plant assembly:

* the coefficient of restitution of a rod thrown onto its stop, against a tight solve_ivp of
  one mass on the same contact law (re-written below in numpy from the docstring of
  emasim.plant.elements.backlash);
* the static penetration F/k of a rod pushed onto its stop, and the rest angle
  theta_max + F r / k_r of a rudder pushed onto its stop (closed forms);
* the rudder stop's torque output against the law written out case by case;
* a run that stays inside the stroke is, to the bit, the run without the stops.

The motor is decoupled from the rod by a 10 mm backlash wherever the stop alone must act:
the nut starts centred in the gap and the tests check that the gap never closes.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from emasim.plant import actuator as A
from emasim.plant.elements.backlash import dead_zone_force
from emasim.plant.elements.stops import EndStopParams
from emasim.plant.presets import sea805
from emasim.scenarios.loader import load_scenario
from emasim.signals import ZERO, Constant, encode
from emasim.sim.core import new_workspace
from emasim.sim.engine import plant_step, simulate

K_STOP = 1.0e7  # N/m: the rod's stop in these tests (softer than the preset's, to resolve it)
ZETA = 0.1  # damping ratio of the stop on the load mass
WIDE_GAP_MM = 10.0  # backlash: the nut stays clear of the rod during the impact
FAR_RUDDER_LIMIT_DEG = 90.0  # beyond the +-30 deg that the stroke gives: never reached


def contact_law(dx, dv, half_gap, stiffness, damping):
    """The dead-zone law of emasim.plant.elements.backlash's docstring, in numpy: K (|dx| - b)
    beyond the gap, plus a damping c dv that acts only in contact and is limited to
    |c dv| <= |Fc|."""
    if dx > half_gap:
        spring = stiffness * (dx - half_gap)
    elif dx < -half_gap:
        spring = stiffness * (dx + half_gap)
    else:
        return 0.0
    bound = abs(spring)
    return spring + min(max(damping * dv, -bound), bound)


def stop_plant(
    stiffness=K_STOP, zeta=ZETA, rudder_limit_deg=FAR_RUDDER_LIMIT_DEG, rudder_k=1e6, rudder_c=0.0
):
    """sea805 (lumped rudder stage) without friction or load damping, a 10 mm backlash, and
    stops of the given stiffness, damped at ``zeta`` on the load mass M_L."""
    plant = sea805()
    plant.friction.model = "none"
    plant.backlash.width_mm = WIDE_GAP_MM
    plant.load.viscous_Ns_per_m = 0.0
    damping = 2.0 * zeta * math.sqrt(stiffness * plant.load_mass_kg)
    plant.end_stops = EndStopParams(
        stiffness_N_per_m=stiffness,
        damping_Ns_per_m=damping,
        rudder_limit_deg=rudder_limit_deg,
        rudder_stiffness_Nm_per_rad=rudder_k,
        rudder_damping_Nms_per_rad=rudder_c,
    )
    return plant, damping


def rod_state(plant, position_m, velocity_m_s):
    """The plant at rest but for the rod at ``position_m`` moving at ``velocity_m_s``, and the
    motor carrying the nut along with it, centred in the gap (K theta = x_L, K wm = v_L)."""
    x = plant.initial_state()
    k = plant.ratio_m_per_rad
    x[A.X_XL], x[A.X_VL] = position_m, velocity_m_s
    x[A.X_THETA], x[A.X_WM] = position_m / k, velocity_m_s / k
    return x


def nut_offset(plant, x):
    """|K theta - x_L| (m): the nut's distance from the centre of the gap."""
    return abs(plant.ratio_m_per_rad * x[A.X_THETA] - x[A.X_XL])


def settle(plant, x, rod_load, duration_s, h):
    """Advance x with plant_step (u = 0, the rod load ``rod_load``) for ``duration_s``;
    returns the largest nut offset seen."""
    p, work = plant.pack(), new_workspace()
    worst = 0.0
    for j in range(round(duration_s / h)):
        plant_step(j * h, x, 0.0, 0.0, p, ZERO, rod_load, ZERO, h, work)
        worst = max(worst, nut_offset(plant, x))
    return worst


def test_the_numpy_law_is_the_compiled_one():
    """The reference below integrates contact_law; it is the compiled dead_zone_force."""
    b, k, c = 0.125, K_STOP, 1e4
    for dx in (-0.1261, -0.1250001, -0.125, 0.0, 0.1249, 0.125, 0.12501, 0.126):
        for dv in (-3.0, -1e-3, 0.0, 2e-4, 0.5):
            assert dead_zone_force(dx, dv, b, k, c) == pytest.approx(
                contact_law(dx, dv, b, k, c), rel=1e-15, abs=1e-12
            )


def reference_restitution(mass, half, stiffness, damping, x0, v0):
    """e of one mass m x'' = -law(x, x') from (x0, v0) (solve_ivp, rtol 1e-12): the rebound
    speed once the mass is back inside the stop, over the impact speed."""

    def rates(t, y):
        return [y[1], -contact_law(y[0], y[1], half, stiffness, damping) / mass]

    def back_inside(t, y):
        return y[0] - (half - 0.1e-3)

    back_inside.terminal, back_inside.direction = True, -1
    sol = solve_ivp(
        rates, (0.0, 1.0), [x0, v0], method="DOP853", rtol=1e-12, atol=1e-15, events=back_inside
    )
    assert sol.status == 1  # it came back
    return -sol.y_events[0][0][1] / v0


def test_a_rod_thrown_onto_its_stop_rebounds_with_the_laws_restitution():
    """0.5 mm inside the upper stop at 0.05 m/s outward; u = 0, no loads. Plant's e (RK4 at
    h = 1 us, about 5400 steps over the 5.4 ms contact) against the one-mass solve_ivp."""
    plant, damping = stop_plant()
    half = 0.5 * plant.drivetrain.stroke_mm * 1e-3
    v_in = 0.05
    x = rod_state(plant, half - 0.5e-3, v_in)
    p, work, h = plant.pack(), new_workspace(), 1e-6
    assert p[A.P_HALF_STROKE] == half and p[A.P_K_STOP] == K_STOP and p[A.P_C_STOP] == damping
    deepest, worst_nut, j = 0.0, 0.0, 0
    outputs = np.empty(A.N_OUTPUTS)
    while not (deepest > 0.0 and x[A.X_XL] < half - 0.1e-3):
        plant_step(j * h, x, 0.0, 0.0, p, ZERO, ZERO, ZERO, h, work)
        j += 1
        deepest = max(deepest, x[A.X_XL] - half)
        worst_nut = max(worst_nut, nut_offset(plant, x))
        if j == 12_000:  # in contact (entered at 10 ms): the stop force output is the law's
            A.plant_outputs(x, p, outputs)
            law = -contact_law(x[A.X_XL], x[A.X_VL], half, K_STOP, damping)
            assert x[A.X_XL] > half and law != 0.0
            assert outputs[A.PLANT.outputs.index("end_stop_force_N")] == pytest.approx(
                law, rel=1e-12
            )
        assert j < 100_000
    e = -x[A.X_VL] / v_in
    assert worst_nut < 0.5 * WIDE_GAP_MM * 1e-3  # the gap never closed: the stop alone acted
    assert deepest == pytest.approx(v_in / math.sqrt(K_STOP / plant.load_mass_kg), rel=0.2)
    mass = plant.load_mass_kg
    expected = reference_restitution(mass, half, K_STOP, damping, half - 0.5e-3, v_in)
    # measured |e - expected| ~ 6e-9 (RK4's error over the contact's kinks at h = 1 us)
    assert e == pytest.approx(expected, abs=1e-6)
    # The unclamped Kelvin-Voigt contact would give exp(-zeta pi / sqrt(1 - zeta^2)) = 0.729;
    # the clamp (no pull, damping limited to the spring force) dissipates less: e = 0.759.
    kelvin_voigt = math.exp(-ZETA * math.pi / math.sqrt(1.0 - ZETA**2))
    assert e - kelvin_voigt > 0.02


@pytest.mark.parametrize("end", [+1, -1])
def test_a_rod_pushed_onto_its_stop_sinks_in_by_f_over_k(end):
    """A constant rod force drives the rod (at rest, on the stop) into it: penetration F/k.
    The rod load is positive against extension, so -F pushes onto the upper stop."""
    force = 2000.0  # N
    plant, _ = stop_plant(zeta=0.5)
    half = 0.5 * plant.drivetrain.stroke_mm * 1e-3
    x = rod_state(plant, end * half, 0.0)
    worst_nut = settle(plant, x, encode([Constant(value=-end * force)]), 0.3, 1e-5)
    assert worst_nut < 0.5 * WIDE_GAP_MM * 1e-3
    penetration = end * (x[A.X_XL] - half * end)
    assert penetration == pytest.approx(force / K_STOP, rel=1e-9)
    assert abs(x[A.X_VL]) < 1e-9
    outputs = np.empty(A.N_OUTPUTS)
    A.plant_outputs(x, plant.pack(), outputs)
    assert outputs[A.PLANT.outputs.index("end_stop_force_N")] == pytest.approx(
        -end * force, rel=1e-9
    )


RUDDER_LIMIT_DEG = 10.0  # inside the +-30 deg of the stroke: the rudder's stop acts first
K_RUDDER = 1.0e5  # N m/rad
C_RUDDER = 400.0  # N m s/rad: about half of critical on the 1.67 kg m^2 seen at the rudder


def test_the_rudder_stop_torque_is_the_law_beyond_the_limit():
    """O_RUDDER_STOP at states of the lumped stage (theta = x_L / arm), each case of the
    law written out: zero inside; spring plus damping; the damping clamped to the spring
    (never pulling); the same mirrored at the lower limit."""
    plant, _ = stop_plant(rudder_limit_deg=RUDDER_LIMIT_DEG, rudder_k=K_RUDDER, rudder_c=C_RUDDER)
    p = plant.pack()
    arm = plant.load.rudder_arm_mm * 1e-3
    limit = math.radians(RUDDER_LIMIT_DEG)
    over = math.radians(2.0)  # 2 deg beyond the limit
    spring = K_RUDDER * over
    cases = [  # (theta, omega, torque on the rudder)
        (math.radians(9.9), 5.0, 0.0),
        (-math.radians(9.9), -5.0, 0.0),
        (limit + over, 0.0, -spring),
        (limit + over, 1.0, -(spring + C_RUDDER * 1.0)),  # c w = 400 < spring = 3491
        (limit + over, -1.0, -(spring - C_RUDDER * 1.0)),
        (limit + over, 50.0, -2.0 * spring),  # c w = 2e4 > spring: clamped
        (limit + over, -50.0, 0.0),  # leaving fast: the damping cancels the spring, no pull
        (-limit - over, 0.0, spring),
        (-limit - over, -1.0, spring + C_RUDDER * 1.0),
        (-limit - over, 50.0, 0.0),
    ]
    outputs = np.empty(A.N_OUTPUTS)
    for theta, omega, expected in cases:
        x = rod_state(plant, theta * arm, omega * arm)
        A.plant_outputs(x, p, outputs)
        assert outputs[A.PLANT.outputs.index("rudder_stop_torque_Nm")] == pytest.approx(
            expected, rel=1e-9, abs=1e-9
        )
        assert A.output("rudder_stop_torque_Nm")(x, p) == pytest.approx(
            expected, rel=1e-9, abs=1e-9
        )
        assert (
            outputs[A.PLANT.outputs.index("end_stop_force_N")] == 0.0
        )  # the rod is well inside its stroke


def test_a_rudder_pushed_onto_its_stop_rests_at_the_closed_form_angle():
    """A constant rod force F (extending) on the lumped stage, the motor decoupled by the
    10 mm gap: the rudder comes to rest at theta_max + F arm / k_r, held by its stop alone."""
    force = 2000.0  # N
    plant, _ = stop_plant(rudder_limit_deg=RUDDER_LIMIT_DEG, rudder_k=K_RUDDER, rudder_c=C_RUDDER)
    arm = plant.load.rudder_arm_mm * 1e-3
    limit = math.radians(RUDDER_LIMIT_DEG)
    x = rod_state(plant, limit * arm, 0.0)
    worst_nut = settle(plant, x, encode([Constant(value=-force)]), 0.3, 1e-5)
    assert worst_nut < 0.5 * WIDE_GAP_MM * 1e-3
    theta = x[A.X_XL] / arm
    expected = limit + force * arm / K_RUDDER
    assert theta == pytest.approx(expected, rel=1e-10)
    assert theta - limit > 4e-3  # it did sink in (4.8 mrad)
    outputs = np.empty(A.N_OUTPUTS)
    A.plant_outputs(x, plant.pack(), outputs)
    assert outputs[A.PLANT.outputs.index("rudder_stop_torque_Nm")] == pytest.approx(
        -force * arm, rel=1e-9
    )
    assert outputs[A.PLANT.outputs.index("end_stop_force_N")] == 0.0
    assert outputs[A.PLANT.outputs.index("rudder_angle_rad")] == theta


def test_a_run_inside_the_stroke_is_the_run_without_stops_to_the_bit():
    with_stops = load_scenario(
        "position-step", controllers=["position=pid"], settings=["duration_s=0.3"]
    )
    assert with_stops.plant.end_stops is not None
    without = with_stops.model_copy(
        update={"plant": with_stops.plant.model_copy(update={"end_stops": None})}
    )
    a, b = simulate(with_stops.setup()), simulate(without.setup())
    position = a["actuator_position_m"]
    half = 0.5 * with_stops.plant.drivetrain.stroke_mm * 1e-3
    assert np.max(np.abs(position)) < half  # inside the stroke throughout ...
    assert np.max(position) > 0.02  # ... after a real move
    rudder_limit = math.radians(with_stops.plant.end_stops.rudder_limit_deg)
    assert np.max(np.abs(a["rudder_angle_rad"])) < rudder_limit
    common = [name for name in a.columns if name in b.columns]
    assert len(common) > 20
    for name in common:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    assert set(a.columns) - set(b.columns) == {"end_stop_force_N", "rudder_stop_torque_Nm"}
    assert np.all(a["end_stop_force_N"] == 0.0)
    assert np.all(a["rudder_stop_torque_Nm"] == 0.0)
