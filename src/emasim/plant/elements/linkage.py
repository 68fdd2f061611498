"""The control-surface linkage: planar bodies tied by clearance-joint hinges (the ADAMS model).

Chain (SPEC 1.6): the actuator swings about its ideal pivot A0 (bearing housing 1) and its rod
slides out by s; the rod end carries the pin of hinge 1 -> auxiliary rocker B, which hangs in
bearing housing 3 on the pin of hinge 3 -> hinge 2 -> auxiliary link C -> hinge 4 -> rocker arm
D, fixed to the rudder shaft, which turns in ideal bearings about O and carries the inertia
disk. Hinges 1-4 are pin-in-hole contacts (emasim.plant.contact) with a radial clearance; with
every hinge a clearance joint there is no closed loop of ideal joints, so the state is

    phi (actuator swing), B = (xB, yB, thB), C = (xC, yC, thC), thD (rudder), and their rates

(16 states), while s, ds/dt come from the drive (or are prescribed, as the paper's velocity
driver did). Equations of motion (planar Newton-Euler; gravity acts out of the plane):

    (I_E + m r^2) phi'' = tau_A0 - 2 m r s' phi'           r = L0 + s, rod mass m at the rod end
    m_B [xB'', yB''] = F_B,    I_B thB'' = M_B             (forces and moments of the contacts)
    m_C [xC'', yC''] = F_C,    I_C thC'' = M_C
    J_D thD'' = M_D - c_D thD' + T_rudder(t)

and on the rod axis the linkage pushes with F_axial = u . F_hinge1 (u the rod direction); the
rod's own axial equation m (s'' - r phi'^2) = F_drive + F_axial belongs to the drive.

Contact at a hinge: d = pin centre - hole centre, penetration delta = |d| - clearance. In
contact, n = d/|d|, the contact point is pc = pin centre + R_pin n, and with the relative
velocity w = v_pin(pc) - v_hole(pc) of the material points there, delta' = n.w and the slip
speed is v_t = t.w (t = n rotated by +90 deg). The pin feels F = -Fn n - mu(v_t) Fn t at pc,
the hole body the opposite.

Body frames: B's origin and centre of mass at its hole of hinge 3, its hinge-1 hole at
(0, -r1) and its hinge-2 pin at (r2, 0); C's centre at mid-length, hinge-2 hole at
(0, -Lc/2), hinge-4 pin at (0, +Lc/2); D turns about O with its hinge-4 hole at (r4, 0).
All numbers are parameters (presets.py holds our reference geometry).
"""

import math

import numpy as np
from pydantic import Field

from ...config import MM, Strict, numbers
from ...jit import njit
from .. import contact
from ..element import Derived, Element, Law, Quantity, State

# --- state of the linkage (positions, then rates) ----------------------------------------
PHI, XB, YB, TB, XC, YC, TC, TD = range(8)
N_POS = 8
N_LINK = 2 * N_POS
_POSITIONS = (
    ("actuator_angle_rad", "rad"),
    ("rocker_x_m", "m"),
    ("rocker_y_m", "m"),
    ("rocker_angle_rad", "rad"),
    ("link_x_m", "m"),
    ("link_y_m", "m"),
    ("link_angle_rad", "rad"),
    ("rudder_angle_rad", "rad"),
)
_RATES = (
    ("actuator_rate_rad_s", "rad/s"),
    ("rocker_vx_m_s", "m/s"),
    ("rocker_vy_m_s", "m/s"),
    ("rocker_rate_rad_s", "rad/s"),
    ("link_vx_m_s", "m/s"),
    ("link_vy_m_s", "m/s"),
    ("link_rate_rad_s", "rad/s"),
    ("rudder_rate_rad_s", "rad/s"),
)
LINK_STATES = tuple(
    State(f"linkage_{name}", unit, "linkage state (module docstring)", atol=1e-12)
    for name, unit in _POSITIONS + _RATES
)
LINK_STATE_NAMES = tuple(state.name for state in LINK_STATES)

