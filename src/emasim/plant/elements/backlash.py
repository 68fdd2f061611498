"""Backlash: the dead-zone contact law between two bodies, and the play (hysteresis) operator.

Dead zone (force/torque form), total gap width 2b, relative displacement dx, rate dv:

    Fc = K (dx - b)   if dx >  b
    Fc = 0            if |dx| <= b
    Fc = K (dx + b)   if dx < -b

plus a damping force c dv that acts only in contact and is limited to |c dv| <= |Fc| (the
Modelica ElastoBacklash rule): the total force is continuous at first contact and never pulls
the bodies together.

Play operator (position form), for a position read through a gap of half-width b:

    y = l x - b   if l x - b >= y_prev
    y = l x + b   if l x + b <= y_prev
    y = y_prev    otherwise

(the paper's eq. 17, read cleanly; l is a gain, 1 by default).
"""

from ...config import MM
from ...jit import njit
from ..element import (
    CLOSED_OVERLAP,
    RK4_OSCILLATOR_LIMIT,
    Coupling,
    Element,
    Quantity,
    damping_for_ratio,
    two_body_rate,
)


@njit(cache=True, inline="always", error_model="numpy")
def dead_zone_force(dx, dv, half_gap, stiffness, damping):
    """Contact force of a backlash element (N or N*m), positive when dx > half_gap.

    Parameters: dx relative displacement and dv its rate (m, m/s or rad, rad/s), half_gap b,
    stiffness K and damping c of the contact. Returns Fc + limited damping as described in the
    module docstring.
    """
    if dx > half_gap:
        spring = stiffness * (dx - half_gap)
        return spring + min(max(damping * dv, -spring), spring)
    if dx < -half_gap:
        spring = stiffness * (dx + half_gap)
        return spring + min(max(damping * dv, spring), -spring)
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def play_operator(x, y_prev, half_gap, gain):
    """Output of the play operator for input x, previous output y_prev (see module docstring)."""
    lx = gain * x
    if lx - half_gap >= y_prev:
        return lx - half_gap
    if lx + half_gap <= y_prev:
        return lx + half_gap
    return y_prev


def _pack(plant) -> dict[str, float]:
    """The gap's parameters: its damping c = 2 zeta sqrt(K m_r) on the reduced mass m_r of the
    motor seen at the nut (J / K^2) and the body beyond the gap (the compliance's node, else
    the load)."""
    b = plant.backlash
    motor_mass = plant.motor.inertia_kgm2 / plant.ratio_m_per_rad**2  # kg, at the nut
    beyond_gap = plant.load_mass_kg if plant.compliance is None else plant.compliance.node_mass_kg
    reduced = motor_mass * beyond_gap / (motor_mass + beyond_gap)
    return {
        "backlash_half_gap_m": 0.5 * b.width_mm * MM,
        "backlash_stiffness_N_per_m": b.stiffness_N_per_m,
        "backlash_damping_Ns_per_m": damping_for_ratio(
            b.damping_ratio, b.stiffness_N_per_m, reduced
        ),
    }


BACKLASH = Element(
    "backlash",
    "dead-zone contact between the nut and the rod",
    params=(
        Quantity("backlash_half_gap_m", "m", "b"),
        Quantity("backlash_stiffness_N_per_m", "N/m", "K"),
        Quantity("backlash_damping_Ns_per_m", "N s/m", "c"),
    ),
    # the gap between the nut and what lies beyond it: a series compliance's node, or the rod
    couplings=(
        Coupling(
            dead_zone_force,
            "nut",
            "far|rod",
            ("backlash_half_gap_m", "backlash_stiffness_N_per_m", "backlash_damping_Ns_per_m"),
        ),
    ),
    after="transmission",
    closed=(("backlash_half_gap_m", -CLOSED_OVERLAP),),
    section="backlash",
    pack=lambda plant: _pack(plant),
    modes=lambda value, mass: [
        (
            "the backlash contact stiffness",
            two_body_rate(
                value("backlash_stiffness_N_per_m"),
                value("rotor_inertia_kgm2") / value("ratio_m_per_rad") ** 2,
                mass("far|rod"),
            ),
            RK4_OSCILLATOR_LIMIT,
        )
    ],
)
