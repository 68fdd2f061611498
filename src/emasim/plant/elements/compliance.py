"""A series spring-damper between the nut and the rod: the axial compliance of the screw, the
nut, their bearings and the rod end, in series with the backlash gap.

With the element, the gap sits between the screw (nut position K theta_m) and a node of mass
m_n (the nut body and what moves with it), and the spring k, with the damper c in parallel,
ties the node to the rod:

    F_gap      = dead_zone_force(K theta_m - x_n, K wm - v_n)     (N; elements.backlash)
    F_spring   = k (x_n - x_L) + c (v_n - v_L)                    (N; pulls as well as pushes)
    m_n dv_n/dt = F_gap - F_spring

and the rod feels F_spring where it felt F_gap. The motor still feels the gap force through the
screw. Without the element the rod feels F_gap directly, and the node's states stay idle.

Checks (tests/test_compliance.py): with the gap closed and far stiffer than k, the motor side
(J/K^2) and the rod (M_L) oscillate at omega = sqrt(k (m1 + m2) / (m1 m2)) as m_n -> 0, and at
the eigenfrequencies of the three-mass chain for any m_n; under a steady force F on the rod the
spring deflects F/k.
"""

from pydantic import Field

from ...config import Strict
from ..element import Quantity, State, rod_position_bound, rod_velocity_bound
from ..spring_damper import spring_damper


class ComplianceParams(Strict):
    """The series spring-damper (module docstring), in SI units."""

    stiffness_N_per_m: float = Field(gt=0, le=1e12, description="k: screw, nut and rod end")
    damping_Ns_per_m: float = Field(ge=0, le=1e7, description="c, in parallel with k")
    node_mass_kg: float = Field(
        gt=0, le=100, description="m_n: the nut and what moves with it between gap and spring"
    )


COMPLIANCE = spring_damper(
    "compliance",
    "series spring-damper between the nut and the rod, behind the backlash gap",
    node="far",
    anchor="rod",
    states=(
        State(
            "compliance_node_position_m",
            "m",
            "position of the node between the gap and the spring (the nut body)",
            atol=1e-14,
            bound=rod_position_bound,
        ),
        State(
            "compliance_node_velocity_m_s",
            "m/s",
            "velocity of the node",
            atol=1e-12,
            bound=rod_velocity_bound,
        ),
    ),
    params=(
        Quantity("compliance_present", "1", "1 with the element, 0 without"),
        Quantity("compliance_stiffness_N_per_m", "N/m", "k"),
        Quantity("compliance_damping_Ns_per_m", "N s/m", "c"),
        Quantity("compliance_node_mass_kg", "kg", "m_n"),
    ),
    output=Quantity("compliance_force_N", "N", "spring-damper force on the rod"),
    output_on_anchor=True,
    mode="the screw's compliance",
    after="ratings",
    section="compliance",
    config=ComplianceParams,
    pack=lambda c, plant: {
        "compliance_stiffness_N_per_m": c.stiffness_N_per_m,
        "compliance_damping_Ns_per_m": c.damping_Ns_per_m,
        "compliance_node_mass_kg": c.node_mass_kg,
    },
    at_rod=lambda plant: plant.compliance.node_mass_kg,
)
