"""Validation of the hinge contact law (emasim.plant.contact, SPEC 1.6).

What is checked against what:

* the unit conversions of the paper's Table 1 (mm-based K, C, d, Vs, Vd) against hand values and
  against the physical statement "same force at the same penetration in either unit system";
* the ADAMS IMPACT normal force against its definition, with an independent STEP reference
  (scipy's cubic Hermite spline with zero end slopes, not the package's formula);
* the ADAMS friction coefficient: odd, Lipschitz continuous with the STEP's maximal slope, bounded,
  its plateaus and monotone pieces;
* the parameter model's validation.

Hypothesis runs with bounded example counts; floats are finite by construction.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from scipy.interpolate import CubicHermiteSpline
from scipy.optimize import brentq

from emasim.plant import contact as C
from emasim.plant.contact import ContactParams, friction_coefficient, normal_force
from emasim.plant.presets import paper_hinge_contact

SETTINGS = settings(max_examples=200, deadline=None)

PAPER = paper_hinge_contact().pack()
K, E, DAMP, DEPTH = PAPER[C.C_K], PAPER[C.C_E], PAPER[C.C_DAMP], PAPER[C.C_DEPTH]
MU_S, MU_D, VS, VD = PAPER[C.C_MU_S], PAPER[C.C_MU_D], PAPER[C.C_VS], PAPER[C.C_VD]

penetrations = st.floats(1e-12, 2e-3)  # m: from round-off to three times the rated-load depth
rates = st.floats(-20.0, 20.0)  # m/s, far beyond any hinge speed in the linkage
speeds = st.floats(-5.0, 5.0)  # slip speeds, m/s: covers 0, Vs = 0.1 and Vd = 1


def step_reference(x, x0, h0, x1, h1):
    """ADAMS STEP built independently: the cubic Hermite spline through (x0, h0), (x1, h1)
    with zero end slopes, held constant outside [x0, x1]."""
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    return float(CubicHermiteSpline([x0, x1], [h0, h1], [0.0, 0.0])(x))


@st.composite
def contact_params(draw):
    """A valid ContactParams, Table-1-like magnitudes, mu_d <= mu_s as in every friction pair."""
    mu_s = draw(st.floats(0.05, 1.0))
    vs = draw(st.floats(1.0, 500.0))
    return ContactParams(
        stiffness_N_per_mm_e=draw(st.floats(1e2, 1e7)),
        exponent=draw(st.floats(1.0, 3.0)),
        damping_Ns_per_mm=draw(st.floats(0.0, 100.0)),
        penetration_depth_mm=draw(st.floats(0.01, 1.0)),
        mu_static=mu_s,
        mu_dynamic=draw(st.floats(0.0, 1.0)) * mu_s,
        stiction_speed_mm_s=vs,
        dynamic_speed_mm_s=vs * draw(st.floats(1.5, 50.0)),
    )


def max_friction_slope(c):
    """The steepest slope of mu(v): a STEP from h0 to h1 over [x0, x1] has slope at most
    1.5 |h1 - h0| / (x1 - x0) (at its midpoint)."""
    inner = 1.5 * 2.0 * c[C.C_MU_S] / (2.0 * c[C.C_VS])
    outer = 1.5 * abs(c[C.C_MU_S] - c[C.C_MU_D]) / (c[C.C_VD] - c[C.C_VS])
    return max(inner, outer)


# --- Table 1 units ------------------------------------------------------------------------------


def test_table1_unit_conversions():
    """K = 1e5 N/mm^2.2 is 1e5 * 1000^2.2 = 3.98e11 N/m^2.2 (not 1e8 N/m); C = 10 N s/mm is
    1e4 N s/m; d = 0.1 mm; Vs, Vd = 100, 1000 mm/s are 0.1, 1 m/s; the rest passes through."""
    assert K == pytest.approx(1e5 * 1000.0**2.2, rel=1e-14)
    assert K == pytest.approx(3.98e11, rel=1e-3)
    assert E == 2.2
    assert DAMP == pytest.approx(1e4, rel=1e-14)
    assert DEPTH == pytest.approx(1e-4, rel=1e-14)
    assert (MU_S, MU_D) == (0.3, 0.1)
    assert VS == pytest.approx(0.1, rel=1e-14)
    assert VD == pytest.approx(1.0, rel=1e-14)


@SETTINGS
@given(p=contact_params(), depth_mm=st.floats(1e-6, 1.0), rate_mm_s=st.floats(-1e4, 1e4))
def test_pack_gives_the_same_force_in_si_as_table1_in_mm(p, depth_mm, rate_mm_s):
    """The physical meaning of the conversion: at a penetration given in mm, K_mm delta_mm^e
    (N) equals K_SI delta_m^e, and C_mm v_mm equals C_SI v_m, for any exponent."""
    c = p.pack()
    spring_mm = p.stiffness_N_per_mm_e * depth_mm**p.exponent
    assert c[C.C_K] * (depth_mm * 1e-3) ** c[C.C_E] == pytest.approx(spring_mm, rel=1e-12)
    damper_mm = p.damping_Ns_per_mm * rate_mm_s
    assert c[C.C_DAMP] * (rate_mm_s * 1e-3) == pytest.approx(damper_mm, rel=1e-12, abs=1e-300)
    assert c[C.C_DEPTH] == pytest.approx(p.penetration_depth_mm * 1e-3, rel=1e-15)
    assert c[C.C_VS] == pytest.approx(p.stiction_speed_mm_s * 1e-3, rel=1e-15)
    assert c[C.C_VD] == pytest.approx(p.dynamic_speed_mm_s * 1e-3, rel=1e-15)


def test_penetration_at_the_rated_50kN_is_about_0_7mm():
    """SPEC 1.6: at the rated 50 kN static load the hinge penetrates about 0.7 mm, seventy
    times the 0.01 mm clearance. Solved with a root finder on the packaged force law and
    compared with the closed form (F/K)^(1/e) = 0.73 mm."""
    delta = brentq(lambda x: normal_force(x, 0.0, PAPER) - 5e4, 1e-6, 1e-2, xtol=1e-15)
    assert delta == pytest.approx((5e4 / K) ** (1.0 / E), rel=1e-9)
    assert 0.65e-3 < delta < 0.75e-3
    assert normal_force(delta, 0.0, PAPER) == pytest.approx(5e4, rel=1e-9)


# --- normal force -------------------------------------------------------------------------------


@SETTINGS
@given(gap=st.floats(0.0, 1.0), rate=rates)
def test_no_force_when_apart(gap, rate):
    """delta <= 0: the pin is clear of the wall (or just touching), no force at any rate."""
    assert normal_force(-gap, rate, PAPER) == 0.0


@SETTINGS
@given(delta=st.floats(-1e-3, 2e-3), rate=st.floats(-1e3, 1e3))
def test_never_pulls(delta, rate):
    """The max(0, ...) clip: a fast separation may cancel the spring but never pull."""
    assert normal_force(delta, rate, PAPER) >= 0.0


@SETTINGS
@given(fraction=st.floats(1e-9, 1.0), rate=rates)
def test_continuous_at_first_contact(fraction, rate):
    """Below the depth d the damping coefficient is STEP <= 3 C (delta/d)^2, so
    0 <= Fn <= K delta^e + 3 C (delta/d)^2 |delta_dot| -> 0 as delta -> 0+, for any rate:
    no force jump at impact (unlike a plain Kelvin-Voigt law, which jumps by C delta_dot)."""
    delta = fraction * DEPTH
    bound = K * delta**E + 3.0 * DAMP * (delta / DEPTH) ** 2 * abs(rate)
    assert 0.0 <= normal_force(delta, rate, PAPER) <= bound * (1.0 + 1e-12)


def test_force_tends_to_zero_at_first_contact():
    """The explicit limit: at 20 m/s approach, Fn < 1e-6 N at delta = 1e-12 m, and it shrinks
    with delta; at delta = 0 exactly it is 0."""
    values = [normal_force(10.0**-k, 20.0, PAPER) for k in range(6, 14)]
    assert np.all(np.diff(values) < 0.0)
    assert values[-1] < 1e-9
    assert normal_force(1e-12, 20.0, PAPER) < 1e-6
    assert normal_force(0.0, 20.0, PAPER) == 0.0


@SETTINGS
@given(delta=penetrations, rate=rates)
def test_damping_is_the_cubic_step_below_d_and_c_beyond(delta, rate):
    """Fn = max(0, K delta^e + c(delta) delta_dot) with c = C for delta >= d and the STEP ramp
    (independent spline reference) below."""
    c_ref = DAMP if delta >= DEPTH else step_reference(delta, 0.0, 0.0, DEPTH, DAMP)
    expected = max(0.0, K * delta**E + c_ref * rate)
    scale = K * delta**E + c_ref * abs(rate)  # what the terms add up to before cancelling
    assert normal_force(delta, rate, PAPER) == pytest.approx(expected, abs=1e-12 * scale)


@pytest.mark.parametrize(
    "fraction, coefficient", [(0.25, 0.15625), (0.5, 0.5), (0.75, 0.84375), (1.0, 1.0), (3.0, 1.0)]
)
def test_damping_ramp_values(fraction, coefficient):
    """Hand values of 3a^2 - 2a^3: the effective damping (Fn(delta, v) - Fn(delta, 0))/v
    at delta = a d is C (3a^2 - 2a^3), and C beyond d."""
    delta, v = fraction * DEPTH, 0.01
    effective = (normal_force(delta, v, PAPER) - normal_force(delta, 0.0, PAPER)) / v
    assert effective == pytest.approx(coefficient * DAMP, rel=1e-9)


# --- friction coefficient -----------------------------------------------------------------------


@SETTINGS
@given(p=contact_params(), v=speeds)
def test_friction_is_odd(p, v):
    c = p.pack()
    assert friction_coefficient(-v, c) == pytest.approx(-friction_coefficient(v, c), abs=1e-15)


@SETTINGS
@given(p=contact_params(), v=speeds, dv=st.floats(-1e-2, 1e-2))
def test_friction_is_lipschitz_continuous(p, v, dv):
    """|mu(v + dv) - mu(v)| <= L |dv| with L the STEP's maximal slope: continuity everywhere,
    including across 0, +-Vs and +-Vd where the formula changes branch."""
    c = p.pack()
    jump = abs(friction_coefficient(v + dv, c) - friction_coefficient(v, c))
    assert jump <= max_friction_slope(c) * abs(dv) * (1.0 + 1e-9) + 1e-15


@pytest.mark.parametrize("point", [0.0, VS, -VS, VD, -VD])
def test_friction_has_equal_left_and_right_limits(point):
    """At the branch points 0, +-Vs, +-Vd of the paper's law the one-sided values agree to the
    slope bound times the step; the value at the point is the common limit."""
    eps = 1e-10
    left = friction_coefficient(point - eps, PAPER)
    right = friction_coefficient(point + eps, PAPER)
    at = friction_coefficient(point, PAPER)
    slope = max_friction_slope(PAPER)
    assert abs(right - left) <= 2.0 * eps * slope + 1e-15
    assert abs(at - left) <= eps * slope + 1e-15


def test_friction_plateaus_and_anchor_values():
    """mu(0) = 0 (no stiction jump), mu(+-Vs) = +-mu_s, mu = mu_d sign(v) for |v| >= Vd."""
    assert friction_coefficient(0.0, PAPER) == 0.0
    assert friction_coefficient(VS, PAPER) == pytest.approx(MU_S, rel=1e-15)
    assert friction_coefficient(-VS, PAPER) == pytest.approx(-MU_S, rel=1e-15)
    for v in (VD, 1.5 * VD, 10.0, 1e3):
        assert friction_coefficient(v, PAPER) == pytest.approx(MU_D, rel=1e-15)
        assert friction_coefficient(-v, PAPER) == pytest.approx(-MU_D, rel=1e-15)


@SETTINGS
@given(p=contact_params(), v=speeds)
def test_friction_bounded_by_mu_s(p, v):
    c = p.pack()
    assert abs(friction_coefficient(v, c)) <= c[C.C_MU_S] * (1.0 + 1e-15)


@SETTINGS
@given(p=contact_params())
def test_friction_monotone_pieces(p):
    """Non-decreasing on [-Vs, Vs] (the stiction ramp through 0) and non-increasing in |v| on
    [Vs, Vd] (the Stribeck-like drop from mu_s to mu_d), on a fine grid."""
    c = p.pack()
    ramp = np.array([friction_coefficient(v, c) for v in np.linspace(-c[C.C_VS], c[C.C_VS], 401)])
    assert np.all(np.diff(ramp) >= -1e-15)
    drop = np.array([friction_coefficient(v, c) for v in np.linspace(c[C.C_VS], c[C.C_VD], 401)])
    assert np.all(np.diff(drop) <= 1e-15)


# --- parameter validation -----------------------------------------------------------------------


def _table1(**changes):
    return paper_hinge_contact().model_dump() | changes


@pytest.mark.parametrize("vd", [100.0, 50.0])
def test_rejects_dynamic_speed_not_above_stiction_speed(vd):
    with pytest.raises(ValueError, match="dynamic_speed_mm_s"):
        ContactParams(**_table1(dynamic_speed_mm_s=vd))


@pytest.mark.parametrize(
    "field, value",
    [
        ("stiffness_N_per_mm_e", -1e5),
        ("stiffness_N_per_mm_e", 0.0),
        ("damping_Ns_per_mm", -1.0),
        ("penetration_depth_mm", 0.0),
        ("stiffness_N_per_mm_e", math.nan),
        ("exponent", math.nan),
        ("mu_static", math.nan),
        ("stiction_speed_mm_s", math.inf),
    ],
)
def test_rejects_bad_values_naming_the_field(field, value):
    """A pydantic ValidationError (a ValueError) whose error location is the offending field."""
    with pytest.raises(ValidationError) as info:
        ContactParams(**_table1(**{field: value}))
    assert isinstance(info.value, ValueError)
    assert [e["loc"] for e in info.value.errors()] == [(field,)]
