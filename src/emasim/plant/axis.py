"""A force-driven linear axis: an ideal drive-gain force source, a rigid carriage, friction.

The axis of a positioning bench such as EMPS (Janot, Gautier, Brunot, *Data Set and Reference
Models of EMPS*, 2019: a DC motor on a ball screw, everything seen on the load side):

    M dv/dt = g_tau u - F_f(v, z),    dx/dt = v

with u the drive's command (V), g_tau the drive gain (N/V: current amplifier, torque constant
and screw in one, as the benchmark identifies it), and the friction F_f (the laws of
emasim.plant.elements.friction, in translation):

- ``coulomb``: Fc tanh(v / v_s) + Fv v + offset (the benchmark's eq. 1, tanh for sign);
- ``asymmetric``: the same with Fc+, Fv+ for v > 0 and Fc-, Fv- for v < 0 (its eq. 12, which
  the authors attribute to fatigue of the screw);
- ``lugre``: the LuGre force sigma0 z + sigma1 dz/dt + Fv v + offset on the bristle state z
  (Fc and the stiction Fs of the Stribeck curve).

The offset is the benchmark's constant term, a force the model subtracts like friction. The
plant is declared as elements (emasim.plant.element) and its right-hand side, outputs and
active states are generated from them by emasim.plant.assembly, as the actuator's are; its
one input is the drive's command, in the slot the generated right-hand side calls ``u_q``.
"""

import math
from typing import Literal

import numpy as np
from pydantic import Field

from ..config import Strict
from ..jit import njit
from .assembly import load
from .element import RK4_OSCILLATOR_LIMIT, Body, Element, Law, Quantity, State, assemble
from .elements.friction import (
    FRICTION_COULOMB,
    FRICTION_LUGRE,
    asymmetric_coulomb_viscous_force,
    lugre_force,
)

FRICTION_ASYMMETRIC = 3  # beside emasim.plant.elements.friction's FRICTION_*
AXIS_FRICTION_MODELS = {
    "coulomb": FRICTION_COULOMB,
    "asymmetric": FRICTION_ASYMMETRIC,
    "lugre": FRICTION_LUGRE,
}
RUNAWAY_STROKES = 10.0  # a carriage this many strokes out has run away


class AxisFriction(Strict):
    """The axis's friction (module docstring), in N and m/s. ``coulomb_N`` and
    ``viscous_Ns_per_m`` are the positive direction's in the asymmetric model, the
    ``*_negative_*`` the negative direction's (ignored otherwise: they must then be left
    unset)."""

    model: Literal["coulomb", "asymmetric", "lugre"] = "coulomb"
    # every number bounded as the actuator's are (emasim.plant.parameters): orders of
    # magnitude beyond any positioning axis, so that a typo or a fit's range of 1e300 is refused
    coulomb_N: float = Field(ge=0.0, le=1e5)
    viscous_Ns_per_m: float = Field(ge=0.0, le=1e7)
    coulomb_negative_N: float | None = Field(default=None, ge=0.0, le=1e5)
    viscous_negative_Ns_per_m: float | None = Field(default=None, ge=0.0, le=1e7)
    offset_N: float = Field(default=0.0, ge=-1e5, le=1e5)
    # tanh(v / v_s) for sign(v): 0.1 mm/s, below the 1 um/ms an encoder count per sample means
    smoothing_speed_m_s: float = Field(default=1e-4, gt=0.0, le=0.1)
    static_N: float | None = Field(default=None, ge=0.0, le=1e5)  # LuGre: Fs
    stribeck_speed_m_s: float = Field(default=1e-3, gt=0.0, le=10.0)  # LuGre: vs
    bristle_stiffness_N_per_m: float = Field(default=1e6, gt=0.0, le=1e12)  # LuGre: sigma0
    bristle_damping_Ns_per_m: float = Field(default=0.0, ge=0.0, le=1e9)  # LuGre: sigma1

    def negative(self) -> tuple[float, float]:
        """(Fc-, Fv-): the negative direction's, the positive's where the model is symmetric."""
        if self.model != "asymmetric":
            return self.coulomb_N, self.viscous_Ns_per_m
        return (
            self.coulomb_N if self.coulomb_negative_N is None else self.coulomb_negative_N,
            self.viscous_Ns_per_m
            if self.viscous_negative_Ns_per_m is None
            else self.viscous_negative_Ns_per_m,
        )


