"""Friction laws of the drive: LuGre (dynamic) and a smoothed Coulomb + viscous map.

The LuGre model (Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE TAC 40(3), 1995):

    g(v)  = Fc + (Fs - Fc) * exp(-(v / vs)**2)          Stribeck curve
    dz/dt = v - sigma0 * |v| * z / g(v)                 bristle deflection
    Ff    = sigma0 * z + sigma1 * dz/dt + sigma2 * v    friction force

The functions are unit-agnostic: in translation v is m/s, z m, F N, sigma0 N/m; on the motor
shaft (the default use in emasim) v is rad/s, z rad, F N*m and sigma0 N*m/rad.

The bristle state is stiff at speed: its eigenvalue is -sigma0*|v|/g(v). With v frozen over a
step h the bristle equation is linear in z and has the exact solution used by
:func:`bristle_update`, which is stable for any h.
"""

import math

from ...jit import njit
from ..element import (
    FAR_RUNAWAY,
    RK4_OSCILLATOR_LIMIT,
    Element,
    Law,
    Quantity,
    State,
    damping_for_ratio,
)

FRICTION_NONE = 0
FRICTION_COULOMB = 1
FRICTION_LUGRE = 2

EXP_ZERO = 746.0  # exp(-x) rounds to exactly 0.0 for x > 745.14


@njit(cache=True, inline="always", error_model="numpy")
def stribeck(v, fc, fs, vs):
    """Stribeck curve g(v) = Fc + (Fs - Fc) exp(-(v/vs)^2), the steady sliding friction level.

    Far above the Stribeck speed the exponential is exactly 0.0 in double precision, and the
    C library computes that underflow on a slow path that sets errno (15 % of the lumped
    loop at 1000 rpm, in ``perf``); so beyond EXP_ZERO the curve returns Fc directly, the
    same value bit for bit."""
    r = v / vs
    r2 = r * r
    if r2 > EXP_ZERO:
        return fc
    return fc + (fs - fc) * math.exp(-r2)


@njit(cache=True, inline="always", error_model="numpy")
def bristle_rate(z, v, fc, fs, vs, sigma0):
    """LuGre bristle rate dz/dt = v - sigma0 |v| z / g(v)."""
    return v - sigma0 * abs(v) * z / stribeck(v, fc, fs, vs)


@njit(cache=True, inline="always", error_model="numpy")
def lugre_force(z, v, fc, fs, vs, sigma0, sigma1, sigma2):
    """LuGre friction force Ff = sigma0 z + sigma1 dz/dt + sigma2 v, returned with dz/dt."""
    z_rate = bristle_rate(z, v, fc, fs, vs, sigma0)
    return sigma0 * z + sigma1 * z_rate + sigma2 * v, z_rate


@njit(cache=True, inline="always", error_model="numpy")
def bristle_update(z0, v, h, fc, fs, vs, sigma0):
    """Bristle state after a step h with the velocity v held constant (exact solution).

    With a = sigma0 |v| / g(v) the bristle equation reads dz/dt = v - a z, so

        z(h) = z_ss + (z0 - z_ss) * exp(-a h),   z_ss = v / a = g(v) sign(v) / sigma0,

    and for v = 0 the state does not move. For a*h << 1 this tends to z0 + (v - a z0) h
    (explicit Euler); for a*h >> 1 it lands on the steady state z_ss: stable for any h.
    """
    a = sigma0 * abs(v) / stribeck(v, fc, fs, vs)
    if a == 0.0:  # v = 0, or so small that sigma0 |v| underflows
        return z0
    z_ss = v / a
    return z_ss + (z0 - z_ss) * math.exp(-a * h)


@njit(cache=True, inline="always", error_model="numpy")
def bristle_half_and_full_step(z0, v, h, fc, fs, vs, sigma0):
    """Exact bristle state after h/2 and after h with v held: (z(h/2), z(h)), one exp."""
    a = sigma0 * abs(v) / stribeck(v, fc, fs, vs)
    if a == 0.0:
        return z0, z0
    z_ss = v / a
    decay = math.exp(-0.5 * a * h)
    z_half = z_ss + (z0 - z_ss) * decay
    return z_half, z_ss + (z0 - z_ss) * decay * decay


@njit(cache=True, inline="always", error_model="numpy")
def coulomb_viscous_force(v, fc, v_smooth, sigma2):
    """Static map Ff = Fc tanh(v / v_smooth) + sigma2 v.

    tanh replaces sign(v) so that the right-hand side stays Lipschitz; v_smooth is the
    speed below which friction fades out (a stand-in for stiction, which this map cannot hold).
    """
    return fc * math.tanh(v / v_smooth) + sigma2 * v


@njit(cache=True, inline="always", error_model="numpy")
def asymmetric_coulomb_viscous_force(v, fc_pos, fv_pos, fc_neg, fv_neg, v_smooth):
    """Static map with a Coulomb and a viscous coefficient for each direction:

        Ff = Fc+ tanh(v / v_smooth) + Fv+ v   for v >= 0
        Ff = Fc- tanh(v / v_smooth) + Fv- v   for v < 0

    (Janot, Young, Gautier, Int. J. Control 90(4), 2017, eq. 12 of the EMPS description, with
    tanh for sign as in :func:`coulomb_viscous_force`, which it equals for equal coefficients).
    Continuous at v = 0, where both branches are 0."""
    if v >= 0.0:
        return coulomb_viscous_force(v, fc_pos, v_smooth, fv_pos)
    return coulomb_viscous_force(v, fc_neg, v_smooth, fv_neg)


