"""Permanent-magnet synchronous motor in the rotor dq frame, with an averaged inverter.

    did/dt = (ud - Rs id + we Lq iq) / Ld
    diq/dt = (uq - Rs iq - we (Ld id + psi_f)) / Lq
    Te     = 1.5 np (psi_f iq + (Ld - Lq) id iq)
    we     = np wm

(SI: V, A, ohm, H, Wb, rad/s, N*m; amplitude-invariant Park transform, hence the 1.5.) The
mechanical equation J dwm/dt = Te - TL - B wm - Tf is assembled in :mod:`emasim.plant.actuator`
because its load comes from the drive train. The inverter is averaged: it delivers the commanded
voltage vector, limited in magnitude to the largest sine a space-vector modulator reaches,
|u_dq| <= Udc / sqrt(3), and it cannot exceed its current: at |i_dq| >= max_current_A its hardware
current limit (the cycle-by-cycle chopping of a drive's PWM stage, averaged over the PWM period)
takes away the part of the command that would grow the current (:func:`inverter_current_rates`).
Only a back-EMF beyond what the bus can oppose still drives the current past it, through the
inverter's diodes, as it would on the drive (emasim.analysis.report.limits_crossed reports it).
"""

import math

from ...config import MM, RPM
from ...jit import njit
from ...numerics import limit_magnitude
from ..element import (
    FAR_RUNAWAY,
    RATED_RUNAWAY,
    RK4_DECAY_LIMIT,
    Body,
    Element,
    Law,
    Quantity,
    State,
    viscous_force,
)


@njit(cache=True, inline="always", error_model="numpy")
def current_rates(i_d, i_q, u_d, u_q, w_e, rs, ld, lq, psi_f):
    """Return (did/dt, diq/dt) in A/s from the dq voltage equations."""
    did = (u_d - rs * i_d + w_e * lq * i_q) / ld
    diq = (u_q - rs * i_q - w_e * (ld * i_d + psi_f)) / lq
    return did, diq


@njit(cache=True, inline="always", error_model="numpy")
def electromagnetic_torque(i_d, i_q, pole_pairs, ld, lq, psi_f):
    """Te = 1.5 np (psi_f iq + (Ld - Lq) id iq) in N*m."""
    return 1.5 * pole_pairs * (psi_f * i_q + (ld - lq) * i_d * i_q)


@njit(cache=True, inline="always", error_model="numpy")
def limit_voltage(u_d, u_q, u_dc):
    """Scale (ud, uq) so that |u| <= Udc/sqrt(3), keeping its direction (averaged SVPWM)."""
    return limit_magnitude(u_d, u_q, u_dc / math.sqrt(3.0))


@njit(cache=True, inline="always", error_model="numpy")
def inverter_current_rates(i_d, i_q, u_d, u_q, w_e, rs, ld, lq, psi_f, i_max, u_dc):
    """(did/dt, diq/dt) in A/s for the commanded (ud, uq), through the inverter's current limit.

    Below i_max the command acts as it is. At |i| >= i_max, when the command would grow the
    current (g = id did/dt + iq diq/dt = |i| d|i|/dt > 0), the inverter applies instead

        u = (ud, uq) - (g / |i|^2) (Ld id, Lq iq),  limited to |u| <= Udc/sqrt(3),

    the command less the part along the current, which leaves d|i|/dt = 0: the current is held
    at i_max. Where that voltage is beyond the bus (a back-EMF the inverter cannot oppose), the
    limited voltage lets the current grow, as the drive's diodes would.
    """
    did, diq = current_rates(i_d, i_q, u_d, u_q, w_e, rs, ld, lq, psi_f)
    i_sq = i_d * i_d + i_q * i_q
    if i_sq < i_max * i_max:
        return did, diq
    growth = i_d * did + i_q * diq
    if growth <= 0.0:
        return did, diq
    cut = growth / i_sq
    v_d, v_q = limit_voltage(u_d - cut * ld * i_d, u_q - cut * lq * i_q, u_dc)
    return current_rates(i_d, i_q, v_d, v_q, w_e, rs, ld, lq, psi_f)


@njit(cache=True, inline="always", error_model="numpy")
def stator_rates(i_d, i_q, u_d, u_q, w, pole_pairs, rs, ld, lq, psi_f, i_max, u_dc):
    """inverter_current_rates at the electrical speed w_e = np w of the shaft speed w."""
    return inverter_current_rates(
        i_d, i_q, u_d, u_q, pole_pairs * w, rs, ld, lq, psi_f, i_max, u_dc
    )


