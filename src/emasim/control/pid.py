"""PI / PID with filtered derivative, feed-forward and anti-windup.

    e      = r - y
    u      = Kp e + I + D + Kff dr/dt,     u_sat = clamp(u, u_min, u_max)
    D(s)   = Kd s / (1 + Tf s) (c R(s) - Y(s))      (backward Euler)
    dI/dt  = Ki e + Kaw (u_sat - u)        (back-calculation with the realised output)

The derivative's set-point weight c (Astrom & Hagglund's two-degree-of-freedom PID) is 0 for
the derivative on the measurement, the industrial default: a set-point step gives no
derivative kick; and 1 for the textbook derivative on the error, which kicks by
Kd dr / (Tf + Ts) at the step. The derivative's memory starts at the first sample, so a step
there (a reference that starts stepped, as bench-step's does) kicks neither.

One compiled law serves the speed loop (y = motor speed, u = iq*) and the position loop
(y = rod position, u = motor speed command). The configs below choose the gains from a
bandwidth, following the cascade practice of motulator (Aalto) and Astrom & Hagglund, PID
Controllers (1995): the speed loop places both closed-loop poles at -alpha_s on the rigid
inertia (Kp = 2 alpha J/kt, Ki = alpha^2 J/kt); the position loop sees the speed loop as ideal,
x' = K w, and places both poles at -alpha_p.

The bandwidth is a design helper and the starting point of a tuning. A tuning searches the
independent gains (``with_explicit_gains``): the position loop's Kp, Ki and Kd (its derivative
filter Tf stays as given) and the speed loop's Kp and Ki, five knobs for a PID cascade, each
over GAIN_SPAN either way of the gain it starts from (widened where the optimum sits on a
bound, emasim.search_rules).
"""

import math
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from ..interface import M_POSITION, M_SPEED, O_RATE, O_VALUE, R_ACCEL, R_RATE, R_VALUE
from ..numerics import clamp
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

GAIN_SPAN = 10.0  # a tuning searches each gain from a tenth to ten times the gain it starts at
SPEED_BANDWIDTH_HZ = 50.0  # SpeedPI's bandwidth when neither it nor its gains are given
POSITION_BANDWIDTH_HZ = 4.0  # PositionPID's, likewise
KP, KI, KD, TF, U_MIN, U_MAX, KFF, CHANNEL, KAW, D_WEIGHT = range(10)
N_PARAMS = 10
INTEGRAL, DERIVATIVE, V_PREV, STARTED = range(4)  # V_PREV: the derivative's last input
N_STATE = 4


@controller_law
def pid(state, params, meas, ref, ts, out):
    """PID law of the module docstring; params and state laid out by KP..D_WEIGHT,
    INTEGRAL..STARTED."""
    y = meas[int(params[CHANNEL])]
    v = params[D_WEIGHT] * ref[R_VALUE] - y  # the derivative's input, c r - y
    if state[STARTED] == 0.0:
        state[V_PREV] = v
        state[STARTED] = 1.0
    e = ref[R_VALUE] - y
    tf = params[TF]
    state[DERIVATIVE] = (tf * state[DERIVATIVE] + params[KD] * (v - state[V_PREV])) / (tf + ts)
    state[V_PREV] = v
    u = params[KP] * e + state[INTEGRAL] + state[DERIVATIVE] + params[KFF] * ref[R_RATE]
    u_sat = clamp(u, params[U_MIN], params[U_MAX])
    state[INTEGRAL] += ts * (params[KI] * e + params[KAW] * (u_sat - u))
    out[O_VALUE] = u_sat
    out[O_RATE] = params[KFF] * ref[R_ACCEL]


def pack_pid(
    kp, ki, kd, tf, limit, kff, channel, commands="current", derivative_weight=0.0
) -> Compiled:
    """Parameter array and zero state of :func:`pid`; anti-windup gain Kaw = Ki/Kp (Tt = Ti);
    ``derivative_weight`` is the set-point weight c of the derivative (module docstring)."""
    params = np.zeros(N_PARAMS)
    params[KP], params[KI], params[KD], params[TF] = kp, ki, kd, tf
    params[U_MIN], params[U_MAX] = -limit, limit
    params[KFF], params[CHANNEL] = kff, channel
    params[KAW] = ki / kp if kp > 0 else 0.0
    params[D_WEIGHT] = derivative_weight
    return Compiled(pid, params, np.zeros(N_STATE), commands)


class SpeedPI(ControllerConfig):
    """Speed-loop PI: motor speed error (rad/s) -> q-axis current command (A)."""

    loop: ClassVar = "speed"
    name: Literal["pi"] = "pi"
    bandwidth_Hz: float | None = Field(
        default=None, gt=0, le=1e4, description="alpha_s / (2 pi); 50 Hz unless gains are given"
    )
    kp_A_s_per_rad: float | None = Field(
        default=None, ge=0, le=1e6, description="overrides bandwidth"
    )
    ki_A_per_rad: float | None = Field(
        default=None, ge=0, le=1e9, description="overrides bandwidth"
    )
    acceleration_feedforward: bool = Field(
        default=False, description="add J/kt * dw_ref/dt to the current command"
    )

    @model_validator(mode="after")
    def _bandwidth_or_gains(self):
        return _bandwidth_or_gains(self, "kp_A_s_per_rad", "ki_A_per_rad")

    def gains(self, plant: PlantFacts) -> tuple[float, float]:
        """(Kp in A s/rad, Ki in A/rad): the fields where given, else from the bandwidth."""
        alpha = 2.0 * math.pi * (self.bandwidth_Hz or SPEED_BANDWIDTH_HZ)
        j_over_kt = plant.inertia_kgm2 / plant.torque_constant_Nm_per_A
        kp = self.kp_A_s_per_rad if self.kp_A_s_per_rad is not None else 2.0 * alpha * j_over_kt
        ki = self.ki_A_per_rad if self.ki_A_per_rad is not None else alpha**2 * j_over_kt
        return float(kp), float(ki)

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        kp, ki = self.gains(plant)
        j_over_kt = plant.inertia_kgm2 / plant.torque_constant_Nm_per_A
        kff = j_over_kt if self.acceleration_feedforward else 0.0
        return pack_pid(kp, ki, 0.0, ts, plant.max_current_A, kff, M_SPEED)

    def with_explicit_gains(self, plant: PlantFacts) -> "SpeedPI":
        kp, ki = self.gains(plant)
        return self.model_copy(
            update={"kp_A_s_per_rad": kp, "ki_A_per_rad": ki, "bandwidth_Hz": None}
        )

    def tunable_ranges(self):
        if self.kp_A_s_per_rad is None or self.ki_A_per_rad is None:
            return {"bandwidth_Hz": (5.0, 300.0)}
        return around({"kp_A_s_per_rad": self.kp_A_s_per_rad, "ki_A_per_rad": self.ki_A_per_rad})


