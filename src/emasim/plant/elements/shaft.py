"""The rudder shaft's torsion: the rocker arm and the inertia disk joined by a torsion spring.

The shaft between the rocker arm (angle theta_r: the linkage's rudder, or x_L / arm with the
lumped stage) and the inertia disk (theta_d) carries the bench's torque sensor. Its torque

    T_shaft = k_t (theta_r - theta_d) + c_t (omega_r - omega_d)              (N m)

turns the disk, J_d domega_d/dt = T_shaft - T_load (J_d: the disk and, with the load motor,
its rotor), and holds the rocker arm back by -T_shaft. The rudder load acts on the disk.
Without the element the disk is part of the rudder's inertia and the load acts there.

Checks (tests/test_shaft.py): with the rod held, the disk rings at sqrt(k_t / J_d); with the
rod free on a lumped stage, at the two-mass frequency sqrt(k_t (1/J_d + 1/(M_L r^2))).
"""

from pydantic import Field

from ...config import Strict
from ..element import FAR_RUNAWAY, Quantity, State
from ..spring_damper import spring_damper


def _disk_back_on_the_rudder(plant) -> dict:
    """Without the shaft's torsion the disk turns with the rudder: on the linkage's rudder
    inertia (the lumped stage's load section carries its rudder inertia whole)."""
    if plant.linkage is None:
        return {}
    inertia = plant.linkage.rudder_inertia_kgm2 + plant.rudder_shaft.disk_inertia_kgm2
    return {"linkage": plant.linkage.model_copy(update={"rudder_inertia_kgm2": inertia})}


class ShaftParams(Strict):
    """The rudder shaft's torsion (module docstring). The disk's inertia moves off the rudder:
    the rudder inertia of the load or linkage section is then the rocker arm's side alone."""

    stiffness_Nm_per_rad: float = Field(gt=0, le=1e12, description="k_t: shaft, torque sensor")
    damping_Nms_per_rad: float = Field(ge=0, le=1e9, description="c_t")
    disk_inertia_kgm2: float = Field(gt=0, le=1e4, description="J_d: the inertia disk")


RUDDER_SHAFT = spring_damper(
    "rudder_shaft",
    "torsion of the rudder shaft between the rocker arm and the inertia disk",
    node="disk",
    anchor="rocker",
    states=(
        State("disk_angle_rad", "rad", "angle of the inertia disk", atol=1e-12),
        State(
            "disk_rate_rad_s",
            "rad/s",
            "rate of the inertia disk",
            atol=1e-10,
            bound=lambda plant: FAR_RUNAWAY,
        ),
    ),
    params=(
        Quantity("shaft_present", "1", "1 with the element, 0 without"),
        Quantity("shaft_stiffness_Nm_per_rad", "N m/rad", "k_t"),
        Quantity("shaft_damping_Nms_per_rad", "N m s/rad", "c_t"),
        Quantity("disk_inertia_kgm2", "kg m^2", "J_d: the disk and the load motor's rotor"),
    ),
    output=Quantity("shaft_torque_Nm", "N m", "torque in the shaft (the torque sensor)"),
    mode="the rudder shaft's torsion",
    rigid_anchor=True,  # the disk rings against the rudder side, far heavier at the arm
    mechanism=True,
    after="anchorage",
    section="rudder_shaft",
    config=ShaftParams,
    pack=lambda sh, plant: {
        "shaft_stiffness_Nm_per_rad": sh.stiffness_Nm_per_rad,
        "shaft_damping_Nms_per_rad": sh.damping_Nms_per_rad,
        "disk_inertia_kgm2": sh.disk_inertia_kgm2 + plant.load_motor_inertia_kgm2,
    },
    # the disk's inertia, and the load motor's on it, seen at the rod through the lever
    at_rod=lambda plant: (
        (plant.rudder_shaft.disk_inertia_kgm2 + plant.load_motor_inertia_kgm2)
        / plant.rod_per_rudder_m_per_rad**2
    ),
    removed=lambda plant: _disk_back_on_the_rudder(plant),
)
