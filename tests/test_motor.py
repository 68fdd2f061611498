"""Validation of the PMSM model on the compiled engine: steady-state current under load, the
energy balance of the electrical and the mechanical side, and the inverter's voltage and
current limits."""

import dataclasses
import math

import numpy as np
import pytest
from helpers import RPM, facts_of, frictionless_sea805, speed_setup, step_signal
from scipy.integrate import solve_ivp

from emasim.plant import actuator as A
from emasim.plant.elements.motor import current_rates, inverter_current_rates
from emasim.sim.engine import simulate

# --- 1. steady iq under load -------------------------------------------------------------------

SPEED_RPM = 500.0
LOAD_STEP_S = 0.2
STEADY_CASES = {
    # B, load viscous c_L, efficiency, half gap (m), motor load TL (N m), rod force F_L (N).
    # With c_L = 0 the rod would rattle in an open gap for ever (each impact only scales the
    # relative speed by the restitution, and the flights grow longer), so that case closes it.
    "motor viscous only": (None, 0.0, 0.9, 0.0, 10.0, 0.0),
    "reflected drag, motor drives": (0.05, 2.0e4, 0.9, None, 10.0, 0.0),
    "rod force back-drives": (0.05, 2.0e4, 0.9, None, -5.0, -3000.0),
}


@pytest.mark.parametrize("case", STEADY_CASES)
def test_steady_iq_balances_the_load(case):
    b_visc, c_load, eta, half_gap, t_load, f_rod = STEADY_CASES[case]
    overrides = dict(CL=c_load, ETA=eta)
    if b_visc is not None:
        overrides["B"] = b_visc
    if half_gap is not None:
        overrides["HALF_GAP"] = half_gap
    plant, p = frictionless_sea805(**overrides)
    setup = speed_setup(
        p,
        facts_of(plant),
        ts=1e-4,
        substeps=4,
        duration_s=0.6,
        speed_rpm=SPEED_RPM,
        motor_load=step_signal(LOAD_STEP_S, t_load),
        rod_load=step_signal(LOAD_STEP_S, f_rod),
    )
    r = simulate(setup)
    steady = r["t_s"] > 0.55

    # expected, from the parameters alone: the rod moves at K w, so the nut pushes it with
    # F = F_L + c_L K w; through the screw that costs K F / eta while the motor drives the
    # load (K F w > 0) and K F eta while the load back-drives it.
    m = plant.motor
    w = SPEED_RPM * RPM
    b_visc = m.viscous_Nms_per_rad if b_visc is None else b_visc
    ratio = plant.ratio_m_per_rad
    kt = 1.5 * m.pole_pairs * m.flux_linkage_Wb
    force = f_rod + c_load * ratio * w
    reflected = ratio * force / eta if ratio * force * w > 0 else ratio * force * eta
    iq_expected = (t_load + b_visc * w + reflected) / kt

    assert abs(iq_expected) > 1.0  # the load is felt
    # in a true steady state every input is constant over a tick and the ZOH/RK4 path is exact,
    # so only the decay of the transients is left (slowest pole ~ 300 1/s, 0.35 s after the
    # load step): the tolerance is rounding-level, far below any of the three terms.
    np.testing.assert_allclose(r["motor_speed_rad_s"][steady], w, rtol=0, atol=1e-8)
    np.testing.assert_allclose(r["iq_A"][steady], iq_expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r["id_A"][steady], 0.0, atol=1e-8)
    np.testing.assert_allclose(r["drivetrain_force_N"][steady], force, rtol=1e-8, atol=1e-6)


# --- 2. energy balance ---------------------------------------------------------------------------

TS_FINE = 2e-5  # s: control tick = trace spacing (record_every=1), one RK4 step per tick
T_END = 0.2
TL_STEP = (0.1, 10.0)  # motor load torque step: (time s, N m)
FL_STEP = (0.15, 2000.0)  # rod force step: (time s, N)


def trapezoid_per_tick(f, ts):
    """Trapezoid integral of the sampled f over each tick [t_k, t_k+1]."""
    return 0.5 * (f[:-1] + f[1:]) * ts