# --- parameters (SI), filled by LinkageParams.pack ----------------------------------------
(
    A0X,
    A0Y,
    H3X,
    H3Y,
    OX,
    OY,
    L0,
    I_E,
    MASS_ROD,
    MASS_B,
    I_B,
    R1,
    R2,
    MASS_C,
    I_C,
    LC,
    J_D,
    R4,
    C_D,
    R_PIN,
    CLEAR,
) = range(21)
CONTACT = CLEAR + 4  # the contact law's packed parameters follow the four clearances
N_LINK_PARAMS = CONTACT + contact.N_CONTACT
_PARAMS = (  # (name, unit), in the order of the index constants above
    ("actuator_pivot_x_m", "m"),
    ("actuator_pivot_y_m", "m"),
    ("rocker_pivot_x_m", "m"),
    ("rocker_pivot_y_m", "m"),
    ("rudder_shaft_x_m", "m"),
    ("rudder_shaft_y_m", "m"),
    ("rod_length_m", "m"),
    ("actuator_inertia_kgm2", "kg m^2"),
    ("rod_mass_kg", "kg"),
    ("rocker_mass_kg", "kg"),
    ("rocker_inertia_kgm2", "kg m^2"),
    ("rocker_arm_1_m", "m"),
    ("rocker_arm_2_m", "m"),
    ("link_mass_kg", "kg"),
    ("link_inertia_kgm2", "kg m^2"),
    ("link_length_m", "m"),
    ("rudder_inertia_kgm2", "kg m^2"),
    ("rudder_arm_m", "m"),
    ("rudder_damping_Nms_per_rad", "N m s/rad"),
    ("pin_radius_m", "m"),
    *((f"hinge{h}_clearance_m", "m") for h in (1, 2, 3, 4)),
    ("contact_stiffness_SI", "N/m^e"),
    ("contact_exponent", "1"),
    ("contact_damping_Ns_per_m", "N s/m"),
    ("contact_penetration_depth_m", "m"),
    ("contact_mu_static", "1"),
    ("contact_mu_dynamic", "1"),
    ("contact_stiction_speed_m_s", "m/s"),
    ("contact_dynamic_speed_m_s", "m/s"),
)
assert len(_PARAMS) == N_LINK_PARAMS and contact.N_CONTACT == 8
LINKAGE_COLUMNS = (
    Quantity("linkage_rod_force_N", "N", "axial push of the linkage on the rod"),
    *(Quantity(f"hinge{h}_force_N", "N", f"normal force at hinge {h}") for h in (1, 2, 3, 4)),
    *(Quantity(f"hinge{h}_penetration_m", "m", f"penetration at hinge {h}") for h in (1, 2, 3, 4)),
)
# generalised forces gathered over the hinges, a tuple indexed by the body states PHI .. TD:
# the torque about the actuator pivot A0 (N m), the force (N) and moment (N m, about its
# origin) on the rocker B, on the link C (about its centre), the moment on the rocker arm D
# about O (N m). A tuple of locals, not rows of dy: the processor keeps them in registers, and
# each is summed in the order of the hinges as before

# bodies
GROUND, ROD, BODY_B, BODY_C, BODY_D = range(5)
N_HINGES = 4
# hinge h: (pin body, pin local x, y code, hole body, hole local code); local points by code
H1, H2, H3, H4 = range(4)


@njit(cache=True, inline="always", error_model="numpy")
def _local_point(hinge, on_pin, q):
    """Body-frame coordinates of a hinge's pin (on_pin) or hole on its body."""
    if hinge == H1:
        return (0.0, 0.0) if on_pin else (0.0, -q[R1])  # pin: rod end; hole: B
    if hinge == H3:
        return (q[H3X], q[H3Y]) if on_pin else (0.0, 0.0)  # pin: ground; hole: B
    if hinge == H2:
        return (q[R2], 0.0) if on_pin else (0.0, -0.5 * q[LC])  # pin: B; hole: C
    return (0.0, 0.5 * q[LC]) if on_pin else (q[R4], 0.0)  # H4 pin: C; hole: D


