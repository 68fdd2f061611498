"""Validation of the clearance-joint linkage (emasim.plant.elements.linkage, emasim.sim.mechanism).

What is checked against what:

1. rigid kinematics: :func:`rigid_pose` against an independent chain closure written here from
   the module docstring's body frames, and the +-30 deg rudder travel of the reference geometry;
2. clearance -> 0: the simulated rudder follows the rigid kinematics within the clearance and
   contact compliance, mapped to the rudder through the closure's sensitivity to hinge offsets;
3. energy: without contact damping and friction, with the rod held, kinetic + contact potential
   energy is conserved through many impacts, the RK4 error falling with the step;
4. scipy's Radau (rtol 1e-10) on the same right-hand side: traces for smooth and dissipative
   rattling motion, statistics for elastic (chaotic) rattling;
5. the equations of motion against sympy.physics.mechanics: a Lagrange derivation of the
   actuator swing on a rod of variable length, and a Kane derivation of the whole 9-coordinate
   chain fed with contact forces computed here from the docstring's contact kinematics;
6. the ideal pivots O and A0 hold to round-off along simulations;
7. no pulling, and Newton's third law through the momentum balance of the free bodies B + C.

The reference geometry is ``presets.reference_linkage``; "c" below is the radial clearance.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from emasim.plant import contact as Ct
from emasim.plant.elements import linkage as L
from emasim.plant.presets import reference_linkage
from emasim.sim.mechanism import advance

MM = 1e-3
DEG = math.pi / 180.0

# generalized coordinates and the arm that turns each into a length (m): used to scale random
# perturbations so every coordinate moves its hinge by a comparable distance
ARM = {
    L.PHI: 0.8,
    L.XB: 1.0,
    L.YB: 1.0,
    L.TB: 0.25,
    L.XC: 1.0,
    L.YC: 1.0,
    L.TC: 0.25,
    L.TD: 0.2,
}
ARMS = np.array([ARM[i] for i in range(L.N_POS)])


# --- helpers ------------------------------------------------------------------------------------


def packed(clearance_mm=0.01, conservative=False, rudder_damping=None):
    """The reference linkage packed to SI; ``conservative`` zeroes contact damping and friction."""
    q = reference_linkage(clearance_mm).pack()
    if conservative:
        q[L.CONTACT + Ct.C_DAMP] = 0.0
        q[L.CONTACT + Ct.C_MU_S] = 0.0
        q[L.CONTACT + Ct.C_MU_D] = 0.0
    if rudder_damping is not None:
        q[L.C_D] = rudder_damping
    return q


def rotate(v, angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def body_pose(body, y, s, q):
    """(reference point, angle) of a body, from the module docstring: the rod's frame at the rod
    end L0 + s from A0 along phi; B and C at their state coordinates; D turning about O."""
    if body == L.ROD:
        return q[[L.A0X, L.A0Y]] + (q[L.L0] + s) * rotate((1.0, 0.0), y[L.PHI]), y[L.PHI]
    if body == L.BODY_B:
        return y[[L.XB, L.YB]], y[L.TB]
    if body == L.BODY_C:
        return y[[L.XC, L.YC]], y[L.TC]
    return q[[L.OX, L.OY]], y[L.TD]


# (pin body, hole body) of hinges 1-4, from the module docstring
HINGE_BODIES = (
    (L.ROD, L.BODY_B),
    (L.BODY_B, L.BODY_C),
    (L.GROUND, L.BODY_B),
    (L.BODY_C, L.BODY_D),
)


def hinge_geometry(q):
    """Per hinge: ((pin body, pin local point), (hole body, hole local point)), written from the
    docstring: B's hinge-1 hole at (0, -r1), hinge-2 pin at (r2, 0), hinge-3 hole at its origin;
    C's hinge-2 hole at (0, -Lc/2), hinge-4 pin at (0, +Lc/2); D's hinge-4 hole at (r4, 0);
    the hinge-1 pin at the rod end; the hinge-3 pin fixed at H3 (absolute)."""
    points = (
        ((0.0, 0.0), (0.0, -q[L.R1])),
        ((q[L.R2], 0.0), (0.0, -0.5 * q[L.LC])),
        ((q[L.H3X], q[L.H3Y]), (0.0, 0.0)),
        ((0.0, 0.5 * q[L.LC]), (q[L.R4], 0.0)),
    )
    return tuple(
        ((pin, pin_local), (hole, hole_local))
        for (pin, hole), (pin_local, hole_local) in zip(HINGE_BODIES, points, strict=True)
    )


def cross(a, b):
    """z component of the planar cross product."""
    return a[0] * b[1] - a[1] * b[0]


def world_point(body, local, y, s, q):
    if body == L.GROUND:
        return np.array(local, float)
    origin, angle = body_pose(body, y, s, q)
    return origin + rotate(local, angle)


def hinge_offsets(y, s, q):
    """(4, 2): pin centre - hole centre at each hinge."""
    return np.array(
        [
            world_point(*pin, y, s, q) - world_point(*hole, y, s, q)
            for pin, hole in hinge_geometry(q)
        ]
    )


def circle_intersection(c1, r1, c2, r2, near):
    """The intersection of two circles nearest ``near`` (written apart from linkage's own)."""
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    d = np.linalg.norm(c2 - c1)
    a = (r1 * r1 - r2 * r2 + d * d) / (2.0 * d)
    h = math.sqrt(r1 * r1 - a * a)
    e = (c2 - c1) / d
    foot = c1 + a * e
    normal = np.array([-e[1], e[0]])
    return min((foot + h * normal, foot - h * normal), key=lambda p: np.linalg.norm(p - near))


def closure_rudder_angle(s, offsets, q):
    """Rudder angle of the chain closed with given hinge offsets (pin - hole, m), walking
    A0 -> rod end -> B (whose origin sits at H3 - offset 3) -> hinge 2 -> C -> hinge 4 -> D.

    Zero offsets give the rigid kinematics; it is written from the docstring's frames only."""
    a0, h3, o = q[[L.A0X, L.A0Y]], q[[L.H3X, L.H3Y]], q[[L.OX, L.OY]]
    d1, d2, d3, d4 = offsets
    b_origin = h3 - d3
    rod_end = circle_intersection(a0, q[L.L0] + s, b_origin + d1, q[L.R1], b_origin - [0, q[L.R1]])
    hole1 = rod_end - d1
    theta_b = math.atan2(hole1[0] - b_origin[0], b_origin[1] - hole1[1])
    hole2 = b_origin + q[L.R2] * np.array([math.cos(theta_b), math.sin(theta_b)]) - d2
    hole4 = circle_intersection(hole2 - d4, q[L.LC], o, q[L.R4], o + [q[L.R4], 0.0])
    return math.atan2(hole4[1] - o[1], hole4[0] - o[0])


def offset_sensitivity(s, q, eps=1e-7):
    """G_h = |d(rudder angle)/d(offset_h)| (1/m) per hinge, by central differences.

    A hinge whose pin sits |offset_h| from its hole centre turns the rudder by at most about
    G_h |offset_h|; at mid stroke G = (1/r1, 1/r4, sqrt(1/r1^2 + 1/r4^2), 1/r4) = (4, 5, 6.4, 5)."""
    g = np.zeros(L.N_HINGES)
    for h in range(L.N_HINGES):
        grad = []
        for k in range(2):
            d = np.zeros((L.N_HINGES, 2))
            d[h, k] = eps
            plus = closure_rudder_angle(s, d, q)
            d[h, k] = -eps
            grad.append((plus - closure_rudder_angle(s, d, q)) / (2 * eps))
        g[h] = math.hypot(*grad)
    return g


def rigid_rates(s, v, q, ds=1e-6):
    """Velocities of the rigid motion at rod speed v (central differences of rigid_pose)."""
    return (L.rigid_pose(s + ds, q)[: L.N_POS] - L.rigid_pose(s - ds, q)[: L.N_POS]) / (2 * ds) * v


def shaking(amplitude_speed, half_period, reversals, s0=0.0):
    """Rod segments (s0, v, duration): out at +v for half a period, then back and forth over
    full periods: a triangle wave of the rod position about s0."""
    segments, s = [], s0
    for k in range(reversals + 1):
        v = amplitude_speed if k % 2 == 0 else -amplitude_speed
        duration = half_period if k == 0 else 2.0 * half_period
        segments.append((s, v, duration))
        s += v * duration
    return segments


def rk4_trace(y, segments, q, h, record, torque=0.0):
    """Run the compiled RK4 (:func:`advance`) over rod segments [(s0, v, duration)], sampling
    every ``record`` s; ``y`` is advanced in place. Returns a dict of sampled arrays."""
    out = {"t": [], "s": [], "y": [], "force": [], "pen": [], "fn": []}
    hinges = np.zeros((L.N_HINGES, 2))
    t0 = 0.0
    for s0, v, duration in segments:
        n = int(round(duration / record))
        substeps = int(round(record / h))
        for k in range(n):
            force = advance(y, s0 + v * k * record, v, record, substeps, torque, q, hinges)
            out["t"].append(t0 + (k + 1) * record)
            out["s"].append(s0 + v * (k + 1) * record)
            out["y"].append(y.copy())
            out["force"].append(force)
            out["pen"].append(hinges[:, 0].copy())
            out["fn"].append(hinges[:, 1].copy())
        t0 += duration
    return {key: np.array(value) for key, value in out.items()}


# Radau tolerances: rtol 1e-10; atol 1e-12 m (rad) on positions, 1e-9 m/s on rates. A smaller
# atol on the rates (1e-13) sits below the round-off of the contact forces and stalls Radau at
# 1e-8 s steps in free flight (it asks for accuracy the right-hand side cannot deliver).
RADAU_ATOL = np.r_[np.full(L.N_POS, 1e-12), np.full(L.N_POS, 1e-9)]


def radau_trace(y0, segments, q, record, torque=0.0):
    """scipy's Radau (rtol 1e-10) on ``linkage_rhs`` with the rod at s0 + v t, restarted at each
    segment (the rod speed jumps there), sampled like :func:`rk4_trace`."""
    out = {"t": [], "s": [], "y": [], "force": [], "pen": [], "fn": []}
    hinges = np.zeros((L.N_HINGES, 2))
    y, t0 = np.array(y0, float), 0.0
    for s0, v, duration in segments:

        def rhs(t, state, s0=s0, v=v):
            dy = np.empty(L.N_LINK)
            L.linkage_rhs(state, s0 + v * t, v, torque, q, dy, hinges)
            return dy

        n = int(round(duration / record))
        t_eval = np.arange(1, n + 1) * record
        t_eval[-1] = duration
        sol = solve_ivp(
            rhs, (0.0, duration), y, method="Radau", rtol=1e-10, atol=RADAU_ATOL, t_eval=t_eval
        )
        assert sol.success, sol.message
        dy = np.empty(L.N_LINK)
        for k, t in enumerate(sol.t):
            state = sol.y[:, k]
            out["t"].append(t0 + t)
            out["s"].append(s0 + v * t)
            out["y"].append(state.copy())
            out["force"].append(L.linkage_rhs(state, s0 + v * t, v, torque, q, dy, hinges))
            out["pen"].append(hinges[:, 0].copy())
            out["fn"].append(hinges[:, 1].copy())
        y, t0 = sol.y[:, -1].copy(), t0 + duration
    return {key: np.array(value) for key, value in out.items()}


def impacts(pen):
    """Per hinge, the number of samples where the penetration goes from <= 0 to > 0."""
    return np.sum((pen[:-1] <= 0.0) & (pen[1:] > 0.0), axis=0)


def kinetic_energy(y, s, s_dot, q):
    """Actuator swing (body about A0 plus rod mass at r = L0 + s, with its slide s_dot),
    B and C translation + rotation, rudder rotation."""
    v = y[L.N_POS :]
    r = q[L.L0] + s
    return 0.5 * (
        q[L.I_E] * v[L.PHI] ** 2
        + q[L.MASS_ROD] * (s_dot**2 + (r * v[L.PHI]) ** 2)
        + q[L.MASS_B] * (v[L.XB] ** 2 + v[L.YB] ** 2)
        + q[L.I_B] * v[L.TB] ** 2
        + q[L.MASS_C] * (v[L.XC] ** 2 + v[L.YC] ** 2)
        + q[L.I_C] * v[L.TC] ** 2
        + q[L.J_D] * v[L.TD] ** 2
    )


def contact_energy(y, s, q):
    """Sum over hinges of K delta^(e+1)/(e+1) for delta > 0 (penetrations from the offsets)."""
    k, e = q[L.CONTACT + Ct.C_K], q[L.CONTACT + Ct.C_E]
    clearance = q[L.CLEAR : L.CLEAR + L.N_HINGES]
    delta = np.linalg.norm(hinge_offsets(y, s, q), axis=1) - clearance
    return float(np.sum(k * np.clip(delta, 0.0, None) ** (e + 1) / (e + 1)))


def random_state(rng, q, offset=3e-5, speed=0.3):
    """A state near the rigid pose at a random extension: every coordinate moved by about
    ``offset`` (m at its arm) and given a rate of about ``speed`` (m/s at its arm), so the
    hinges sit anywhere from clear to tens of um deep, approaching and separating, slipping from
    below Vs to beyond Vd. Returns (y, s, s_dot)."""
    s = rng.uniform(-0.1, 0.1)
    y = L.rigid_pose(s, q)
    y[: L.N_POS] += rng.normal(0.0, offset, L.N_POS) / ARMS
    y[L.N_POS :] = rng.normal(0.0, speed, L.N_POS) / ARMS
    return y, s, rng.normal(0.0, speed)


# --- 1. rigid kinematics ------------------------------------------------------------------------


@pytest.mark.parametrize("s_mm", [-125.0, -60.0, 0.0, 37.5, 125.0])
def test_rigid_pose_closes_every_hinge(s_mm):
    """At rest with every pin centred in its hole: hinge_contact's penetration is -c at every
    hinge and the offsets recomputed from the docstring frames vanish, to round-off (1e-13 m on
    coordinates of order 1 m); the independent closure gives the same rudder angle."""
    q = packed()
    s = s_mm * MM
    y = L.rigid_pose(s, q)
    assert np.all(y[L.N_POS :] == 0.0)
    for h in range(L.N_HINGES):
        delta = L.hinge_contact(h, y, s, 0.0, q)[4]
        assert delta == pytest.approx(-q[L.CLEAR + h], abs=1e-13)
    assert np.abs(hinge_offsets(y, s, q)).max() < 1e-13
    closed = closure_rudder_angle(s, np.zeros((L.N_HINGES, 2)), q)
    assert closed == pytest.approx(y[L.TD], abs=1e-12)


def test_rudder_travel_is_about_30_deg_and_monotone():
    """+-125 mm of rod turns the rudder by about +-30 deg (measured -30.23 / +29.84 deg:
    sin(30 deg) = 125/250 with the rod slightly off square), strictly increasing in s;
    rudder_angle_of_extension is rigid_pose's angle."""
    q = packed()
    s = np.linspace(-125.0, 125.0, 251) * MM
    theta = L.rudder_angle_of_extension(s, q)
    assert theta[0] == pytest.approx(-30.0 * DEG, abs=0.5 * DEG)
    assert theta[-1] == pytest.approx(30.0 * DEG, abs=0.5 * DEG)
    assert np.all(np.diff(theta) > 0.0)
    assert theta[125] == pytest.approx(0.0, abs=1e-12)
    assert np.array_equal(theta[::50], [L.rigid_pose(x, q)[L.TD] for x in s[::50]])


def test_rigid_pose_rejects_an_extension_that_cannot_close():
    with pytest.raises(ValueError, match="cannot close"):
        L.rigid_pose(0.6, packed())


def test_rigid_poses_mark_only_the_extensions_that_cannot_close():
    """Each row is its own point: the one that cannot close is NaN, the others as alone."""
    q = packed()
    poses = L.rigid_poses(np.array([-0.05, 0.6, 0.1]), q)
    assert np.isnan(poses[1]).all()
    assert np.array_equal(poses[[0, 2]], [L.rigid_pose(-0.05, q), L.rigid_pose(0.1, q)])


def test_a_stroke_the_linkage_cannot_follow_is_named_at_its_first_open_extension():
    """The check of a plant names the first of its 101 rod extensions that cannot close."""
    from emasim.plant.parameters import check_linkage_closes

    with pytest.raises(ValueError, match=r"cannot close at rod extension -600 mm of the \+-600"):
        check_linkage_closes(reference_linkage(), 1200.0)


# --- 2. clearance -> 0 reproduces the rigid kinematics -----------------------------------------

# Hinge loads of the slow rigid motion: the inertial loads of its accelerations at 20 mm/s
# (actuator swing (I_E + m r^2) phi''/r + Coriolis ~ 0.015 N, link ~ 0.002 N, rudder
# J_D theta''/r4 ~ 0.002 N) are about 0.02 N; LOAD = 0.1 N bounds them with a factor 5 for the
# lever ratios (r1/r2, the link's slant) between a body's inertia and a hinge.
LOAD = 0.1


def peak_penetration(load, clearance, q):
    """Deepest penetration when a load F drives a body across the gap c into the contact
    spring with no damping (work-energy): K delta^(e+1)/(e+1) = F (c + delta). For c -> 0 this
    is the suddenly applied load's overshoot, (e+1)^(1/e) = 1.7 times the static (F/K)^(1/e);
    for c = 0.01 mm the impact dominates (5 um at 0.1 N, against 1.9 um static)."""
    k, e = q[L.CONTACT + Ct.C_K], q[L.CONTACT + Ct.C_E]
    return brentq(lambda d: k * d ** (e + 1) / (e + 1) - load * (clearance + d), 1e-12, 1e-3)


def slow_drive(clearance_mm, v=0.02, duration=1.0, h=1e-5):
    """The rod driven at v from s = -v T/2 to +v T/2, the linkage started on the rigid pose
    with the rigid motion's velocities (so the start does not ring the mechanism). Returns the
    trace, the rudder deviation from the rigid kinematics, G (the largest summed offset
    sensitivity along the path) and delta* = peak_penetration(LOAD, c)."""
    q = packed(clearance_mm)
    s0 = -0.5 * v * duration
    y = L.rigid_pose(s0, q)
    y[L.N_POS :] = rigid_rates(s0, v, q)
    trace = rk4_trace(y, [(s0, v, duration)], q, h=h, record=1e-3)
    deviation = trace["y"][:, L.TD] - L.rudder_angle_of_extension(trace["s"], q)
    g = max(offset_sensitivity(x, q).sum() for x in (s0, 0.0, -s0))
    delta = peak_penetration(LOAD, clearance_mm * MM, q)
    return q, trace, deviation, g, delta


def test_vanishing_clearance_follows_rigid_kinematics():
    """c = 1e-6 mm, rod at 20 mm/s for 1 s, h = 1e-5 s. A hinge's offset is c + delta, and an
    offset turns the rudder by at most G_h times it (G = sum G_h = 20.4-20.5 /m from the
    closure), so |theta - theta_rigid| <= G (c + delta*) = 6.6e-5 rad (0.004 deg) with
    delta* = 3.2 um the peak penetration under LOAD; the hinge forces stay below
    K delta*^e = 0.32 N. Measured: 7.4e-6 rad, 0.053 N. (The soft contact makes the compliance,
    not the 1 nm clearance, the whole deviation.)"""
    q, trace, deviation, g, delta = slow_drive(1e-6)
    assert 20.0 < g < 21.0
    assert trace["fn"].max() < q[L.CONTACT + Ct.C_K] * delta ** q[L.CONTACT + Ct.C_E]
    bound = g * (1e-9 + delta)
    assert np.abs(deviation).max() < bound < 7e-5


def test_paper_clearance_deviation_is_of_the_order_of_clearance_over_arms():
    """c = 0.01 mm: the pins ride on the back of their holes, so the rudder lags by about the
    clearances mapped through the arms: between 0.2 G c and G (c + delta*) (4e-5 .. 3.1e-4 rad,
    delta* = 5 um from crossing the gap under LOAD; forces below K delta*^e = 0.8 N).
    Measured 7.5e-5 rad = 0.37 G c, forces up to 0.17 N."""
    q, trace, deviation, g, delta = slow_drive(0.01)
    c = 0.01 * MM
    assert trace["fn"].max() < q[L.CONTACT + Ct.C_K] * delta ** q[L.CONTACT + Ct.C_E]
    assert 0.2 * g * c < np.abs(deviation).max() < g * (c + delta)


# --- 3. energy conservation ---------------------------------------------------------------------


def rattle_energy(h, duration=0.3):
    """Conservative contacts (C = 0, mu = 0), 0.1 mm clearance, rod held at s = 30 mm, the
    bodies launched (rudder 0.05 rad/s, actuator swing, B and C moving): they rattle through
    the clearances. Returns (relative energy error over time, impacts per hinge)."""
    q = packed(0.1, conservative=True)
    s = 0.03
    y = L.rigid_pose(s, q)
    y[L.N_POS + L.TD] = 0.05
    y[L.N_POS + L.PHI] = 0.01
    y[L.N_POS + L.XB] = 0.015
    y[L.N_POS + L.YC] = -0.01
    y[L.N_POS + L.TC] = 0.05
    e0 = kinetic_energy(y, s, 0.0, q) + contact_energy(y, s, q)
    trace = rk4_trace(y, [(s, 0.0, duration)], q, h=h, record=5e-5)
    energy = np.array([kinetic_energy(x, s, 0.0, q) + contact_energy(x, s, q) for x in trace["y"]])
    return (energy - e0) / e0, impacts(trace["pen"])


def test_energy_is_conserved_without_damping_and_friction():
    """With the rod held, no contact damping or friction and no rudder damping the linkage is
    conservative: E = kinetic + sum K delta^(e+1)/(e+1). Over 0.3 s and ~140 impacts the
    largest relative error of RK4 is < 2e-7 at h = 1e-5 s (measured 5.7e-8) and falls by at
    least 4x per halving of h (order >= 2). Measured 2.0e-6, 5.7e-8, 5.9e-9 at h = 2e-5, 1e-5,
    5e-6: 34x then 10x, order 3.3-5 (the rattle is chaotic, so each h meets different impacts;
    the force K delta^2.2 is only C^2 at first contact, which limits RK4's order there)."""
    errors, counts = {}, {}
    for h in (2e-5, 1e-5, 5e-6):
        drift, hits = rattle_energy(h)
        errors[h], counts[h] = np.abs(drift).max(), hits
    assert counts[1e-5].sum() > 100 and np.all(counts[1e-5] >= 10)
    assert errors[1e-5] < 2e-7
    assert errors[2e-5] > 4.0 * errors[1e-5] > 16.0 * errors[5e-6]


# --- 4. against scipy's Radau -------------------------------------------------------------------


def test_smooth_motion_matches_radau():
    """Contact established everywhere: the rudder loaded by 50 N m against the motion (settled
    0.3 s first), then the rod pushed at 20 mm/s for 30 ms: penetrations 50-90 um, axial
    force 134-307 N. RK4 at h = 1e-5 s and Radau (rtol 1e-10, atol 1e-12 / 1e-9) agree within
    1e-11 m (rad) in positions, 1e-8 m/s in rates, 1e-5 N in force. Measured 4.5e-13, 3.9e-10,
    1.8e-7 N, the same at h = 5e-6 s: the residue is Radau's tolerance, not RK4's error."""
    q = packed()
    torque = -50.0
    y = L.rigid_pose(0.0, q)
    hinges = np.zeros((L.N_HINGES, 2))
    advance(y, 0.0, 0.0, 0.3, 30000, torque, q, hinges)
    segments = [(0.0, 0.02, 0.03)]
    reference = radau_trace(y, segments, q, record=1e-3, torque=torque)
    trace = rk4_trace(y.copy(), segments, q, h=1e-5, record=1e-3, torque=torque)
    assert np.all(trace["pen"] > 0.0)  # every hinge in contact: the smooth regime
    assert np.abs(trace["y"][:, : L.N_POS] - reference["y"][:, : L.N_POS]).max() < 1e-11
    assert np.abs(trace["y"][:, L.N_POS :] - reference["y"][:, L.N_POS :]).max() < 1e-8
    assert np.abs(trace["force"] - reference["force"]).max() < 1e-5
    assert 150.0 < -trace["force"].mean() < 300.0


def test_dissipative_rattle_matches_radau():
    """The paper's contact (damping, friction) with 0.1 mm clearance, the rod shaken at
    +-50 mm/s reversing every 8 ms for 60 ms: 9, 5, 0 and 3 impacts at hinges 1-4. The
    dissipation keeps the motion non-chaotic over this window, so traces still compare:
    identical impact counts, rudder within 1e-10 rad (measured 8.6e-12), axial force within
    1e-3 N of its 130 N peaks (measured 2.4e-5 N: both resolve the impacts)."""
    q = packed(0.1)
    segments = shaking(0.05, 0.004, 7)
    y0 = L.rigid_pose(0.0, q)
    reference = radau_trace(y0, segments, q, record=1e-5)
    trace = rk4_trace(y0.copy(), segments, q, h=2.5e-6, record=1e-5)
    hits = impacts(trace["pen"])
    assert np.array_equal(hits, impacts(reference["pen"]))
    assert hits[0] >= 5 and hits.sum() >= 10
    assert np.abs(trace["y"][:, L.TD] - reference["y"][:, L.TD]).max() < 1e-10
    assert np.abs(trace["force"] - reference["force"]).max() < 1e-3


def test_chaotic_rattle_statistics_match_radau():
    """Elastic contacts (C = 0, mu = 0), 0.1 mm clearance, the rod shaken at +-50 mm/s
    reversing every 8 ms for 92 ms. Trajectories are chaotic: two RK4 runs (h = 1e-5 and
    5e-6 s) separate by about 10x every 10 ms and differ by hundreds of N by the end, so only
    statistics compare. Across RK4 steps 1e-5 .. 1.25e-6 s the hinge-1 impact count is 35 each,
    the other hinges within +-2, the mean axial force 0.02-4.2 N with a standard deviation
    sigma of 133-141 N. Tolerances (about three times that spread): hinge-1 impacts within
    10 %, others within 20 % (+1), mean force within 0.1 sigma, sigma within 10 %. Measured
    (RK4 h = 2.5e-6 s / Radau): impacts 35/36, 36/36, 16/16, 33/31; mean 0.12/1.80 N;
    sigma 133.4/133.0 N; largest force difference between the traces 336 N."""
    q = packed(0.1, conservative=True)
    segments = shaking(0.05, 0.004, 11)
    y0 = L.rigid_pose(0.0, q)
    reference = radau_trace(y0, segments, q, record=1e-5)
    trace = rk4_trace(y0.copy(), segments, q, h=2.5e-6, record=1e-5)
    hits, ref_hits = impacts(trace["pen"]), impacts(reference["pen"])
    assert hits[0] >= 20
    assert abs(hits[0] - ref_hits[0]) <= 0.1 * ref_hits[0]
    assert np.all(np.abs(hits - ref_hits) <= 0.2 * ref_hits + 1)
    sigma = reference["force"].std()
    assert trace["force"].std() == pytest.approx(sigma, rel=0.1)
    assert abs(trace["force"].mean() - reference["force"].mean()) < 0.1 * sigma


# --- 5. equations of motion against sympy.physics.mechanics -------------------------------------


@pytest.fixture(scope="module")
def mech():
    """sympy.physics.mechanics, skipped when sympy is not installed (a test-only dependency)."""
    pytest.importorskip("sympy")
    import sympy
    from sympy.physics import mechanics

    return sympy, mechanics


PARAM_NAMES = ("A0x", "A0y", "Ox", "Oy", "L0", "IE", "m", "mB", "IB", "mC", "IC", "JD", "cD")
PARAM_INDEX = (L.A0X, L.A0Y, L.OX, L.OY, L.L0, L.I_E, L.MASS_ROD, L.MASS_B, L.I_B, L.MASS_C, L.I_C)
PARAM_INDEX += (L.J_D, L.C_D)


def test_actuator_swing_lagrange(mech):
    """Lagrange for the actuator alone: a body of inertia I_E turning about A0 and the rod mass
    m at r = L0 + s on it, coordinates (phi, s); a force F at a rod-fixed point P_c and the
    drive force Fd along the rod. sympy's equations are, identically,
        (I_E + m r^2) phi'' + 2 m r s' phi' = (P_c - A0) x F           (the docstring's swing)
        m (s'' - r phi'^2) = Fd + u . F                                  (the rod axial equation)
    and at random states where hinge 1 alone is in contact, with F from hinge_contact at its
    contact point, phi'' matches linkage_rhs and u . F its returned axial force (1e-12 rel)."""
    sp, me = mech
    t = me.dynamicsymbols._t
    phi, s = me.dynamicsymbols("phi s")
    i_e, m, l0, fd, fx, fy, a, b = sp.symbols("I_E m L0 F_d F_x F_y a b", real=True)
    n = me.ReferenceFrame("N")
    rod = n.orientnew("R", "Axis", [phi, n.z])
    a0 = me.Point("A0")
    a0.set_vel(n, 0)
    end = a0.locatenew("P", (l0 + s) * rod.x)
    end.set_vel(n, end.pos_from(a0).dt(n))
    contact_point = end.locatenew("Pc", a * rod.x + b * rod.y)  # a rod-fixed point
    contact_point.v2pt_theory(end, n, rod)
    body = me.RigidBody("E", a0, rod, sp.Symbol("m_E"), (me.inertia(rod, 0, 0, i_e), a0))
    lagrangian = me.Lagrangian(n, body, me.Particle("rod", end, m))
    loads = [(contact_point, fx * n.x + fy * n.y), (end, fd * rod.x)]
    lm = me.LagrangesMethod(lagrangian, [phi, s], forcelist=loads, frame=n)
    eqs = lm.form_lagranges_equations()
    r, phid, sd = l0 + s, phi.diff(t), s.diff(t)
    force = fx * n.x + fy * n.y
    moment = contact_point.pos_from(a0).cross(force).dot(n.z)
    swing = (i_e + m * r**2) * phi.diff(t, 2) + 2 * m * r * sd * phid - moment
    axial = m * (s.diff(t, 2) - r * phid**2) - fd - force.dot(rod.x)
    assert sp.simplify(eqs[0] - swing) == 0
    assert sp.simplify(eqs[1] - axial) == 0

    rhs = lm.rhs()  # [phi, s, phi', s', phi'', s'']
    args = [phi, s, phid, sd, i_e, m, l0, fd, fx, fy, a, b]
    phi_acc = sp.lambdify(args, rhs[2])
    s_acc = sp.lambdify(args, rhs[3])
    q = packed()
    rng = np.random.default_rng(7)
    dy, hinges = np.empty(L.N_LINK), np.zeros((L.N_HINGES, 2))
    loaded = 0
    for _ in range(10):
        ext = rng.uniform(-0.1, 0.1)
        y = L.rigid_pose(ext, q)  # every pin centred: only hinge 1 will touch
        y[L.PHI] += rng.uniform(1.2, 6.0) * q[L.CLEAR] / (q[L.L0] + ext) * rng.choice([-1, 1])
        y[L.N_POS :] = rng.normal(0.0, 0.3, L.N_POS) / ARMS
        s_dot = rng.normal(0.0, 0.3)
        f_axial = L.linkage_rhs(y, ext, s_dot, 0.0, q, dy, hinges)
        assert hinges[0, 0] > 0.0 and np.all(hinges[1:, 0] < 0.0)
        fx_, fy_, px, py, _, _ = L.hinge_contact(L.H1, y, ext, s_dot, q)
        rod_end = world_point(L.ROD, (0.0, 0.0), y, ext, q)
        local = rotate((px - rod_end[0], py - rod_end[1]), -y[L.PHI])
        drive = rng.normal(0.0, 1e3)
        values = [y[L.PHI], ext, y[L.N_POS + L.PHI], s_dot, q[L.I_E], q[L.MASS_ROD], q[L.L0]]
        values += [drive, fx_, fy_, *local]
        assert dy[L.N_POS + L.PHI] == pytest.approx(phi_acc(*values), rel=1e-12, abs=1e-12)
        r_ = q[L.L0] + ext
        f_sympy = q[L.MASS_ROD] * (s_acc(*values) - r_ * y[L.N_POS + L.PHI] ** 2) - drive
        assert f_axial == pytest.approx(f_sympy, rel=1e-10, abs=1e-9)
        loaded += hinges[0, 1] > 0.0
    assert loaded >= 5  # most states load hinge 1 (fast separation clips the others to 0)


@pytest.fixture(scope="module")
def kane_chain(mech):
    """Kane's equations of the whole chain, derived by sympy: coordinates (phi, xB, yB, thB, xC,
    yC, thC, thD, s); the actuator body about A0 with the rod mass at L0 + s, free planar bodies
    B and C, the rudder D about O with viscous damping c_D and an external torque T, and a drive
    force Fd on the rod. Each hinge's contact force (F_hx, F_hy) acts on the pin body at a
    body-fixed point and its opposite on the hole body at a body-fixed point (symbolic local
    coordinates, set per state to the contact point). Returns lambdified (mass matrix, forcing)
    and, per body, the world position and velocity of a body-fixed point."""
    sp, me = mech
    t = me.dynamicsymbols._t
    coords = me.dynamicsymbols("phi xB yB thB xC yC thC thD s")
    speeds = me.dynamicsymbols("u0:9")
    phi, xb, yb, thb, xc, yc, thc, thd, s = coords
    params = sp.symbols(" ".join(PARAM_NAMES), real=True)
    a0x, a0y, ox, oy, l0, i_e, m, mb, ib, mc, ic, jd, cd = params
    torque, fd = sp.symbols("T F_d", real=True)
    kd = [u - c.diff(t) for u, c in zip(speeds, coords, strict=True)]
    to_speeds = {c.diff(t): u for u, c in zip(speeds, coords, strict=True)}

    n = me.ReferenceFrame("N")
    frame = {L.ROD: phi, L.BODY_B: thb, L.BODY_C: thc, L.BODY_D: thd}
    frame = {body: n.orientnew(f"F{body}", "Axis", [angle, n.z]) for body, angle in frame.items()}
    origin = me.Point("origin")
    origin.set_vel(n, 0)
    a0 = origin.locatenew("A0", a0x * n.x + a0y * n.y)
    a0.set_vel(n, 0)
    rod_end = a0.locatenew("P", (l0 + s) * frame[L.ROD].x)
    rod_end.set_vel(n, rod_end.pos_from(origin).dt(n).subs(to_speeds))
    b_origin = origin.locatenew("Bo", xb * n.x + yb * n.y)
    b_origin.set_vel(n, b_origin.pos_from(origin).dt(n).subs(to_speeds))
    c_origin = origin.locatenew("Co", xc * n.x + yc * n.y)
    c_origin.set_vel(n, c_origin.pos_from(origin).dt(n).subs(to_speeds))
    o = origin.locatenew("O", ox * n.x + oy * n.y)
    o.set_vel(n, 0)
    reference = {L.ROD: rod_end, L.BODY_B: b_origin, L.BODY_C: c_origin, L.BODY_D: o}
    bodies = [
        me.RigidBody(
            "E", a0, frame[L.ROD], sp.Symbol("mE"), (me.inertia(frame[L.ROD], 0, 0, i_e), a0)
        ),
        me.Particle("rod", rod_end, m),
        me.RigidBody(
            "B", b_origin, frame[L.BODY_B], mb, (me.inertia(frame[L.BODY_B], 0, 0, ib), b_origin)
        ),
        me.RigidBody(
            "C", c_origin, frame[L.BODY_C], mc, (me.inertia(frame[L.BODY_C], 0, 0, ic), c_origin)
        ),
        me.RigidBody(
            "D", o, frame[L.BODY_D], sp.Symbol("mD"), (me.inertia(frame[L.BODY_D], 0, 0, jd), o)
        ),
    ]

    def fixed_point(body, name, lx, ly):
        point = reference[body].locatenew(name, lx * frame[body].x + ly * frame[body].y)
        point.v2pt_theory(reference[body], n, frame[body])  # a material point of the body
        return point

    loads = [(frame[L.BODY_D], (torque - cd * speeds[7]) * n.z), (rod_end, fd * frame[L.ROD].x)]
    locals_, forces = [], []
    for h in range(L.N_HINGES):
        f = sp.symbols(f"F{h}x F{h}y", real=True)
        forces += f
        for role, body in zip(("pin", "hole"), HINGE_BODIES[h], strict=True):
            lx, ly = sp.symbols(f"{role}{h}x {role}{h}y", real=True)
            locals_ += [lx, ly]
            if body != L.GROUND:
                sign = 1 if role == "pin" else -1
                loads.append(
                    (fixed_point(body, f"{role}{h}", lx, ly), sign * (f[0] * n.x + f[1] * n.y))
                )
    kane = me.KanesMethod(n, q_ind=coords, u_ind=speeds, kd_eqs=kd)
    kane.kanes_equations(bodies, loads)
    args = [coords, speeds, params, [torque, fd], locals_, forces]
    mass = sp.lambdify(args, kane.mass_matrix, "numpy")
    forcing = sp.lambdify(args, kane.forcing, "numpy")

    lx, ly = sp.symbols("lx ly", real=True)
    kinematics = {}
    for body in reference:
        point = fixed_point(body, f"probe{body}", lx, ly)
        pos, vel = point.pos_from(origin), point.vel(n).subs(to_speeds)
        expr = [pos.dot(n.x), pos.dot(n.y), vel.dot(n.x), vel.dot(n.y)]
        kinematics[body] = sp.lambdify([coords, speeds, params, lx, ly], expr, "numpy")
    return mass, forcing, kinematics


def independent_contacts(y, s, s_dot, q, kinematics):
    """Every hinge's contact from the module docstring, with sympy's point kinematics: offset
    d = pin - hole, delta = |d| - c; in contact n = d/|d|, contact point pc = pin + R_pin n,
    w = v_pin(pc) - v_hole(pc) of the material points, delta' = n.w, v_t = t.w with t = n turned
    +90 deg; F_pin = -Fn n - mu(v_t) Fn t with the packaged scalar laws (tested in
    test_contact). Returns (locals (16,), forces (8,), delta (4,), Fn (4,))."""
    coords, speeds = np.r_[y[: L.N_POS], s], np.r_[y[L.N_POS :], s_dot]
    params = q[list(PARAM_INDEX)]
    c = q[L.CONTACT :]
    locals_, forces, deltas, normals = [], [], [], []
    for h, (pin, hole) in enumerate(hinge_geometry(q)):
        pin_c, hole_c = world_point(*pin, y, s, q), world_point(*hole, y, s, q)
        offset = pin_c - hole_c
        delta = np.linalg.norm(offset) - q[L.CLEAR + h]
        deltas.append(delta)
        if delta <= 0.0:
            locals_ += [0.0] * 4
            forces += [0.0, 0.0]
            normals.append(0.0)
            continue
        nrm = offset / np.linalg.norm(offset)
        tan = np.array([-nrm[1], nrm[0]])
        pc = pin_c + q[L.R_PIN] * nrm
        velocity = []
        for body, _ in (pin, hole):
            if body == L.GROUND:
                locals_ += list(pc)
                velocity.append(np.zeros(2))
                continue
            ref, angle = body_pose(body, y, s, q)
            local = rotate(pc - ref, -angle)
            px, py, vx, vy = kinematics[body](coords, speeds, params, *local)
            assert np.allclose([px, py], pc, rtol=0.0, atol=1e-14)
            locals_ += list(local)
            velocity.append(np.array([vx, vy]))
        w = velocity[0] - velocity[1]
        fn = Ct.normal_force(delta, nrm @ w, c)
        mu = Ct.friction_coefficient(tan @ w, c)
        forces += list(-fn * nrm - mu * fn * tan)
        normals.append(fn)
    return np.array(locals_), np.array(forces), np.array(deltas), np.array(normals)


def test_chain_equations_match_kane(kane_chain):
    """At 40 random states (hinges clear or up to ~0.1 mm deep, approaching and separating at up
    to ~1 m/s, slipping below Vs to beyond Vd; normal forces up to several kN), with rudder
    damping 0.7 N m s/rad, a rudder torque and a drive force: linkage_rhs's 8 accelerations
    equal those of sympy's Kane equations with the independently computed contact forces
    (within 1e-12 of each acceleration's size, floored at 1e-3 of the largest; measured 9e-15),
    its axial force equals m (s'' - r phi'^2) - Fd from Kane's rod equation, and its per-hinge
    penetrations and normal forces equal the independent ones."""
    mass, forcing, kinematics = kane_chain
    q = packed(rudder_damping=0.7)
    rng = np.random.default_rng(2024)
    params = q[list(PARAM_INDEX)]
    dy, hinges = np.empty(L.N_LINK), np.zeros((L.N_HINGES, 2))
    touching = np.zeros(L.N_HINGES, int)
    for _ in range(40):
        y, s, s_dot = random_state(rng, q)
        torque, drive = rng.normal(0.0, 100.0), rng.normal(0.0, 1e3)
        f_axial = L.linkage_rhs(y, s, s_dot, torque, q, dy, hinges)
        locals_, forces, deltas, normals = independent_contacts(y, s, s_dot, q, kinematics)
        np.testing.assert_allclose(hinges[:, 0], deltas, rtol=0.0, atol=1e-15)
        np.testing.assert_allclose(hinges[:, 1], normals, rtol=1e-9, atol=1e-9)
        touching += normals > 0.0
        args = (np.r_[y[: L.N_POS], s], np.r_[y[L.N_POS :], s_dot], params, (torque, drive))
        full_mass = mass(*args, locals_, forces)
        full_forcing = forcing(*args, locals_, forces)
        acc = np.linalg.solve(full_mass, np.ravel(full_forcing))
        scale = np.abs(acc[: L.N_POS]) + 1e-3 * np.abs(acc[: L.N_POS]).max()
        assert np.all(np.abs(dy[L.N_POS :] - acc[: L.N_POS]) <= 1e-12 * scale)
        r = q[L.L0] + s
        kane_axial = q[L.MASS_ROD] * (acc[8] - r * y[L.N_POS + L.PHI] ** 2) - drive
        assert f_axial == pytest.approx(kane_axial, rel=1e-12, abs=1e-9)
    assert np.all(touching >= 5)  # every hinge exercised in contact


# --- 6. ideal joints ----------------------------------------------------------------------------


def test_ideal_pivots_hold_along_a_simulation():
    """O and A0 are generalized coordinates, so along any motion (here the paper's contact with
    0.1 mm clearance, the rod shaken for 60 ms) the rudder's hinge-4 hole stays r4 from O and
    the rod end L0 + s from A0, to round-off (1e-15 m), as the code's own points report."""
    q = packed(0.1)
    trace = rk4_trace(L.rigid_pose(0.0, q), shaking(0.05, 0.004, 7), q, h=5e-6, record=1e-4)
    o, a0 = q[[L.OX, L.OY]], q[[L.A0X, L.A0Y]]
    hole4 = L._local_point(L.H4, False, q)
    for y, s in zip(trace["y"], trace["s"], strict=True):
        frames = L._frames(y, s, 0.0, q)
        p4 = np.array(L._point(frames, L.BODY_D, *hole4))
        end = np.array(L._point(frames, L.ROD, 0.0, 0.0))
        assert abs(np.linalg.norm(p4 - o) - q[L.R4]) < 1e-15
        assert abs(np.linalg.norm(end - a0) - (q[L.L0] + s)) < 2e-15
    assert np.ptp(trace["y"][:, L.TD]) > 0.0 and np.ptp(trace["s"]) > 1e-4


# --- 7. no pulling, Newton's third law ----------------------------------------------------------


def test_contacts_never_pull_and_act_equally_on_pin_and_hole():
    """At 200 random states: every normal force is >= 0 and the force on a pin points back
    towards its hole centre (F . n <= 0, n = (pin - hole)/|pin - hole|); the contact point is
    on the pin's rim. The free bodies B and C obey the momentum balances of their external
    forces only, the hinge-2 pair cancelling (equal, opposite, at the same point):
        m_B a_B + m_C a_C = -F1 - F3 + F4
        sum (r x m a + I theta'') = sum p x F_external     (about the world origin)
    with F_h the force on hinge h's pin (B is hinge 1's and 3's hole, C hinge 4's pin)."""
    q = packed()
    rng = np.random.default_rng(11)
    dy, hinges = np.empty(L.N_LINK), np.zeros((L.N_HINGES, 2))
    clipped = 0
    for _ in range(200):
        y, s, s_dot = random_state(rng, q, speed=1.0)
        L.linkage_rhs(y, s, s_dot, 0.0, q, dy, hinges)
        assert np.all(hinges[:, 1] >= 0.0)
        contacts = [L.hinge_contact(h, y, s, s_dot, q) for h in range(L.N_HINGES)]
        offsets = hinge_offsets(y, s, q)
        for h, (fx, fy, px, py, delta, fn) in enumerate(contacts):
            if delta <= 0.0:
                assert (fx, fy, fn) == (0.0, 0.0, 0.0)
                continue
            nrm = offsets[h] / np.linalg.norm(offsets[h])
            assert np.dot((fx, fy), nrm) == pytest.approx(-fn, abs=1e-12 * (1.0 + fn))
            pin = world_point(*hinge_geometry(q)[h][0], y, s, q)
            assert np.linalg.norm(np.array([px, py]) - pin) == pytest.approx(q[L.R_PIN], rel=1e-12)
            clipped += fn == 0.0
        force = np.array([c[:2] for c in contacts])
        point = np.array([c[2:4] for c in contacts])
        acc = dy[L.N_POS :]
        masses = (q[L.MASS_B], q[L.MASS_C])
        lin = masses[0] * acc[[L.XB, L.YB]] + masses[1] * acc[[L.XC, L.YC]]
        external = -force[L.H1] - force[L.H3] + force[L.H4]
        np.testing.assert_allclose(lin, external, rtol=0.0, atol=1e-9 * (1.0 + np.abs(force).max()))
        ang = (
            cross(y[[L.XB, L.YB]], masses[0] * acc[[L.XB, L.YB]])
            + q[L.I_B] * acc[L.TB]
            + cross(y[[L.XC, L.YC]], masses[1] * acc[[L.XC, L.YC]])
            + q[L.I_C] * acc[L.TC]
        )
        moments = (
            -cross(point[L.H1], force[L.H1])
            - cross(point[L.H3], force[L.H3])
            + cross(point[L.H4], force[L.H4])
        )
        assert ang == pytest.approx(moments, abs=1e-9 * (1.0 + np.abs(force).max()))
    assert clipped > 0  # some states separate fast enough for the max(0, .) to act
