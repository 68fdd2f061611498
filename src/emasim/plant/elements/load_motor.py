"""The bench's load motor: a torque servo on the rudder shaft, with its own inertia and
torque-loop bandwidth.

Its torque T_lm (N m, opposing positive deflection) follows its command through a first-order
torque loop of bandwidth f_b (time constant tau = 1 / (2 pi f_b)), limited to its rating:

    T_cmd  = T(t) + T_pre + k_aero theta                                    (N m)
    dT_lm/dt = (clamp(T_cmd, -T_max, T_max) - T_lm) / tau

T(t) is the scenario's rudder load profile (constant or stepped torques), T_pre a standing
preload present from t = 0 (the state starts at it: no transient at the start), and k_aero
a spring-like aerodynamic hinge moment on the angle theta the load motor sits at (the disk
with the shaft's torsion, else the rudder). The rotor's inertia adds to the disk's, or to the
rudder's without the shaft element. Without the element the rudder load is T(t) itself.

Check (tests/test_load_motor.py): a torque step gives T_cmd (1 - exp(-t / tau)).
"""

import math

from pydantic import Field, model_validator

from ...config import Strict
from ...jit import njit
from ...numerics import clamp
from ..element import RATED_RUNAWAY, RK4_DECAY_LIMIT, Element, Law, Quantity, State


@njit(cache=True, inline="always", error_model="numpy")
def rudder_load(present, torque, profile):
    """The load on the rudder side (N m, opposing positive deflection): the load motor's
    torque, or without one the profile T(t) itself."""
    return torque if present != 0.0 else profile


@njit(cache=True, inline="always", error_model="numpy")
def load_motor_rate(torque, profile, angle, tau, spring, preload, max_torque):
    """dT_lm/dt (N m/s) for the profile torque T(t) and the angle theta (module docstring)."""
    command = clamp(profile + preload + spring * angle, -max_torque, max_torque)
    return (command - torque) / tau


class LoadMotorParams(Strict):
    """The load motor (module docstring)."""

    inertia_kgm2: float = Field(ge=0, le=1e3, description="rotor inertia on the rudder shaft")
    bandwidth_Hz: float = Field(gt=0, le=1e4, description="f_b of its torque loop")
    max_torque_Nm: float = Field(gt=0, le=1e6, description="T_max: its torque rating")
    spring_Nm_per_deg: float = Field(
        default=0.0, ge=-1e6, le=1e6, description="k_aero: hinge moment per degree of rudder"
    )
    preload_Nm: float = Field(
        default=0.0, ge=-1e6, le=1e6, description="T_pre: standing torque from t = 0"
    )

    @model_validator(mode="after")
    def _preload_within_rating(self):
        if abs(self.preload_Nm) > self.max_torque_Nm:
            raise ValueError(
                f"preload_Nm ({self.preload_Nm:g}) must be within the load motor's rating, "
                f"+-max_torque_Nm = +-{self.max_torque_Nm:g} N m"
            )
        return self

    @property
    def time_constant_s(self) -> float:
        """tau = 1 / (2 pi f_b)."""
        return 1.0 / (2.0 * math.pi * self.bandwidth_Hz)


LOAD_MOTOR = Element(
    "load_motor",
    "the bench's load motor: a first-order torque servo on the rudder shaft",
    states=(
        State(
            "load_motor_torque_Nm",
            "N m",
            "the load motor's torque, opposing positive deflection",
            atol=1e-9,
            bound=lambda plant: (
                RATED_RUNAWAY * plant.load_motor.max_torque_Nm if plant.load_motor else 1.0
            ),
        ),
    ),
    params=(
        Quantity("load_motor_present", "1", "1 with the element, 0 without"),
        Quantity("load_motor_time_constant_s", "s", "tau = 1 / (2 pi f_b)"),
        Quantity("load_motor_spring_Nm_per_rad", "N m/rad", "k_aero"),
        Quantity("load_motor_preload_Nm", "N m", "T_pre, from t = 0"),
        Quantity("load_motor_max_torque_Nm", "N m", "T_max"),
    ),
    presence="load_motor_present",
    laws=(
        Law(
            load_motor_rate,
            (
                "x.load_motor_torque_Nm",
                "in.t_rudder",
                "disk|rocker.x",
                "p.load_motor_time_constant_s",
                "p.load_motor_spring_Nm_per_rad",
                "p.load_motor_preload_Nm",
                "p.load_motor_max_torque_Nm",
            ),
            ("rate",),
        ),
        Law(
            rudder_load,
            ("p.load_motor_present", "x.load_motor_torque_Nm", "in.t_rudder"),
            ("load",),
            always=True,
        ),
    ),
    rates=(("load_motor_torque_Nm", "rate"),),
    forces=(("disk|rocker", "-load"),),
    modes=lambda value, mass: [
        ("the load motor's torque loop", 1.0 / value("load_motor_time_constant_s"), RK4_DECAY_LIMIT)
    ],
    mechanism=True,
    after="rudder_shaft",
    section="load_motor",
    config=LoadMotorParams,
    pack=lambda plant: {
        "load_motor_time_constant_s": plant.load_motor.time_constant_s,
        "load_motor_spring_Nm_per_rad": math.degrees(plant.load_motor.spring_Nm_per_deg),
        "load_motor_preload_Nm": plant.load_motor.preload_Nm,
        "load_motor_max_torque_Nm": plant.load_motor.max_torque_Nm,
    },
    initial=lambda plant: {"load_motor_torque_Nm": plant.load_motor.preload_Nm},  # from t = 0
    stage="load motor",
)
