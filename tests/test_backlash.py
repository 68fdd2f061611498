"""Validation of the backlash models: the dead-zone contact law, the two-inertia oscillation
through the gap on the compiled engine, and the play operator against python-control."""

import dataclasses
import math

import control
import numpy as np
import pytest
from helpers import facts_of, frictionless_sea805, inert_speed_controller, speed_setup
from hypothesis import given, settings
from hypothesis import strategies as st

from emasim.plant import actuator as A
from emasim.plant.elements.backlash import dead_zone_force, play_operator
from emasim.sim.engine import simulate

SETTINGS = settings(max_examples=300, deadline=None)

half_gaps = st.floats(1e-6, 1e-2)
stiffnesses = st.floats(1e3, 1e10)
dampings = st.floats(0.0, 1e6)
rates = st.floats(-10.0, 10.0)
fractions = st.floats(0.0, 1.0)
outside = st.floats(1e-9, 10.0)  # how far beyond the gap edge, in units of b


# --- 1. the dead-zone contact law --------------------------------------------------------------


@SETTINGS
@given(
    b=half_gaps, k=stiffnesses, c=dampings, frac=fractions, dv=rates, sign=st.sampled_from([-1, 1])
)
def test_no_force_inside_the_gap(b, k, c, frac, dv, sign):
    assert dead_zone_force(sign * frac * b, dv, b, k, c) == 0.0


@SETTINGS
@given(b=half_gaps, k=stiffnesses, c=dampings, beyond=outside, dv=rates)
def test_contact_never_pulls(b, k, c, beyond, dv):
    dx = b * (1.0 + beyond)
    assert dead_zone_force(dx, dv, b, k, c) >= 0.0
    assert dead_zone_force(-dx, dv, b, k, c) <= 0.0


@SETTINGS
@given(b=half_gaps, k=stiffnesses, c=dampings, beyond=outside, dv=rates)
def test_force_is_bounded_by_twice_the_spring(b, k, c, beyond, dv):
    """The limited damping never more than doubles the spring force (|c dv| <= |Fc|)."""
    dx = b * (1.0 + beyond)
    spring = k * (dx - b)
    for s in (1.0, -1.0):
        f = dead_zone_force(s * dx, dv, b, k, c)
        assert abs(f) <= 2.0 * spring * (1.0 + 1e-12)


@SETTINGS
@given(b=half_gaps, k=stiffnesses, c=st.floats(1.0, 1e6), dv=st.floats(-1e3, 1e3))
def test_continuous_at_first_contact(b, k, c, dv):
    """|F| -> 0 as |dx| -> b from outside, however fast the bodies close (|F| <= 2 K eps)."""
    forces = []
    for eps in b * np.logspace(-1, -9, 9):
        for s in (1.0, -1.0):
            f = dead_zone_force(s * (b + eps), s * dv, b, k, c)
            assert abs(f) <= 2.0 * k * eps * (1.0 + 1e-6) + 1e-12 * k * b
            forces.append(abs(f))
    assert forces[-1] <= 2.0 * k * b * 1e-9 * (1.0 + 1e-6) + 1e-12 * k * b


@SETTINGS
@given(b=half_gaps, k=stiffnesses, c=dampings, frac=st.floats(0.0, 11.0), dv=rates)
def test_odd_symmetry(b, k, c, frac, dv):
    dx = frac * b
    assert dead_zone_force(-dx, -dv, b, k, c) == -dead_zone_force(dx, dv, b, k, c)


@SETTINGS
@given(b=half_gaps, k=stiffnesses, beyond=outside, dv=rates)
def test_undamped_law_is_a_shifted_spring(b, k, beyond, dv):
    dx = b * (1.0 + beyond)
    assert dead_zone_force(dx, dv, b, k, 0.0) == pytest.approx(k * (dx - b), rel=1e-12)
    assert dead_zone_force(-dx, dv, b, k, 0.0) == pytest.approx(k * (-dx + b), rel=1e-12)


@SETTINGS
@given(b=half_gaps, k=stiffnesses, c=st.floats(1.0, 1e6), beyond=outside, frac=fractions)
def test_unlimited_damping_is_kelvin_voigt(b, k, c, beyond, frac):
    """Where |c dv| < |Fc| the limit is idle and F = K (dx - b) + c dv."""
    dx = b * (1.0 + beyond)
    spring = k * (dx - b)
    for dv in (frac * spring / c, -frac * spring / c):
        expected = spring + c * dv  # frac = 1 sits on the limit: 0 up to rounding of spring
        tol = 1e-12 * spring
        assert dead_zone_force(dx, dv, b, k, c) == pytest.approx(expected, rel=0, abs=tol)
        assert dead_zone_force(-dx, -dv, b, k, c) == pytest.approx(-expected, rel=0, abs=tol)


# --- 2. undamped two-inertia oscillation through the gap -----------------------------------------