@njit(cache=True, inline="always", error_model="numpy")
def _hinge_bodies(hinge):
    """(pin body, hole body) of a hinge."""
    if hinge == H1:
        return ROD, BODY_B
    if hinge == H3:
        return GROUND, BODY_B
    if hinge == H2:
        return BODY_B, BODY_C
    return BODY_C, BODY_D


# the fields of a body's frame in the table built by _frames
F_RX, F_RY, F_VX, F_VY, F_COS, F_SIN, F_OMEGA = range(7)


@njit(cache=True, inline="always", error_model="numpy")
def _frames(y, s, s_dot, q):
    """Frame of every body, one tuple each: reference point, its velocity, cos and sin of the
    orientation, angular rate. The rod's frame sits at the rod end, turning with phi; the
    ground's is the identity at the origin (its points are given in world coordinates). A
    tuple of tuples, not an array: it lives in registers, and the right-hand side allocates
    nothing."""
    v = y[N_POS:]
    phi, w = y[PHI], v[PHI]
    r = q[L0] + s
    ux, uy = math.cos(phi), math.sin(phi)
    return (
        (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0),
        (
            q[A0X] + r * ux,
            q[A0Y] + r * uy,
            s_dot * ux - r * w * uy,
            s_dot * uy + r * w * ux,
            ux,
            uy,
            w,
        ),
        (y[XB], y[YB], v[XB], v[YB], math.cos(y[TB]), math.sin(y[TB]), v[TB]),
        (y[XC], y[YC], v[XC], v[YC], math.cos(y[TC]), math.sin(y[TC]), v[TC]),
        (q[OX], q[OY], 0.0, 0.0, math.cos(y[TD]), math.sin(y[TD]), v[TD]),
    )


@njit(cache=True, inline="always", error_model="numpy")
def _point(f, body, lx, ly):
    """World position of a body-fixed point (local lx, ly)."""
    frame = f[body]
    c, s = frame[F_COS], frame[F_SIN]
    return frame[F_RX] + c * lx - s * ly, frame[F_RY] + s * lx + c * ly


@njit(cache=True, inline="always", error_model="numpy")
def _velocity_at(f, body, px, py):
    """Velocity of the material point of ``body`` that is at (px, py)."""
    frame = f[body]
    w = frame[F_OMEGA]
    return frame[F_VX] - w * (py - frame[F_RY]), frame[F_VY] + w * (px - frame[F_RX])


@njit(cache=True, inline="always", error_model="numpy")
def _gap(hinge, f, q):
    """A hinge's geometry from the body frames: its pin's centre (x, y), the offset (dx, dy)
    of the pin's centre from the hole's, its length and the penetration (m)."""
    pin_body, hole_body = _hinge_bodies(hinge)
    lx, ly = _local_point(hinge, True, q)
    pin_x, pin_y = _point(f, pin_body, lx, ly)
    lx, ly = _local_point(hinge, False, q)
    hole_x, hole_y = _point(f, hole_body, lx, ly)
    dx, dy = pin_x - hole_x, pin_y - hole_y
    dist = math.sqrt(dx * dx + dy * dy)
    return pin_x, pin_y, dx, dy, dist, dist - q[CLEAR + hinge]


@njit(cache=True, inline="always", error_model="numpy")
def _contact(hinge, f, q, gap, power):
    """Contact of one hinge from the body frames, its _gap and the contact law's
    penetration_power of its penetration (see hinge_contact)."""
    pin_body, hole_body = _hinge_bodies(hinge)
    pin_x, pin_y, dx, dy, dist, delta = gap
    if delta <= 0.0:
        return 0.0, 0.0, pin_x, pin_y, delta, 0.0
    nx, ny = dx / dist, dy / dist
    px, py = pin_x + q[R_PIN] * nx, pin_y + q[R_PIN] * ny
    vpx, vpy = _velocity_at(f, pin_body, px, py)
    vhx, vhy = _velocity_at(f, hole_body, px, py)
    wx, wy = vpx - vhx, vpy - vhy
    c = q[CONTACT:]
    fn = contact.normal_force_of(power, delta, nx * wx + ny * wy, c)
    ft = -contact.friction_coefficient(-ny * wx + nx * wy, c) * fn
    return -fn * nx - ft * ny, -fn * ny + ft * nx, px, py, delta, fn


