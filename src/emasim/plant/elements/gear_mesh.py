"""The torsion between the motor and the screw: a gear mesh (or a direct drive's shaft
coupling), a torsional spring-damper with its own play.

With the element the rotor (the motor's inertia J: the rotor and what turns rigidly with it,
the pinion) and the screw side (J_s: the wheel, the screw and what turns with it) are two
bodies. The screw side's angle theta_s, its inertia J_s and the mesh's stiffness k and damping
c are all seen at the motor shaft (a stiffness k_w or an inertia J_w at the wheel of a gear
ratio N is k_w / N^2 or J_w / N^2 here), so the transmission's K still turns theta_s into
the nut's travel. The mesh's torque, on the screw side and back on the rotor,

    T = k (theta_m - theta_s) + c (omega_m - omega_s)                        (no play)
    T = dead_zone_force(theta_m - theta_s, omega_m - omega_s, b, k, c)      (a play of 2b)

(the dead zone of emasim.plant.elements.backlash: no torque inside the play, damping only in
contact). The nut moves with the screw side and its reaction acts there. Without the element
the screw is the rotor. Its ablation stage is the compliance's.

Checks (tests/test_gear_mesh.py): with the play closed, the rotor and the screw side ring at
the two-mass frequency omega_n = sqrt(k (1/J + 1/J_s)) with the damping ratio
zeta = c / (2 sqrt(k J_r)), J_r = J J_s / (J + J_s); inside the play the mesh carries nothing.
"""

import math

from pydantic import Field

from ...config import Strict
from ...jit import njit
from ..element import Quantity, State
from ..spring_damper import spring_damper, spring_damper_force
from .backlash import dead_zone_force
from .motor import shaft_angle_bound, shaft_speed_bound


@njit(cache=True, inline="always", error_model="numpy")
def mesh_torque(dx, dv, half_play, stiffness, damping):
    """T (N m) of the mesh for the rotor's lead dx (rad) over the screw side and its rate dv
    (rad/s): the dead zone of half-width b, or with no play the spring-damper."""
    if half_play > 0.0:
        return dead_zone_force(dx, dv, half_play, stiffness, damping)
    return spring_damper_force(dx, dv, stiffness, damping)


class GearMeshParams(Strict):
    """The mesh (module docstring), everything seen at the motor shaft."""

    stiffness_Nm_per_rad: float = Field(gt=0, le=1e12, description="k: the mesh's torsion")
    damping_Nms_per_rad: float = Field(ge=0, le=1e6, description="c, in parallel with k")
    screw_inertia_kgm2: float = Field(
        gt=0, le=1e3, description="J_s: the wheel, the screw and what turns with it"
    )
    play_deg: float = Field(default=0.0, ge=0, le=10, description="2b: the mesh's total play")


GEAR_MESH = spring_damper(
    "gear_mesh",
    "the torsion between the motor and the screw, with its own play",
    node="screw",
    anchor="motor",
    states=(
        State(
            "screw_angle_rad",
            "rad",
            "angle of the screw side, seen at the motor shaft",
            atol=1e-11,
            bound=shaft_angle_bound,
        ),
        State(
            "screw_speed_rad_s",
            "rad/s",
            "speed of the screw side, seen at the motor shaft",
            atol=1e-9,
            bound=shaft_speed_bound,
        ),
    ),
    params=(
        Quantity("gear_mesh_present", "1", "1 with the element, 0 without"),
        Quantity("gear_mesh_stiffness_Nm_per_rad", "N m/rad", "k"),
        Quantity("gear_mesh_damping_Nms_per_rad", "N m s/rad", "c"),
        Quantity("screw_inertia_kgm2", "kg m^2", "J_s"),
    ),
    output=Quantity("gear_mesh_torque_Nm", "N m", "torque of the mesh on the screw side"),
    mode="the gear mesh",
    play=Quantity("gear_mesh_half_play_rad", "rad", "b: half the mesh's play"),
    law=mesh_torque,
    after="anchorage",
    section="gear_mesh",
    config=GearMeshParams,
    pack=lambda mesh, plant: {
        "gear_mesh_stiffness_Nm_per_rad": mesh.stiffness_Nm_per_rad,
        "gear_mesh_damping_Nms_per_rad": mesh.damping_Nms_per_rad,
        "screw_inertia_kgm2": mesh.screw_inertia_kgm2,
        "gear_mesh_half_play_rad": math.radians(0.5 * mesh.play_deg),
    },
    at_motor=lambda plant: plant.gear_mesh.screw_inertia_kgm2,
)