PSI_INERT = 1e-6  # Wb: back-EMF and torque per ampere of an electrically inert motor
TS = 1e-4  # s, control tick = trace spacing (record_every=1)
SUBSTEPS = 10  # RK4 step h = 10 us
N_PERIODS = 8


def undamped_two_inertia(v_rel, zero_momentum):
    """Run the conservative plant from the middle of the gap; return (result, constants).

    Bodies start at dx = 0 with relative velocity v_rel = K_ratio wm - vL. With
    ``zero_momentum`` the centre of mass is at rest (m1 v1 + m2 v2 = 0); otherwise the load is
    at rest and the motor moves at v_rel / K_ratio.
    """
    plant, p = frictionless_sea805(B=0.0, CL=0.0, CB=0.0, ETA=1.0, PSI=PSI_INERT)
    facts = dataclasses.replace(facts_of(plant), flux_linkage_Wb=PSI_INERT)
    ratio, kb, b = p[A.P_K], p[A.P_KB], p[A.P_HALF_GAP]
    # masses from the pydantic parameters, not from the packed array the plant reads
    m1 = plant.motor.inertia_kgm2 / plant.ratio_m_per_rad**2
    m2 = plant.load_mass_kg
    m_r = m1 * m2 / (m1 + m2)
    omega = math.sqrt(plant.backlash.stiffness_N_per_m / m_r)
    half_width = 0.5 * plant.backlash.width_mm * 1e-3
    period = 2.0 * (2.0 * half_width / v_rel) + 2.0 * math.pi / omega

    x0 = np.zeros(A.N_STATE)
    if zero_momentum:
        x0[A.X_WM] = m2 / (m1 + m2) * v_rel / ratio
        x0[A.X_VL] = -m1 / (m1 + m2) * v_rel
    else:
        x0[A.X_WM] = v_rel / ratio
    setup = speed_setup(
        p,
        facts,
        ts=TS,
        substeps=SUBSTEPS,
        duration_s=(N_PERIODS + 1.5) * period,
        speed=inert_speed_controller(),
        x0=x0,
    )
    consts = dict(m1=m1, m2=m2, ratio=ratio, kb=kb, b=b, omega=omega, period=period)
    return simulate(setup), consts


CASES = [(0.1, True), (0.02, False)]


@pytest.mark.parametrize(("v_rel", "zero_momentum"), CASES)
def test_oscillation_period_through_the_gap(v_rel, zero_momentum):
    r, c = undamped_two_inertia(v_rel, zero_momentum)
    t = r["t_s"]
    dx = c["ratio"] * r["motor_angle_rad"] - r["actuator_position_m"]

    # the motor is electrically inert: no current flows, its torque is nil against the contact
    assert np.abs(r["iq_A"]).max() < 1e-4
    assert np.abs(r["id_A"]).max() < 1e-4
    contact_torque = c["ratio"] * np.abs(r["drivetrain_force_N"]).max()
    assert np.abs(r["torque_Nm"]).max() < 1e-9 * contact_torque

    # upward crossings of the gap's middle, one per period. Between contacts both bodies fly
    # freely, so dx is linear in t there and the interpolated crossing time is exact: the
    # trace spacing Ts does not limit the measurement.
    i = np.nonzero((dx[:-1] < 0.0) & (dx[1:] >= 0.0))[0]
    assert np.all(np.abs(dx[i]) < c["b"]) and np.all(np.abs(dx[i + 1]) < c["b"])
    crossings = t[i] - dx[i] * (t[i + 1] - t[i]) / (dx[i + 1] - dx[i])
    periods = np.diff(crossings)
    assert len(periods) == N_PERIODS

    # Error budget: the contact law has a kink at first contact, where RK4 drops to second
    # order, so the contact phase (duration 2 pi / omega per period) is timed to about
    # (omega h)^2 of its length (omega h = 0.019, (omega h)^2 = 3.5e-4). A 1 % error in the
    # stiffness, or the load mass used instead of the reduced mass, moves T by > 3e-3.
    h = TS / SUBSTEPS
    tol = (c["omega"] * h) ** 2 * (2.0 * math.pi / c["omega"]) / c["period"]
    rel = periods / c["period"] - 1.0
    assert np.abs(rel).max() < tol, (periods, c["period"])