@njit(cache=True, error_model="numpy")
def hinge_contact(hinge, y, s, s_dot, q):
    """Contact of one hinge: (Fx, Fy) on the pin body at (px, py), penetration (m), |Fn| (N).

    Returns (fx, fy, px, py, delta, fn); zero force when the pin is clear of the hole wall.
    """
    f = _frames(y, s, s_dot, q)
    gap = _gap(hinge, f, q)
    return _contact(hinge, f, q, gap, contact.penetration_power(gap[5], q[CONTACT:]))


@njit(cache=True, inline="always", error_model="numpy")
def _apply(body, fx, fy, px, py, f, q, g):
    """The generalised forces g (see above) with a force at a point added to those of a body,
    and its push along the rod axis (N), which only the rod feels."""
    tau, fx_b, fy_b, m_b, fx_c, fy_c, m_c, m_d = g
    if body == GROUND:
        return g, 0.0
    if body == ROD:
        tau += (px - q[A0X]) * fy - (py - q[A0Y]) * fx
        return (tau, fx_b, fy_b, m_b, fx_c, fy_c, m_c, m_d), f[ROD][F_COS] * fx + f[ROD][F_SIN] * fy
    frame = f[body]
    moment = (px - frame[F_RX]) * fy - (py - frame[F_RY]) * fx
    if body == BODY_B:
        return (tau, fx_b + fx, fy_b + fy, m_b + moment, fx_c, fy_c, m_c, m_d), 0.0
    if body == BODY_C:
        return (tau, fx_b, fy_b, m_b, fx_c + fx, fy_c + fy, m_c + moment, m_d), 0.0
    return (tau, fx_b, fy_b, m_b, fx_c, fy_c, m_c, m_d + moment), 0.0


@njit(cache=True, inline="always", error_model="numpy")
def _hinge(h, f, q, hinges, g, axial, gap, power):
    """Hinge h's contact (its _gap and penetration_power given): its penetration and normal
    force into ``hinges``; return the generalised forces g with its force on its two bodies
    added, and ``axial`` plus its push along the rod axis (N), the pin's part added first,
    then the hole's."""
    fx, fy, px, py, delta, fn = _contact(h, f, q, gap, power)
    hinges[h, 0] = delta
    hinges[h, 1] = fn
    if fn == 0.0:
        return g, axial
    pin_body, hole_body = _hinge_bodies(h)
    g, push = _apply(pin_body, fx, fy, px, py, f, q, g)
    axial += push
    g, push = _apply(hole_body, -fx, -fy, px, py, f, q, g)
    axial += push
    return g, axial