class AxisParams(Strict):
    """A force-driven axis: mass, drive gain, stroke and friction (module docstring)."""

    mass_kg: float = Field(gt=0.0, le=1e4)  # bounds: see AxisFriction
    drive_gain_N_per_V: float = Field(gt=0.0, le=1e5)
    stroke_m: float = Field(gt=0.0, le=100.0)
    max_speed_m_s: float = Field(gt=0.0, le=100.0)
    friction: AxisFriction


@njit(cache=True, inline="always", error_model="numpy")
def drive_force(gain, u):
    """The drive's force g_tau u (N) for the command u (V)."""
    return gain * u


@njit(cache=True, inline="always", error_model="numpy")
def axis_friction(v, z, model, fc, fv, fc_neg, fv_neg, offset, v_smooth, fs, vs, s0, s1):
    """The friction force on the carriage (N) at speed v (m/s) and bristle state z (m), with
    the bristle rate dz/dt (m/s, 0 but for LuGre), for the model of the module docstring."""
    if model == FRICTION_LUGRE:
        force, z_rate = lugre_force(z, v, fc, fs, vs, s0, s1, fv)
        return force + offset, z_rate
    force = asymmetric_coulomb_viscous_force(v, fc, fv, fc_neg, fv_neg, v_smooth)
    return force + offset, 0.0


def _bristle_bound(axis: AxisParams) -> float:
    f = axis.friction
    return RUNAWAY_STROKES * max(f.static_N or f.coulomb_N, 1.0) / f.bristle_stiffness_N_per_m


def _pack_friction(axis: AxisParams) -> dict[str, float]:
    f = axis.friction
    fc_neg, fv_neg = f.negative()
    return {
        "axis_friction_model": AXIS_FRICTION_MODELS[f.model],
        "axis_coulomb_N": f.coulomb_N,
        "axis_viscous_Ns_per_m": f.viscous_Ns_per_m,
        "axis_coulomb_negative_N": fc_neg,
        "axis_viscous_negative_Ns_per_m": fv_neg,
        "axis_offset_N": f.offset_N,
        "axis_smoothing_speed_m_s": f.smoothing_speed_m_s,
        "axis_static_N": f.coulomb_N if f.static_N is None else f.static_N,
        "axis_stribeck_speed_m_s": f.stribeck_speed_m_s,
        "axis_bristle_stiffness_N_per_m": f.bristle_stiffness_N_per_m,
        "axis_bristle_damping_Ns_per_m": f.bristle_damping_Ns_per_m,
    }


CARRIAGE = Element(
    "carriage",
    "the rigid moving mass, everything seen on the load side",
    states=(
        State(
            "axis_position_m",
            "m",
            "carriage position",
            atol=1e-12,
            bound=lambda axis: RUNAWAY_STROKES * axis.stroke_m,
        ),
        State(
            "axis_velocity_m_s",
            "m/s",
            "carriage velocity",
            atol=1e-10,
            bound=lambda axis: RUNAWAY_STROKES * axis.max_speed_m_s,
        ),
    ),
    params=(Quantity("axis_mass_kg", "kg", "M"),),
    bodies=(Body("carriage", "axis_position_m", "axis_velocity_m_s", "axis_mass_kg"),),
    pack=lambda axis: {"axis_mass_kg": axis.mass_kg},
)

FORCE_DRIVE = Element(
    "force_drive",
    "an ideal drive-gain force source, F = g_tau u",
    params=(Quantity("drive_gain_N_per_V", "N/V", "g_tau"),),
    # no output: the loop records the force it applies (an output cannot read the command)
    laws=(Law(drive_force, ("p.drive_gain_N_per_V", "in.u_q"), ("force",)),),
    forces=(("carriage", "+force"),),
    after="carriage",
    pack=lambda axis: {"drive_gain_N_per_V": axis.drive_gain_N_per_V},
)