def torque_constant(pole_pairs: float, psi_f: float) -> float:
    """kt = 1.5 np psi_f (N*m/A): torque per q-axis ampere with id = 0."""
    return 1.5 * pole_pairs * psi_f


def _current_bound(plant) -> float:
    return RATED_RUNAWAY * plant.motor.max_current_A


def shaft_angle_bound(plant) -> float:
    """A shaft angle seen at the motor (rad) this far out is a runaway: FAR_RUNAWAY strokes."""
    return FAR_RUNAWAY * plant.drivetrain.stroke_mm * MM / plant.ratio_m_per_rad


def shaft_speed_bound(plant) -> float:
    """A shaft speed seen at the motor (rad/s) this fast is a runaway: RATED_RUNAWAY times the
    speed limit."""
    return RATED_RUNAWAY * plant.motor.max_speed_rpm * RPM


_STATOR = (  # the stator's parameters, in the order stator_rates takes them
    "p.stator_resistance_ohm",
    "p.inductance_d_H",
    "p.inductance_q_H",
    "p.flux_linkage_Wb",
    "p.max_current_A",
    "p.dc_bus_V",
)

MOTOR = Element(
    "motor",
    "PMSM in dq with the averaged inverter",
    states=(
        State("id_A", "A", "d-axis current", atol=1e-9, bound=_current_bound),
        State("iq_A", "A", "q-axis current", atol=1e-9, bound=_current_bound),
        State(
            "motor_angle_rad",
            "rad",
            "motor shaft angle",
            atol=1e-11,
            bound=shaft_angle_bound,
        ),
        State(
            "motor_speed_rad_s",
            "rad/s",
            "motor mechanical speed",
            atol=1e-9,
            bound=shaft_speed_bound,
        ),
    ),
    params=(
        Quantity("stator_resistance_ohm", "ohm", "Rs"),
        Quantity("inductance_d_H", "H", "Ld"),
        Quantity("inductance_q_H", "H", "Lq"),
        Quantity("flux_linkage_Wb", "Wb", "psi_f"),
        Quantity("pole_pairs", "1", "np"),
        Quantity("rotor_inertia_kgm2", "kg m^2", "J"),
        Quantity("motor_viscous_Nms_per_rad", "N m s/rad", "B"),
        Quantity("dc_bus_V", "V", "Udc"),
        Quantity(
            "max_current_A",
            "A",
            "the drive's current limit, held on every command and by the inverter on |i_dq|",
        ),
        Quantity("max_speed_rad_s", "rad/s", "the drive's speed limit, held on every command"),
    ),
    outputs=(Quantity("torque_Nm", "N m", "electromagnetic torque Te"),),
    # the rotor (and what turns rigidly with it): J dw/dt = Te - B w - T_friction - TL - T_nut
    bodies=(
        Body(
            "motor",
            "motor_angle_rad",
            "motor_speed_rad_s",
            "rotor_inertia_kgm2",
            order=("motor", "friction", "t_load", "transmission"),
        ),
    ),
    laws=(
        Law(
            stator_rates,
            ("x.id_A", "x.iq_A", "in.u_d", "in.u_q", "motor.v", "p.pole_pairs", *_STATOR),
            ("did", "diq"),
        ),
        Law(
            electromagnetic_torque,
            ("x.id_A", "x.iq_A", "p.pole_pairs", *_STATOR[1:4]),
            ("torque",),
        ),
        Law(viscous_force, ("p.motor_viscous_Nms_per_rad", "motor.v"), ("viscous",)),
    ),
    forces=(("motor", "+torque"), ("motor", "-viscous"), ("motor", "-in.t_load")),
    section="motor",
    pack=lambda plant: {
        "stator_resistance_ohm": plant.motor.resistance_ohm,
        "inductance_d_H": plant.motor.inductance_d_H,
        "inductance_q_H": plant.motor.inductance_q_H,
        "flux_linkage_Wb": plant.motor.flux_linkage_Wb,
        "pole_pairs": plant.motor.pole_pairs,
        "rotor_inertia_kgm2": plant.motor.inertia_kgm2,
        "motor_viscous_Nms_per_rad": plant.motor.viscous_Nms_per_rad,
        "dc_bus_V": plant.motor.dc_bus_V,
        "max_current_A": plant.motor.max_current_A,
        "max_speed_rad_s": plant.motor.max_speed_rpm * RPM,
    },
    rates=(("id_A", "did"), ("iq_A", "diq")),
    values=(("torque_Nm", "torque"),),
    modes=lambda value, mass: [
        (
            "the stator time constant L/R",
            value("stator_resistance_ohm") / min(value("inductance_d_H"), value("inductance_q_H")),
            RK4_DECAY_LIMIT,
        )
    ],
)