@njit(cache=True, error_model="numpy")
def linkage_rhs(y, s, s_dot, rudder_torque, q, dy, hinges):
    """Write dy/dt of the linkage; return the axial force of the linkage on the rod (N).

    y: the 16 linkage states; s, s_dot: rod extension (m) and rate; rudder_torque: external
    torque on the rudder shaft (N m); q: linkage parameters. ``hinges`` (4 x 2) receives each
    hinge's penetration (m) and normal force (N).

    The integration waits for each right-hand side, so its time is the latency of this one:
    the hinges come one by one, each inlined with its bodies known (no call and no branch on
    the hinge; a loop over them calling the contact took 1.3x the time), and the four
    penetrations and their powers (libm's pow, the longest step) come first, together, so that
    the processor overlaps them (0.85x the time of each hinge calling its own). The sums are
    those of one hinge after the other, so the result is the same to the bit.
    """
    f = _frames(y, s, s_dot, q)
    c = q[CONTACT:]
    gap1, gap2, gap3, gap4 = _gap(H1, f, q), _gap(H2, f, q), _gap(H3, f, q), _gap(H4, f, q)
    power1 = contact.penetration_power(gap1[5], c)
    power2 = contact.penetration_power(gap2[5], c)
    power3 = contact.penetration_power(gap3[5], c)
    power4 = contact.penetration_power(gap4[5], c)
    g = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    g, axial = _hinge(H1, f, q, hinges, g, 0.0, gap1, power1)
    g, axial = _hinge(H2, f, q, hinges, g, axial, gap2, power2)
    g, axial = _hinge(H3, f, q, hinges, g, axial, gap3, power3)
    g, axial = _hinge(H4, f, q, hinges, g, axial, gap4, power4)
    tau, fx_b, fy_b, m_b, fx_c, fy_c, m_c, m_d = g
    v = y[N_POS:]
    r = q[L0] + s
    phi_dd = (tau - 2.0 * q[MASS_ROD] * r * s_dot * v[PHI]) / (q[I_E] + q[MASS_ROD] * r * r)
    for i in range(N_POS):
        dy[i] = v[i]
    dy[N_POS + PHI] = phi_dd
    dy[N_POS + XB] = fx_b / q[MASS_B]
    dy[N_POS + YB] = fy_b / q[MASS_B]
    dy[N_POS + TB] = m_b / q[I_B]
    dy[N_POS + XC] = fx_c / q[MASS_C]
    dy[N_POS + YC] = fy_c / q[MASS_C]
    dy[N_POS + TC] = m_c / q[I_C]
    dy[N_POS + TD] = (m_d - q[C_D] * v[TD] + rudder_torque) / q[J_D]
    return axial


def _circle_intersections(c1, r1, c2, r2, near) -> np.ndarray:
    """For each row: the intersection point of the circle of radius r1 about c1 with the one
    of radius r2 about c2 that lies closest to ``near``; NaN where the circles do not meet.
    Points are (n, 2) arrays or one (2,) point for all rows; radii (n,) arrays or numbers.

    With d = |c2 - c1|, the chord's foot lies a = (r1^2 - r2^2 + d^2) / (2 d) from c1 along
    c2 - c1, and the two points h = sqrt(r1^2 - a^2) to either side of it.
    """
    c1, c2, near = (np.asarray(p, dtype=float) for p in (c1, c2, near))
    along = c2 - c1
    d = _lengths(along)
    meet = (d > 0) & (d <= r1 + r2) & (d >= np.abs(r1 - r2))
    with np.errstate(divide="ignore", invalid="ignore"):  # rows that do not meet
        a = (_square(r1) - _square(r2) + _square(d)) / (2 * d)
        h = np.sqrt(np.maximum(_square(r1) - _square(a), 0.0))
        mid = c1 + a[..., None] * along / d[..., None]
        perp = np.stack([-along[..., 1], along[..., 0]], axis=-1) / d[..., None]
    plus, minus = mid + h[..., None] * perp, mid - h[..., None] * perp
    nearer = _lengths(plus - near) <= _lengths(minus - near)
    points = np.where(nearer[..., None], plus, minus)
    return np.where(meet[..., None], points, np.nan)


# Rounded as the kinematics were when they took one point at a time, so that the rudder
# tables, and the runs that follow them, keep their last bits: a length as np.linalg.norm of
# one point (a dot product), a square as a scalar's ** 2 (libm's pow, which differs from x * x
# in the last bit for about 0.1 % of numbers), the angles and their sines by libm (numpy's own
# arctan2 differs from it in the last bit for about 2 % of these points). Each by libm itself,
# never by a numpy ufunc: numpy picks its float64 pow and arctan2 by the processor (SVML where
# it finds AVX-512, X86_V4), so np.float_power gave other last bits on such a machine.