class PositionPID(ControllerConfig):
    """Position-loop PID: rod position error (m) -> motor speed command (rad/s).

    Gains act on rod quantities (Kp in 1/s, Ki in 1/s^2, Kd dimensionless) and are divided by K
    to command the motor. From the bandwidth, with the speed loop taken as ideal, the loop
    (1 + Kd) s^2 + Kp s + Ki has both poles at -alpha_p: Kp = 2 alpha (1 + Kd),
    Ki = alpha^2 (1 + Kd). ``pi`` is the same law with Kd = 0.
    """

    loop: ClassVar = "position"
    name: Literal["pid", "pi"] = "pid"
    bandwidth_Hz: float | None = Field(
        default=None, gt=0, le=1e3, description="alpha_p / (2 pi); 4 Hz unless gains are given"
    )
    kd: float | None = Field(
        default=None, ge=0, le=100, description="derivative gain; pid default 0.05"
    )
    kp_per_s: float | None = Field(default=None, ge=0, le=1e6, description="overrides bandwidth")
    ki_per_s2: float | None = Field(default=None, ge=0, le=1e9, description="overrides bandwidth")
    derivative_filter_s: float = Field(default=2e-3, gt=0, le=1.0, description="Tf of the D term")
    velocity_feedforward: bool = Field(default=True, description="add dx_ref/dt / K")
    derivative_on: Literal["measurement", "error"] = Field(
        default="measurement",
        description="the D term's input: the measurement (no kick on set-point steps) or the "
        "error (the textbook PID)",
    )

    @model_validator(mode="after")
    def _no_derivative_in_pi(self):
        if self.name == "pi" and self.kd:
            raise ValueError("kd must be 0 or absent for the 'pi' controller; use name = 'pid'")
        return _bandwidth_or_gains(self, "kp_per_s", "ki_per_s2")

    def gains(self) -> tuple[float, float, float]:
        """(Kp in 1/s, Ki in 1/s^2, Kd): the fields where given, else from the bandwidth."""
        alpha = 2.0 * math.pi * (self.bandwidth_Hz or POSITION_BANDWIDTH_HZ)
        kd = 0.0 if self.name == "pi" else (0.05 if self.kd is None else self.kd)
        kp = self.kp_per_s if self.kp_per_s is not None else 2.0 * alpha * (1.0 + kd)
        ki = self.ki_per_s2 if self.ki_per_s2 is not None else alpha**2 * (1.0 + kd)
        return kp, ki, kd

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        kp, ki, kd = self.gains()
        k = plant.ratio_m_per_rad
        kff = 1.0 / k if self.velocity_feedforward else 0.0
        return pack_pid(
            kp / k,
            ki / k,
            kd / k,
            self.derivative_filter_s,
            plant.max_speed_rad_s,
            kff,
            M_POSITION,
            commands="speed",
            derivative_weight=1.0 if self.derivative_on == "error" else 0.0,
        )

    def with_explicit_gains(self, plant: PlantFacts) -> "PositionPID":
        kp, ki, kd = self.gains()
        explicit = {"kp_per_s": kp, "ki_per_s2": ki, "bandwidth_Hz": None}
        return self.model_copy(update=explicit | ({"kd": kd} if self.name == "pid" else {}))

    def tunable_ranges(self):
        if self.kp_per_s is None or self.ki_per_s2 is None:
            ranges = {"bandwidth_Hz": (0.2, 20.0)}
            if self.name == "pid":
                ranges["kd"] = (1e-3, 1.0)
            return ranges
        gains = {"kp_per_s": self.kp_per_s, "ki_per_s2": self.ki_per_s2}
        return around(gains | ({"kd": self.kd} if self.name == "pid" else {}))


def _bandwidth_or_gains(config, kp: str, ki: str):
    """Refuse a bandwidth given beside both explicit gains: they would override its design,
    and the bandwidth would be silently ignored."""
    if config.bandwidth_Hz is not None and getattr(config, kp) is not None:
        if getattr(config, ki) is not None:
            raise ValueError(
                f"bandwidth_Hz and the gains {kp}, {ki} are both given: give the gains, or the "
                f"bandwidth alone (replace the whole table, e.g. "
                f"controllers.{config.loop}={{name = '{config.name}', bandwidth_Hz = ...}})"
            )
    return config


def around(gains: dict[str, float]) -> dict[str, tuple[float, float]]:
    """Field -> the search range of an explicit gain: GAIN_SPAN either way of it (a gain set
    to 0 is left out: a log-uniform search cannot start from it)."""
    return {
        field: (value / GAIN_SPAN, value * GAIN_SPAN) for field, value in gains.items() if value
    }