@njit(cache=True, inline="always", error_model="numpy")
def friction_torque(w, z, model, fc, fs, ws, sigma0, sigma1, sigma2, w_smooth):
    """Friction torque on the shaft (N m) at speed w and bristle state z, and the bristle rate
    dz/dt (rad/s, zero but for the LuGre model), for the model FRICTION_*."""
    if model == FRICTION_LUGRE:
        return lugre_force(z, w, fc, fs, ws, sigma0, sigma1, sigma2)
    if model == FRICTION_COULOMB:
        return coulomb_viscous_force(w, fc, w_smooth, sigma2), 0.0
    return 0.0, 0.0


def bristle_damping_for_ratio(zeta: float, sigma0: float, inertia: float, sigma2: float) -> float:
    """sigma1 giving damping ratio zeta to the presliding (bristle) mode on a given inertia.

    sigma1 = 2 zeta sqrt(sigma0 * J) - sigma2 (Astrom & Canudas de Wit, IEEE CSM 28(6), 2008).
    The 1995 choice sigma1 = sqrt(sigma0) holds only for a 1 kg mass. Raises ValueError if the
    result is negative (sigma2 alone already over-damps the mode at that zeta).
    """
    sigma1 = damping_for_ratio(zeta, sigma0, inertia) - sigma2
    if sigma1 < 0.0:
        raise ValueError(
            f"friction.bristle_damping_ratio={zeta} gives sigma1 < 0 with sigma2={sigma2}; "
            "raise the ratio or lower sigma2"
        )
    return sigma1


FRICTION_MODELS = {"none": FRICTION_NONE, "coulomb": FRICTION_COULOMB, "lugre": FRICTION_LUGRE}


def _pack(f, inertia: float) -> dict[str, float]:
    """The friction's parameters from its section f (FrictionParams) and the inertia the
    bristles carry (kg m^2): sigma1 from the damping ratio of the presliding mode."""
    return {
        "friction_model": FRICTION_MODELS[f.model],
        "coulomb_Nm": f.coulomb_Nm,
        "static_Nm": f.static_Nm,
        "stribeck_speed_rad_s": f.stribeck_speed_rad_s,
        "bristle_stiffness_Nm_per_rad": f.bristle_stiffness_Nm_per_rad,
        "bristle_damping_Nms_per_rad": bristle_damping_for_ratio(
            f.bristle_damping_ratio, f.bristle_stiffness_Nm_per_rad, inertia, f.viscous_Nms_per_rad
        ),
        "friction_viscous_Nms_per_rad": f.viscous_Nms_per_rad,
        "smoothing_speed_rad_s": f.smoothing_speed_rad_s,
    }


FRICTION = Element(
    "friction",
    "friction on the motor shaft: LuGre, Coulomb + viscous, or none",
    states=(
        State(
            "bristle_state_rad",
            "rad",
            "LuGre bristle deflection (split off RK4, updated exactly)",
            atol=1e-15,
            bound=lambda plant: (
                FAR_RUNAWAY
                * max(plant.friction.static_Nm, 1e-3)
                / plant.friction.bristle_stiffness_Nm_per_rad
            ),
        ),
    ),
    params=(
        Quantity("friction_model", "1", "FRICTION_NONE, FRICTION_COULOMB or FRICTION_LUGRE"),
        Quantity("coulomb_Nm", "N m", "Tc"),
        Quantity("static_Nm", "N m", "Ts"),
        Quantity("stribeck_speed_rad_s", "rad/s", "ws"),
        Quantity("bristle_stiffness_Nm_per_rad", "N m/rad", "sigma0"),
        Quantity("bristle_damping_Nms_per_rad", "N m s/rad", "sigma1"),
        Quantity("friction_viscous_Nms_per_rad", "N m s/rad", "sigma2"),
        Quantity("smoothing_speed_rad_s", "rad/s", "Coulomb map: tanh(w/ws) for sign(w)"),
    ),
    outputs=(Quantity("friction_torque_Nm", "N m", "friction torque on the motor shaft"),),
    laws=(
        Law(
            friction_torque,
            (
                "motor.v",
                "x.bristle_state_rad",
                "p.friction_model",
                "p.coulomb_Nm",
                "p.static_Nm",
                "p.stribeck_speed_rad_s",
                "p.bristle_stiffness_Nm_per_rad",
                "p.bristle_damping_Nms_per_rad",
                "p.friction_viscous_Nms_per_rad",
                "p.smoothing_speed_rad_s",
            ),
            ("torque", "bristle_rate"),
        ),
    ),
    forces=(("motor", "-torque"),),
    after="motor",
    section="friction",
    pack=lambda plant: _pack(plant.friction, plant.motor.inertia_kgm2),
    rates=(("bristle_state_rad", "bristle_rate"),),
    values=(("friction_torque_Nm", "torque"),),
    modes=lambda value, mass: (
        [
            (
                "the LuGre bristle stiffness",
                math.sqrt(value("bristle_stiffness_Nm_per_rad") / value("rotor_inertia_kgm2")),
                RK4_OSCILLATOR_LIMIT,
            )
        ]
        if value("friction_model") == FRICTION_LUGRE
        else []
    ),
)
