"""Gearbox and planetary roller screw: the kinematic chain from motor angle to rod position.

Gearbox (spur pair): ratio N = Z2/Z1, w_out = w_in / N, T_out = eta_g N T_in when driving.
Roller screw: lead L = n_s p, x = theta_s L / (2 pi), F = 2 pi eta_s T / L when driving.
Overall x = K theta_m with K = L / (2 pi N) (m/rad). Ratio and efficiency are kept apart: the
paper's i = eta Z2/Z1 is right for torque but wrong for speed.

Efficiency depends on the direction of power flow. A force F on the nut, reflected to the motor
shaft, is K F / eta while the motor drives the load (K F wm > 0), and K F eta while the load
back-drives the motor. Both branches are zero at F = 0, so the reflected torque is continuous
when contact opens or closes.
"""

import math

from ...jit import njit
from ..element import Derived, Element, Law, Quantity


def transmission_ratio(lead_m: float, gear_ratio: float) -> float:
    """K = L / (2 pi N): rod travel per motor radian (m/rad)."""
    return lead_m / (2.0 * math.pi * gear_ratio)


@njit(cache=True, inline="always", error_model="numpy")
def reflected_torque(force, motor_speed, ratio_k, efficiency):
    """Torque (N*m) that a nut force (N) puts on the motor shaft through gearbox and screw."""
    torque = ratio_k * force
    if torque * motor_speed > 0.0:
        return torque / efficiency
    return torque * efficiency


@njit(cache=True, inline="always", error_model="numpy")
def nut_motion(theta, w, x_body, v_body, ratio_k):
    """The nut's position (m) and velocity (m/s): x_body + K theta, on the screw's shaft at
    theta (rad) turning at w (rad/s) in a body at x_body moving at v_body."""
    return ratio_k * theta + x_body, ratio_k * w + v_body


@njit(cache=True, inline="always", error_model="numpy")
def nut_reaction(force, w, ratio_k, efficiency):
    """What a force on the nut (N) does: the screw's thrust bearing passes it to the body, and
    the shaft turning at w feels -reflected_torque(-force) (N m), the torque the nut's load
    takes through the efficiency."""
    return force, -reflected_torque(-force, w, ratio_k, efficiency)


TRANSMISSION = Element(
    "transmission",
    "gearbox and roller screw: ratio and efficiency",
    params=(
        Quantity("ratio_m_per_rad", "m/rad", "K = L / (2 pi N)"),
        Quantity("efficiency", "1", "eta = eta_gear eta_screw"),
    ),
    # the nut follows the screw's shaft (the motor's, or a gear mesh's far side) in the body
    derived=(
        Derived(
            "nut",
            motion=Law(
                nut_motion,
                (
                    "screw|motor.x",
                    "screw|motor.v",
                    "housing|ground.x",
                    "housing|ground.v",
                    "p.ratio_m_per_rad",
                ),
                ("x", "v"),
            ),
            fold=Law(
                nut_reaction,
                ("nut.f", "screw|motor.v", "p.ratio_m_per_rad", "p.efficiency"),
                ("body_force", "shaft_torque"),
            ),
            onto=("housing|ground", "screw|motor"),
        ),
    ),
    after="friction",
    section="drivetrain",
    pack=lambda plant: {
        "ratio_m_per_rad": plant.ratio_m_per_rad,
        "efficiency": plant.drivetrain.gear_efficiency * plant.drivetrain.screw_efficiency,
    },
)