def quadrature_error_bound(f, ts):
    """Estimate of the trapezoid rule's error from the data: sum of ts/12 |second difference|."""
    return ts / 12.0 * np.abs(f[2:] - 2.0 * f[1:-1] + f[:-2]).sum()


@pytest.fixture(scope="module")
def energy_run():
    """A speed step to 1000 rpm (current limit reached), a load torque step and a rod force
    step, through the open backlash with its damped contact; friction none, efficiency 1."""
    plant, p = frictionless_sea805(ETA=1.0)
    setup = speed_setup(
        p,
        facts_of(plant),
        ts=TS_FINE,
        substeps=1,
        duration_s=T_END,
        speed_rpm=1000.0,
        motor_load=step_signal(*TL_STEP),
        rod_load=step_signal(*FL_STEP),
    )
    return plant, p, simulate(setup)


def test_electrical_energy_balance(energy_run):
    """Input = copper losses + change of magnetic energy + mechanical work Te wm."""
    plant, _, r = energy_run
    m = plant.motor
    rs, ld, lq, psi, n_p = (
        m.resistance_ohm,
        m.inductance_d_H,
        m.inductance_q_H,
        m.flux_linkage_Wb,
        m.pole_pairs,
    )
    i_d, i_q, w = r["id_A"], r["iq_A"], r["motor_speed_rad_s"]
    # the voltages of row k are held over tick k; the last row's tick has no end sample
    u_d, u_q = r["ud_V"][:-1], r["uq_V"][:-1]
    torque = 1.5 * n_p * (psi * i_q + (ld - lq) * i_d * i_q)
    np.testing.assert_allclose(r["torque_Nm"], torque, rtol=1e-12, atol=1e-12)

    e_in = np.sum(
        1.5 * (u_d * trapezoid_per_tick(i_d, TS_FINE) + u_q * trapezoid_per_tick(i_q, TS_FINE))
    )
    copper = np.sum(trapezoid_per_tick(1.5 * rs * (i_d**2 + i_q**2), TS_FINE))
    magnetic = 0.75 * (ld * i_d**2 + lq * i_q**2)
    d_magnetic = magnetic[-1] - magnetic[0]
    mechanical = np.sum(trapezoid_per_tick(torque * w, TS_FINE))
    residual = e_in - copper - d_magnetic - mechanical

    # tolerance: the trapezoid rule's error, estimated from the traces themselves (voltages
    # are exact per tick; currents, losses and power are sampled every Ts)
    bound = (
        1.5 * np.abs(u_d).max() * quadrature_error_bound(i_d, TS_FINE)
        + 1.5 * np.abs(u_q).max() * quadrature_error_bound(i_q, TS_FINE)
        + quadrature_error_bound(1.5 * rs * (i_d**2 + i_q**2), TS_FINE)
        + quadrature_error_bound(torque * w, TS_FINE)
    )
    # the bound is tight enough that dropping any term of the balance would fail
    assert bound < 0.1 * min(copper, abs(d_magnetic), mechanical)
    assert abs(residual) < 2.0 * bound, (residual, bound, e_in)