@pytest.mark.parametrize(("v_rel", "zero_momentum"), CASES)
def test_oscillation_conserves_energy_and_momentum(v_rel, zero_momentum):
    r, c = undamped_two_inertia(v_rel, zero_momentum)
    v1 = c["ratio"] * r["motor_speed_rad_s"]  # nut velocity, m/s
    v2 = r["actuator_velocity_m_s"]
    dx = c["ratio"] * r["motor_angle_rad"] - r["actuator_position_m"]
    penetration = np.maximum(np.abs(dx) - c["b"], 0.0)
    assert penetration.max() > 0.0  # it did hit both flanks...
    assert dx.max() > c["b"] and dx.min() < -c["b"]

    kinetic = 0.5 * c["m1"] * v1**2 + 0.5 * c["m2"] * v2**2
    spring = 0.5 * c["kb"] * penetration**2
    energy = kinetic + spring
    # relative-motion energy (total minus centre-of-mass energy) carries all the exchange;
    # its error, like the period's, is second order in omega h from the kink (see above).
    momentum = c["m1"] * v1 + c["m2"] * v2
    m_total = c["m1"] + c["m2"]
    relative_energy = energy - 0.5 * momentum**2 / m_total
    # ...and hard enough to turn all of the relative kinetic energy into spring energy
    assert spring.max() > 0.99 * relative_energy[0]
    h = TS / SUBSTEPS
    tol = (c["omega"] * h) ** 2
    drift = np.abs(relative_energy / relative_energy[0] - 1.0).max()
    assert drift < tol
    assert np.abs(energy / energy[0] - 1.0).max() < tol
    # internal forces only: the momentum stays put to rounding
    scale = c["m1"] * np.abs(v1).max() + c["m2"] * np.abs(v2).max()
    assert np.abs(momentum - momentum[0]).max() < 1e-10 * scale


# --- 3. play operator ----------------------------------------------------------------------------

N_PER_PERIOD = 8192
N_MEASURED = 3  # periods after one settling period


def play_response(x, half_gap, gain, y0=0.0):
    y = np.empty_like(x)
    prev = y0
    for k, xk in enumerate(x):
        prev = play_operator(xk, prev, half_gap, gain)
        y[k] = prev
    return y


def first_harmonic_gain(amplitude, half_gap, gain=1.0):
    """Complex first-harmonic gain of the play operator for x = A sin(theta)."""
    theta = 2.0 * np.pi * np.arange((1 + N_MEASURED) * N_PER_PERIOD) / N_PER_PERIOD
    x = amplitude * np.sin(theta)
    y = play_response(x, half_gap, gain)[N_PER_PERIOD:]
    theta = theta[N_PER_PERIOD:]
    # y ~ a1 cos + b1 sin  ->  N = (b1 + j a1) / A = (2 j / (n A)) sum y exp(-j theta)
    return 2j * np.sum(y * np.exp(-1j * theta)) / (len(y) * amplitude)


@pytest.mark.parametrize("ratio", [1.02, 1.2, 1.5, 2.0, 3.0, 10.0, 50.0])
def test_play_describing_function_matches_python_control(ratio):
    """python-control's width b_ct is the total play: its output holds while |x - c| < b_ct/2
    (descfcn.friction_backlash_nonlinearity), so b_ct = 2 * half_gap.

    Error budget: the rectangle rule over whole periods of a continuous output with kinks is
    O(dtheta^2) = (2 pi / 8192)^2 = 6e-7, and the sampled turning point misses the peak by at
    most A dtheta^2 / 8 (both ~1e-7 of N, measured 3e-8); 1e-5 leaves margin, while a 1 %
    error in the gap moves N by more than 1e-4 at every amplitude here.
    """
    half_gap = 0.05e-3
    amplitude = ratio * half_gap
    measured = first_harmonic_gain(amplitude, half_gap)
    reference = control.describing_function(
        control.friction_backlash_nonlinearity(2.0 * half_gap), amplitude
    )
    assert abs(measured - reference) < 1e-5, (measured, reference)


@pytest.mark.parametrize("gain", [0.5, 2.0])
def test_play_describing_function_with_gain(gain):
    """y = play(x; b, l) = l * play(x; b / l, 1), so N = l * N_ct(A; b_ct = 2 b / l)."""
    half_gap, amplitude = 1.0, 3.0
    measured = first_harmonic_gain(amplitude, half_gap, gain)
    reference = gain * control.describing_function(
        control.friction_backlash_nonlinearity(2.0 * half_gap / gain), amplitude
    )
    assert abs(measured - reference) < 1e-5 * gain, (measured, reference)


def test_play_below_the_gap_passes_nothing():
    assert abs(first_harmonic_gain(0.9, 1.0)) < 1e-12


@settings(max_examples=200, deadline=None)
@given(
    steps=st.lists(st.floats(-5.0, 5.0), min_size=1, max_size=60),
    b=st.floats(0.0, 2.0),
    gain=st.floats(0.1, 10.0),
    start=st.floats(-1.0, 1.0),
)
def test_play_output_stays_in_the_band_and_moves_only_on_its_edge(steps, b, gain, start):
    x = np.cumsum(steps)
    y = play_response(x, b, gain, y0=gain * x[0] + start * b)
    lx = gain * x
    tol = 1e-12 * (1.0 + np.abs(lx))
    assert np.all(y >= lx - b - tol) and np.all(y <= lx + b + tol)
    prev = np.concatenate(([gain * x[0] + start * b], y[:-1]))
    moved = y != prev
    on_edge = np.isclose(y, lx - b, rtol=0, atol=1e-12) | np.isclose(y, lx + b, rtol=0, atol=1e-12)
    assert np.all(on_edge[moved])
