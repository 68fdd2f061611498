"""The rod and the lumped rudder stage, or the rod alone when the linkage carries the rudder.

The rod (position x_L, velocity v_L, mass M_L: the rod and the lumped rudder seen through its
arm, J_r / r^2, or with the linkage the rod alone) feels the drive train's push F_drive (the
compliance spring's, or without it the gap's), its end stops, the rudder side through the
rocker arm (the lumped stage's T_r / r, or the linkage's axial push and the swing's
centripetal term), the external force F_L(t) and its viscous damping:

    M_L dv_L/dt = F_drive + F_stop + F_axial - F_L(t) + T_r / r - c_L v_L (+ M_L r phi'^2)

The rudder angle is the rocker arm's (the linkage's, or x_L / r of the lumped stage).
"""

from ...config import MM
from ..element import (
    Body,
    Element,
    Law,
    Quantity,
    State,
    rod_position_bound,
    rod_velocity_bound,
    total,
    viscous_force,
)
from .linkage import LOAD_LINKAGE, LOAD_LUMPED

ROD = Element(
    "rod",
    "the rod and the lumped rudder stage (rudder angle = rod position / arm), or the rod alone "
    "when the linkage carries the rudder",
    states=(
        State(
            "actuator_position_m",
            "m",
            "rod (load-side) position",
            atol=1e-14,
            bound=rod_position_bound,
        ),
        State("actuator_velocity_m_s", "m/s", "rod velocity", atol=1e-12, bound=rod_velocity_bound),
    ),
    params=(
        Quantity("load_mass_kg", "kg", "M_L: rod + lumped rudder, or the rod alone"),
        Quantity("load_viscous_Ns_per_m", "N s/m", "c_L"),
        Quantity("rudder_arm_m", "m", "lumped stage: rudder angle = x_L / arm"),
        Quantity("load_model", "1", "LOAD_LUMPED, LOAD_LINKAGE or LOAD_HELD"),
    ),
    outputs=(
        Quantity("drivetrain_force_N", "N", "force of the drive train on the rod"),
        Quantity("rudder_angle_rad", "rad", "rudder angle"),
    ),
    # the sum in the order of the module docstring (emasim.plant.element.Body.order)
    bodies=(
        Body(
            "rod",
            "actuator_position_m",
            "actuator_velocity_m_s",
            "load_mass_kg",
            order=(
                "fold_far",
                "compliance",
                "end_stops",
                "linkage__axial",
                "f_load",
                "linkage__lever",
                "rod",
            ),
        ),
    ),
    laws=(
        Law(viscous_force, ("p.load_viscous_Ns_per_m", "rod.v"), ("viscous",)),
        # what a load cell on the rod reads: the compliance spring's push, or without the
        # compliance what the gap passes on to the rod
        Law(total, ("far|rod.fold", "-compliance.force"), ("drive_force",), always=True),
    ),
    forces=(("rod", "-in.f_load"), ("rod", "-viscous")),
    values=(("rudder_angle_rad", "rocker.x"), ("drivetrain_force_N", "drive_force")),
    after="backlash",
    section="load",
    pack=lambda plant: {
        "load_mass_kg": plant.linkage.rod_mass_kg if plant.linkage else plant.load_mass_kg,
        "load_viscous_Ns_per_m": plant.load.viscous_Ns_per_m,
        "rudder_arm_m": plant.load.rudder_arm_mm * MM,
        "load_model": LOAD_LINKAGE if plant.linkage else LOAD_LUMPED,
    },
)