def test_mechanical_energy_balance(energy_run):
    """Te wm = d/dt kinetic + dissipation (B, load viscous, contact damping) + load work
    + d/dt contact spring energy."""
    plant, p, r = energy_run
    m, bl = plant.motor, plant.backlash
    ratio = plant.ratio_m_per_rad
    mass = plant.load_mass_kg
    inertia, b_visc, c_load = m.inertia_kgm2, m.viscous_Nms_per_rad, plant.load.viscous_Ns_per_m
    half_gap, k_contact = 0.5 * bl.width_mm * 1e-3, bl.stiffness_N_per_m
    c_contact = p[A.P_CB]  # from the damping ratio on the reduced mass: checked below
    m1 = inertia / ratio**2
    assert c_contact == pytest.approx(
        2.0 * bl.damping_ratio * math.sqrt(k_contact * m1 * mass / (m1 + mass)), rel=1e-12
    )

    t, w, v = r["t_s"], r["motor_speed_rad_s"], r["actuator_velocity_m_s"]
    torque = r["torque_Nm"]  # checked against the currents in the electrical test
    dx = ratio * r["motor_angle_rad"] - r["actuator_position_m"]
    dv = ratio * w - v
    penetration = np.maximum(np.abs(dx) - half_gap, 0.0)
    spring = np.sign(dx) * k_contact * penetration
    damper = np.where(
        penetration > 0.0, np.clip(c_contact * dv, -np.abs(spring), np.abs(spring)), 0.0
    )
    np.testing.assert_allclose(r["drivetrain_force_N"], spring + damper, rtol=1e-9, atol=1e-6)
    assert np.count_nonzero(penetration) > 100  # the contact was exercised

    # loads are held at their value at the middle of each tick (steps fall on ticks)
    mid = t[:-1] + 0.5 * TS_FINE
    t_load = np.where(mid >= TL_STEP[0], TL_STEP[1], 0.0)
    f_rod = np.where(mid >= FL_STEP[0], FL_STEP[1], 0.0)

    def trap(f):
        return trapezoid_per_tick(f, TS_FINE)

    work_in = np.sum(trap(torque * w))
    kinetic = 0.5 * inertia * w**2 + 0.5 * mass * v**2
    spring_energy = 0.5 * k_contact * penetration**2
    terms = {
        "kinetic": kinetic[-1] - kinetic[0],
        "spring": spring_energy[-1] - spring_energy[0],
        "motor viscous": np.sum(trap(b_visc * w**2)),
        "load viscous": np.sum(trap(c_load * v**2)),
        "contact damping": np.sum(trap(damper * dv)),
        "motor load": np.sum(t_load * trap(w)),
        "rod load": np.sum(f_rod * trap(v)),
    }
    residual = work_in - sum(terms.values())
    bound = (
        quadrature_error_bound(torque * w, TS_FINE)
        + quadrature_error_bound(b_visc * w**2, TS_FINE)
        + quadrature_error_bound(c_load * v**2, TS_FINE)
        + quadrature_error_bound(damper * dv, TS_FINE)
        + TL_STEP[1] * quadrature_error_bound(w, TS_FINE)
        + FL_STEP[1] * quadrature_error_bound(v, TS_FINE)
    )
    dissipations = [terms[k] for k in ("motor viscous", "load viscous", "contact damping")]
    assert min(dissipations) > 0.0
    assert bound < 0.1 * min(dissipations)  # dropping any dissipation would fail
    assert abs(residual) < 2.0 * bound, (residual, bound, terms)


# --- 3. voltage limit ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("speed_rpm", "controller_bus_factor"),
    [(20000.0, 1.0), (-20000.0, 1.0), (20000.0, 10.0)],
    ids=["forward", "reverse", "controller-thinks-bus-is-10x"],
)
def test_voltage_never_exceeds_the_inverter_limit(speed_rpm, controller_bus_factor):
    """A step far beyond the voltage-limited speed (~6500 rpm) saturates the inverter. With
    controller_bus_factor > 1 the current loop's own limit is inert and only the plant's
    averaged inverter stands between the request and the motor. The drive's own speed limit
    is raised above the step, so that the engine's clamp of the command does not act first."""
    plant, p = frictionless_sea805(WMAX=2.0 * abs(speed_rpm) * RPM)
    facts = facts_of(plant)
    current_facts = dataclasses.replace(facts, dc_bus_V=controller_bus_factor * facts.dc_bus_V)
    setup = speed_setup(
        p,
        facts,
        ts=1e-4,
        substeps=4,
        duration_s=0.2,
        speed_rpm=speed_rpm,
        current_facts=current_facts,
    )
    r = simulate(setup)
    limit = plant.motor.dc_bus_V / math.sqrt(3.0)
    u = np.hypot(r["ud_V"], r["uq_V"])
    assert u.max() <= limit * (1.0 + 1e-12)
    assert np.mean(u >= limit * (1.0 - 1e-9)) > 0.5  # the limit was active most of the run
    # and the motor got close to the speed where its back-EMF alone reaches the limit
    assert abs(r["motor_speed_rad_s"]).max() > 0.9 * limit / (
        plant.motor.pole_pairs * plant.motor.flux_linkage_Wb
    )


