"""The anchorage: the actuator body on the aircraft structure, a spring-damper along its axis.

The body (housing, stator, screw bearings: mass m_h) sits at x_h on the anchorage's spring k_a
and damper c_a. The screw turns in the body, so the nut is at x_h + K theta_m and the backlash
gap closes on x_h + K theta_m - x_far; the screw's thrust bearing passes the gap's reaction to
the body, and the rod's end stops act between the rod and the body:

    m_h dv_h/dt = -F_gap - F_stop_rod - k_a x_h - c_a v_h                   (N)

The rod position x_L stays absolute (what the linkage and the rudder see); the rod's
displacement sensor, fixed on the body, reads x_L - x_h. Without the element x_h = v_h = 0.

Checks (tests/test_anchorage.py): with the rotor locked, the body and rod on the anchorage
oscillate at sqrt(k_eff / (m_h + M_L)) (the gap's and the anchorage's springs in series);
with the series compliance between them, at the eigenfrequencies of the two-mass chain.
"""

from pydantic import Field

from ...config import Strict
from ..element import Quantity, State, rod_position_bound, rod_velocity_bound
from ..spring_damper import spring_damper


class AnchorageParams(Strict):
    """The anchorage (module docstring), in SI units."""

    stiffness_N_per_m: float = Field(gt=0, le=1e12, description="k_a: structure and mounts")
    damping_Ns_per_m: float = Field(ge=0, le=1e9, description="c_a")
    housing_mass_kg: float = Field(gt=0, le=1e4, description="m_h: body, stator, screw bearings")


ANCHORAGE = spring_damper(
    "anchorage",
    "the actuator body on the structure: a spring-damper along the actuator's axis",
    node="housing",
    anchor="ground",
    states=(
        State(
            "housing_position_m",
            "m",
            "displacement of the actuator body on its anchorage",
            atol=1e-14,
            bound=rod_position_bound,
        ),
        State(
            "housing_velocity_m_s",
            "m/s",
            "velocity of the actuator body",
            atol=1e-12,
            bound=rod_velocity_bound,
        ),
    ),
    params=(
        Quantity("anchorage_present", "1", "1 with the element, 0 without"),
        Quantity("anchorage_stiffness_N_per_m", "N/m", "k_a"),
        Quantity("anchorage_damping_Ns_per_m", "N s/m", "c_a"),
        Quantity("housing_mass_kg", "kg", "m_h"),
    ),
    output=Quantity("anchorage_force_N", "N", "force of the structure on the actuator body"),
    mode="the anchorage",
    order=("anchorage", "transmission", "end_stops"),  # m_h dv_h/dt = F_a - F_gap - F_stop
    after="compliance",
    section="anchorage",
    config=AnchorageParams,
    pack=lambda a, plant: {
        "anchorage_stiffness_N_per_m": a.stiffness_N_per_m,
        "anchorage_damping_Ns_per_m": a.damping_Ns_per_m,
        "housing_mass_kg": a.housing_mass_kg,
    },
)