def _lengths(v: np.ndarray) -> np.ndarray:
    """|v| of each row of an (n, 2) array."""
    return np.sqrt((v[..., None, :] @ v[..., :, None])[..., 0, 0])


_square = np.vectorize(lambda x: math.pow(x, 2), otypes=[float])
_atan2 = np.vectorize(math.atan2, otypes=[float])
_cos = np.vectorize(math.cos, otypes=[float])
_sin = np.vectorize(math.sin, otypes=[float])


def rigid_poses(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(n, 16): the linkage states with every clearance closed, at rest, at each rod
    extension of s (m); a row of NaN where the geometry cannot close.

    Rigid kinematics: the rod end is at L0 + s from A0 and r1 from B's pivot H3; B's hinge-2
    pin is then fixed, and the link's other end is Lc from it and r4 from O.
    """
    s = np.atleast_1d(np.asarray(s, dtype=float))
    a0, h3, o = q[[A0X, A0Y]], q[[H3X, H3Y]], q[[OX, OY]]
    p1 = _circle_intersections(a0, q[L0] + s, h3, q[R1], near=h3 + [0.0, -q[R1]])
    theta_b = _atan2(p1[:, 0] - h3[0], -(p1[:, 1] - h3[1]))  # hole at (0, -r1) turned
    p2 = h3 + q[R2] * np.stack([_cos(theta_b), _sin(theta_b)], axis=-1)
    p4 = _circle_intersections(p2, q[LC], o, q[R4], near=o + [q[R4], 0.0])
    y = np.zeros((s.size, N_LINK))
    y[:, PHI] = _atan2(p1[:, 1] - a0[1], p1[:, 0] - a0[0])
    y[:, XB], y[:, YB], y[:, TB] = h3[0], h3[1], theta_b
    y[:, XC], y[:, YC] = (0.5 * (p2 + p4)).T
    y[:, TC] = _atan2(p4[:, 1] - p2[:, 1], p4[:, 0] - p2[:, 0]) - 0.5 * math.pi
    y[:, TD] = _atan2(p4[:, 1] - o[1], p4[:, 0] - o[0])
    y[np.isnan(p1[:, 0]) | np.isnan(p4[:, 0])] = np.nan
    return y


def rigid_pose(s: float, q: np.ndarray) -> np.ndarray:
    """The 16 linkage states with every clearance closed, at rod extension s (m), at rest
    (:func:`rigid_poses`); ValueError where the geometry cannot close."""
    return _closed(rigid_poses(s, q))[0]


def rudder_angle_of_extension(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rigid-kinematics rudder angle (rad) for rod extensions s (m); ValueError where the
    geometry cannot close."""
    return _closed(rigid_poses(s, q))[:, TD]


def _closed(poses: np.ndarray) -> np.ndarray:
    if np.isnan(poses).any():
        raise ValueError("linkage geometry cannot close at this rod extension")
    return poses


Point_mm = numbers(2, ge=-1e4, le=1e4)  # (x, y) in mm, within 10 m of the origin


class LinkageParams(Strict):
    """The linkage, in mm, kg and kg m^2 (see the module docstring for the frames)."""

    actuator_pivot_mm: Point_mm = Field(description="A0, bearing housing 1")
    rocker_pivot_mm: Point_mm = Field(description="H3, bearing housing 3")
    rudder_shaft_mm: Point_mm = Field(description="O, bearing housings 1/2")
    rod_length_mm: float = Field(gt=0, le=1e4, description="L0: A0 to the rod end at mid stroke")
    actuator_inertia_kgm2: float = Field(gt=0, le=1e4, description="I_E: actuator body about A0")
    rod_mass_kg: float = Field(gt=0, le=1e4)
    rocker_mass_kg: float = Field(gt=0, le=1e4)
    rocker_inertia_kgm2: float = Field(gt=0, le=1e4)
    rocker_arm_1_mm: float = Field(gt=0, le=1e4, description="r1: H3 to hinge 1")
    rocker_arm_2_mm: float = Field(gt=0, le=1e4, description="r2: H3 to hinge 2")
    link_mass_kg: float = Field(gt=0, le=1e4)
    link_inertia_kgm2: float = Field(gt=0, le=1e4)
    link_length_mm: float = Field(gt=0, le=1e4, description="Lc: hinge 2 to hinge 4")
    rudder_inertia_kgm2: float = Field(gt=0, le=1e4, description="J_D: rocker arm, rudder, disk")
    rudder_arm_mm: float = Field(gt=0, le=1e4, description="r4: O to hinge 4")
    rudder_damping_Nms_per_rad: float = Field(ge=0, le=1e6)
    pin_radius_mm: float = Field(gt=0, le=1e3)
    hinge_clearance_mm: numbers(N_HINGES, ge=0, le=10) = Field(
        description="radial clearance of hinges 1, 2, 3, 4"
    )
    contact: contact.ContactParams

    def pack(self) -> np.ndarray:
        """The flat SI array read by :func:`linkage_rhs`."""
        q = np.zeros(N_LINK_PARAMS)
        q[[A0X, A0Y]] = np.array(self.actuator_pivot_mm) * MM
        q[[H3X, H3Y]] = np.array(self.rocker_pivot_mm) * MM
        q[[OX, OY]] = np.array(self.rudder_shaft_mm) * MM
        q[L0] = self.rod_length_mm * MM
        q[I_E], q[MASS_ROD] = self.actuator_inertia_kgm2, self.rod_mass_kg
        q[MASS_B], q[I_B] = self.rocker_mass_kg, self.rocker_inertia_kgm2
        q[R1], q[R2] = self.rocker_arm_1_mm * MM, self.rocker_arm_2_mm * MM
        q[MASS_C], q[I_C] = self.link_mass_kg, self.link_inertia_kgm2
        q[LC] = self.link_length_mm * MM
        q[J_D], q[R4] = self.rudder_inertia_kgm2, self.rudder_arm_mm * MM
        q[C_D] = self.rudder_damping_Nms_per_rad
        q[R_PIN] = self.pin_radius_mm * MM
        clearance = np.array(self.hinge_clearance_mm) * MM
        q[[CLEAR + H1, CLEAR + H2, CLEAR + H3, CLEAR + H4]] = clearance
        q[CONTACT:] = self.contact.pack()
        return q


# --- the rudder side's coupling to the rod: the lumped stage, the linkage, or held ---------
LOAD_LUMPED = 0  # the rod and a lumped rudder stage: rudder angle = rod position / arm
LOAD_LINKAGE = 1  # the rod alone; the linkage carries the rudder
LOAD_HELD = 2  # the rod alone; the rudder side is solved elsewhere (a co-simulation's mechanism)
# and its states are held in x between exchanges


@njit(cache=True, inline="always", error_model="numpy")
def rocker_motion(load_model, s, s_dot, arm, angle, rate):
    """The rocker arm's angle (rad) and rate (rad/s): the linkage's (integrated, or held by a
    co-simulation), or the rod's (s, s_dot) through the lumped stage's arm."""
    if load_model != LOAD_LUMPED:
        return angle, rate
    return s / arm, s_dot / arm


@njit(cache=True, inline="always", error_model="numpy")
def rocker_reaction(torque, load_model, s, s_dot, arm, x, p, dx, x0, p0, hinges):
    """What the torque on the rocker arm (N m, driving positive deflection) does to the rod:
    (the linkage's axial push in N, the lumped stage's push in N, an acceleration in m/s^2).
    Lumped stage: torque / arm. Linkage: its right-hand side (its states y = x[x0:], its
    parameters q = p[p0:], its rates written into dx[x0:], the hinges into ``hinges``), its
    axial push, and the centripetal r phi'^2 of the swinging rod (r = L0 + s). Held: nothing
    (a co-simulation solves the rudder side). The two pushes are kept apart because the rod's
    equation sums them at different places (emasim.plant.elements.rod). The slices are made
    here, with the linkage alone: views made at every call of the right-hand side slowed the
    loop of every plant without the linkage (benchmarks/bench_paired.py). On the bench they
    cost about 30 ns of a right-hand side's 190 (their reference counts); handing the
    linkage the plant's whole arrays with these offsets instead measured slower (216 against
    187 ns a call, interleaved, in one process), so the views stay."""
    if load_model == LOAD_LUMPED:
        return 0.0, torque / arm, 0.0
    if load_model == LOAD_HELD:
        return 0.0, 0.0, 0.0
    y, q = x[x0 : x0 + N_LINK], p[p0 : p0 + N_LINK_PARAMS]
    axial = linkage_rhs(y, s, s_dot, torque, q, dx[x0 : x0 + N_LINK], hinges)
    swing = y[N_POS + PHI]
    return axial, 0.0, (q[L0] + s) * swing * swing


@njit(cache=True, inline="always", error_model="numpy")
def linkage_columns(y, s, s_dot, q):
    """The linkage's outputs (LINKAGE_COLUMNS) of state y: its axial push on the rod (N), the
    hinges' normal forces (N) and penetrations (m), hinges 1 to 4."""
    hinges = np.empty((N_HINGES, 2))
    axial = linkage_rhs(y, s, s_dot, 0.0, q, np.empty(N_LINK), hinges)
    return (
        axial,
        hinges[H1, 1],
        hinges[H2, 1],
        hinges[H3, 1],
        hinges[H4, 1],
        hinges[H1, 0],
        hinges[H2, 0],
        hinges[H3, 0],
        hinges[H4, 0],
    )


def _pack(plant) -> dict[str, float]:
    """The linkage's parameters, with the rudder inertia of the whole plant on the rocker arm
    (PlantParams.rudder_inertia_kgm2: the load motor's rotor joins it without the rudder
    shaft's torsion)."""
    q = plant.linkage.pack()
    q[J_D] = plant.rudder_inertia_kgm2
    return dict(zip((f"linkage_{name}" for name, _ in _PARAMS), q, strict=True))


LINKAGE = Element(
    "linkage",
    "planar bodies tied by four clearance-joint hinges (ADAMS model)",
    states=LINK_STATES,
    params=tuple(Quantity(f"linkage_{name}", unit) for name, unit in _PARAMS),
    outputs=LINKAGE_COLUMNS,
    presence="load_model",  # LOAD_LINKAGE, or LOAD_HELD (the states held), a parameter of the rod
    derived=(
        Derived(
            "rocker",
            motion=Law(
                rocker_motion,
                (
                    "p.load_model",
                    "rod.x",
                    "rod.v",
                    "p.rudder_arm_m",
                    f"x.{LINK_STATE_NAMES[TD]}",
                    f"x.{LINK_STATE_NAMES[N_POS + TD]}",
                ),
                ("x", "v"),
            ),
            fold=Law(
                rocker_reaction,
                (
                    "rocker.f",
                    "p.load_model",
                    "rod.x",
                    "rod.v",
                    "p.rudder_arm_m",
                    "x",
                    "p",
                    "dx",
                    "x0[linkage]",
                    "p0[linkage]",
                    "hinges",
                ),
                ("axial", "lever", "swing"),
            ),
            onto=("rod", "rod", "rod.a"),
            exchange="axial",
        ),
    ),
    laws=(
        Law(
            linkage_columns,
            ("x[linkage]", "rod.x", "rod.v", "p[linkage]"),
            tuple(q.name for q in LINKAGE_COLUMNS),
        ),
    ),
    values=tuple((q.name, q.name) for q in LINKAGE_COLUMNS),
    mechanism=True,
    after="load_motor",
    section="linkage",
    config=LinkageParams,
    pack=lambda plant: _pack(plant),
    initial=lambda plant: dict(
        zip(LINK_STATE_NAMES, rigid_pose(0.0, plant.linkage.pack()), strict=True)
    ),
    stage="linkage",
)