# --- 4. the inverter's current limit -------------------------------------------------------------

_P = frictionless_sea805()[1]
SEA805 = {
    name: float(_P[getattr(A, f"P_{key}")])
    for name, key in (
        ("rs", "RS"),
        ("ld", "LD"),
        ("lq", "LQ"),
        ("psi_f", "PSI"),
        ("i_max", "IMAX"),
        ("u_dc", "UDC"),
    )
}
ELECTRICAL = tuple(SEA805.values())[:4]  # rs, ld, lq, psi_f


def inverter_rates(i_d, i_q, u_d, u_q, w_e, motor=SEA805):
    return inverter_current_rates(i_d, i_q, u_d, u_q, w_e, *motor.values())


def test_a_locked_rotor_current_rises_as_rl_and_stops_at_the_limit():
    """Rotor locked (we = 0), a 10 V step on q: i(t) = (u/Rs)(1 - exp(-Rs t/Lq)) would reach
    206 A; the inverter holds it at 58 A from t* = -(Lq/Rs) ln(1 - 58 Rs/u). The closed form
    against a tight-tolerance solve_ivp of the element's own rates."""
    u, rs, lq, i_max = 10.0, SEA805["rs"], SEA805["lq"], SEA805["i_max"]
    t_star = -(lq / rs) * math.log(1.0 - i_max * rs / u)
    t = np.linspace(0.0, 3.0 * t_star, 301)
    sol = solve_ivp(
        lambda _t, i: inverter_rates(i[0], i[1], 0.0, u, 0.0),
        (0.0, t[-1]),
        [0.0, 0.0],
        t_eval=t,
        rtol=1e-10,
        atol=1e-9,
        max_step=t_star / 200.0,
    )
    expected = np.minimum((u / rs) * (1.0 - np.exp(-rs * t / lq)), i_max)
    assert np.max(np.abs(sol.y[1] - expected)) < 1e-6 * i_max
    assert np.max(np.abs(sol.y[0])) < 1e-9


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 135.0, -100.0])
def test_at_the_limit_no_command_grows_the_current_and_below_it_all_act(angle_deg):
    """At |i| = i_max in any direction, a command that would grow |i| is cut to d|i|/dt = 0;
    one that lowers it acts as it is; below the limit every command acts as it is."""
    a = math.radians(angle_deg)
    i_d, i_q = SEA805["i_max"] * math.cos(a), SEA805["i_max"] * math.sin(a)
    w_e = 4 * 100.0
    free = current_rates(i_d, i_q, 150.0, -80.0, w_e, *ELECTRICAL)
    held = inverter_rates(i_d, i_q, 150.0, -80.0, w_e)
    growth = i_d * free[0] + i_q * free[1]
    if growth > 0.0:
        assert i_d * held[0] + i_q * held[1] == pytest.approx(0.0, abs=1e-9 * abs(growth))
    else:
        assert held == pytest.approx(free, rel=1e-15)
    below = inverter_rates(0.9 * i_d, 0.9 * i_q, 150.0, -80.0, w_e)
    assert below == current_rates(0.9 * i_d, 0.9 * i_q, 150.0, -80.0, w_e, *ELECTRICAL)


@pytest.mark.parametrize("emf_ratio", [0.8, 1.2])
def test_a_back_emf_beyond_the_bus_drives_the_current_past_the_limit(emf_ratio):
    """Back-driven at we psi_f = ratio x Udc/sqrt(3), at the limit with the command pushing the
    current up: within the bus the inverter holds it (diq/dt = 0); beyond it, the largest
    voltage the inverter has cannot stop the current growing (the diodes conduct)."""
    u_max = SEA805["u_dc"] / math.sqrt(3.0)
    w_e = -emf_ratio * u_max / SEA805["psi_f"]  # driven backwards: the back-EMF pushes iq up
    _, diq = inverter_rates(0.0, SEA805["i_max"], 0.0, u_max, w_e)
    if emf_ratio < 1.0:
        assert diq == pytest.approx(0.0, abs=1e-6)
    else:
        assert diq > 0.0
