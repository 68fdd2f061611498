"""End stops: the rod's at both ends of the stroke, and the rudder's travel limits.

A stop is a stiff contact with damping, the dead-zone law of :mod:`emasim.plant.elements.backlash`
with the stroke as its gap. With s the rod's extension relative to the actuator body (m,
0 at mid stroke) and v its rate,

    F_stop = -dead_zone_force(s, v, L/2, k, c)                    (N, on the rod)

zero inside the stroke |s| <= L/2, k (|s| - L/2) plus a damping c v that never pulls the rod
back onto the stop beyond it. The rudder's travel limits act the same way on the rudder
angle theta_r (rad) about its shaft,

    T_stop = -dead_zone_force(theta_r, omega_r, theta_max, k_r, c_r)   (N m, on the rudder)

(with the lumped rudder stage the stop torque reaches the rod through the arm). Inside the
stroke and the travel limits both are exactly zero, so a run that stays inside them is the
run without stops, to the bit.

Check (tests/test_stops.py): a rod thrown onto a stop rebounds with the coefficient of
restitution of this contact law, computed independently by a tight solve_ivp of one mass
on the same law.
"""

import math

from pydantic import Field

from ...config import MM, Strict
from ...jit import njit
from ..element import RK4_OSCILLATOR_LIMIT, Coupling, Element, Quantity, two_body_rate
from .backlash import dead_zone_force


@njit(cache=True, inline="always", error_model="numpy")
def stop_force(position, rate, limit, stiffness, damping):
    """Force (or torque) of a pair of stops at +-limit on a body at ``position`` moving at
    ``rate``: zero inside, pushing back beyond (module docstring)."""
    return -dead_zone_force(position, rate, limit, stiffness, damping)


class EndStopParams(Strict):
    """The stops (module docstring). The rod's sit at the ends of the drive train's stroke."""

    stiffness_N_per_m: float = Field(gt=0, le=1e12, description="k: the rod's stops")
    damping_Ns_per_m: float = Field(ge=0, le=1e9, description="c: the rod's stops")
    rudder_limit_deg: float = Field(gt=0, le=180, description="theta_max: the rudder's stops")
    rudder_stiffness_Nm_per_rad: float = Field(gt=0, le=1e12, description="k_r")
    rudder_damping_Nms_per_rad: float = Field(ge=0, le=1e9, description="c_r")


END_STOPS = Element(
    "end_stops",
    "stiff damped stops at both ends of the rod's stroke and at the rudder's travel limits",
    params=(
        Quantity("end_stops_present", "1", "1 with the stops, 0 without (a motor test stand)"),
        Quantity("stroke_half_m", "m", "L/2: the rod's stops, from mid stroke"),
        Quantity("stop_stiffness_N_per_m", "N/m", "k"),
        Quantity("stop_damping_Ns_per_m", "N s/m", "c"),
        Quantity("rudder_limit_rad", "rad", "theta_max: the rudder's stops"),
        Quantity("rudder_stop_stiffness_Nm_per_rad", "N m/rad", "k_r"),
        Quantity("rudder_stop_damping_Nms_per_rad", "N m s/rad", "c_r"),
    ),
    outputs=(
        Quantity("end_stop_force_N", "N", "force of the rod's end stops on the rod"),
        Quantity("rudder_stop_torque_Nm", "N m", "torque of the rudder's stops on the rudder"),
    ),
    presence="end_stops_present",
    # stop_force(s) = dead_zone_force(-s): the rod's stops on its extension from the body, the
    # rudder's on its angle from the structure
    couplings=(
        Coupling(
            dead_zone_force,
            "housing|ground",
            "rod",
            ("stroke_half_m", "stop_stiffness_N_per_m", "stop_damping_Ns_per_m"),
            result="rod_force",
        ),
        Coupling(
            dead_zone_force,
            "ground",
            "rocker",
            (
                "rudder_limit_rad",
                "rudder_stop_stiffness_Nm_per_rad",
                "rudder_stop_damping_Nms_per_rad",
            ),
            result="rudder_torque",
        ),
    ),
    values=(("end_stop_force_N", "rod_force"), ("rudder_stop_torque_Nm", "rudder_torque")),
    after="rod",
    section="end_stops",
    config=EndStopParams,
    pack=lambda plant: {
        "stroke_half_m": 0.5 * plant.drivetrain.stroke_mm * MM,
        "stop_stiffness_N_per_m": plant.end_stops.stiffness_N_per_m,
        "stop_damping_Ns_per_m": plant.end_stops.damping_Ns_per_m,
        "rudder_limit_rad": math.radians(plant.end_stops.rudder_limit_deg),
        "rudder_stop_stiffness_Nm_per_rad": plant.end_stops.rudder_stiffness_Nm_per_rad,
        "rudder_stop_damping_Nms_per_rad": plant.end_stops.rudder_damping_Nms_per_rad,
    },
    modes=lambda value, mass: [
        (
            "the rod's end stops",
            two_body_rate(value("stop_stiffness_N_per_m"), value("load_mass_kg")),
            RK4_OSCILLATOR_LIMIT,
        )
    ],
)