AXIS_FRICTION = Element(
    "axis_friction",
    "Coulomb + viscous (symmetric or asymmetric) or LuGre friction, and the offset",
    states=(
        State(
            "axis_bristle_state_m",
            "m",
            "LuGre bristle deflection",
            atol=1e-15,
            bound=_bristle_bound,
        ),
    ),
    params=(
        Quantity("axis_friction_model", "1", "FRICTION_COULOMB, FRICTION_ASYMMETRIC, _LUGRE"),
        Quantity("axis_coulomb_N", "N", "Fc (Fc+ in the asymmetric model)"),
        Quantity("axis_viscous_Ns_per_m", "N s/m", "Fv (Fv+)"),
        Quantity("axis_coulomb_negative_N", "N", "Fc-"),
        Quantity("axis_viscous_negative_Ns_per_m", "N s/m", "Fv-"),
        Quantity("axis_offset_N", "N", "the constant term"),
        Quantity("axis_smoothing_speed_m_s", "m/s", "tanh(v/v_s) for sign(v)"),
        Quantity("axis_static_N", "N", "LuGre: Fs"),
        Quantity("axis_stribeck_speed_m_s", "m/s", "LuGre: vs"),
        Quantity("axis_bristle_stiffness_N_per_m", "N/m", "LuGre: sigma0"),
        Quantity("axis_bristle_damping_Ns_per_m", "N s/m", "LuGre: sigma1"),
    ),
    outputs=(Quantity("friction_force_N", "N", "friction and offset on the carriage"),),
    laws=(
        Law(
            axis_friction,
            (
                "carriage.v",
                "x.axis_bristle_state_m",
                "p.axis_friction_model",
                "p.axis_coulomb_N",
                "p.axis_viscous_Ns_per_m",
                "p.axis_coulomb_negative_N",
                "p.axis_viscous_negative_Ns_per_m",
                "p.axis_offset_N",
                "p.axis_smoothing_speed_m_s",
                "p.axis_static_N",
                "p.axis_stribeck_speed_m_s",
                "p.axis_bristle_stiffness_N_per_m",
                "p.axis_bristle_damping_Ns_per_m",
            ),
            ("force", "bristle_rate"),
        ),
    ),
    forces=(("carriage", "-force"),),
    rates=(("axis_bristle_state_m", "bristle_rate"),),
    values=(("friction_force_N", "force"),),
    after="force_drive",
    pack=_pack_friction,
    modes=lambda value, mass: [
        mode
        for mode in [
            (
                "the LuGre bristle stiffness",
                math.sqrt(value("axis_bristle_stiffness_N_per_m") / value("axis_mass_kg")),
                RK4_OSCILLATOR_LIMIT,
            )
        ]
        if value("axis_friction_model") == FRICTION_LUGRE
    ],
)

AXIS = assemble((CARRIAGE, FORCE_DRIVE, AXIS_FRICTION))
GENERATED = load(AXIS)
rhs = GENERATED.rhs  # (x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges): u_q the command
plant_outputs = GENERATED.plant_outputs  # (x, p, out)
N_STATE = len(AXIS.states)
N_OUTPUTS = len(AXIS.outputs)
X_POSITION = AXIS.states.index("axis_position_m")
X_VELOCITY = AXIS.states.index("axis_velocity_m_s")


def pack(axis: AxisParams):
    """The axis's packed parameter vector (AXIS.params order)."""
    values = {}
    for element in AXIS.elements:
        values.update(element.pack(axis))
    return np.array([values[name] for name in AXIS.params.names], dtype=np.float64)


P_GAIN = AXIS.params.index("drive_gain_N_per_V")
O_FRICTION = AXIS.outputs.index("friction_force_N")


def inverse_model(model: str, velocity: np.ndarray, acceleration: np.ndarray):
    """The observation matrix of the axis's inverse model, F = M a + F_f(v), by parameter
    (AxisParams paths), where it is linear in them (sign(v) for the Coulomb term's tanh):

    - ``coulomb``: F = M a + Fv v + Fc sign(v) + offset;
    - ``asymmetric``: F = M a + Fv+ v+ + Fc+ [v > 0] + Fv- v- - Fc- [v < 0] + offset, v+ and
      v- the positive and negative parts of v (eq. 12 of the EMPS description).

    Raises ValueError for LuGre, which is not linear in its parameters."""
    one = np.ones_like(velocity)
    if model == "coulomb":
        return {
            "mass_kg": acceleration,
            "friction.viscous_Ns_per_m": velocity,
            "friction.coulomb_N": np.sign(velocity),
            "friction.offset_N": one,
        }
    if model == "asymmetric":
        positive, negative = velocity > 0.0, velocity < 0.0
        return {
            "mass_kg": acceleration,
            "friction.viscous_Ns_per_m": velocity * positive,
            "friction.coulomb_N": positive * 1.0,
            "friction.viscous_negative_Ns_per_m": velocity * negative,
            "friction.coulomb_negative_N": -1.0 * negative,
            "friction.offset_N": one,
        }
    raise ValueError(f"the {model} friction is not linear in its parameters")
