"""Classic sliding-mode speed control with an exponential reaching law.

Speed loop dw/dt = b u + d, sliding variable s = w - w_ref (rad/s), reaching law
ds/dt = -eps sat(s/phi) - q s, hence

    iq* = u = (dw_ref/dt - eps sat(s / phi) - q s) / b,       b = kt / J

(Utkin; Gao & Hung, IEEE TIE 40(1), 1993). phi = 0 gives the discontinuous sign law and its
chattering; phi > 0 a boundary layer, inside which the law is proportional with a residual
error of about phi |d| / eps. eps must exceed the disturbance |d| (rad/s^2) for s to reach 0.
"""

from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from ..interface import M_SPEED, O_RATE, O_VALUE, R_RATE, R_VALUE
from ..numerics import boundary_layer, clamp
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

EPS, Q, PHI, B, LIMIT = range(5)
N_PARAMS = 5


@controller_law
def sliding_mode_speed(state, params, meas, ref, ts, out):
    """Classic SMC of the module docstring."""
    s = meas[M_SPEED] - ref[R_VALUE]
    accel = ref[R_RATE] - params[EPS] * boundary_layer(s, params[PHI]) - params[Q] * s
    out[O_VALUE] = clamp(accel / params[B], -params[LIMIT], params[LIMIT])
    out[O_RATE] = 0.0


class SpeedSMC(ControllerConfig):
    """Classic sliding-mode speed controller (iq* out)."""

    loop: ClassVar = "speed"
    name: Literal["smc"] = "smc"
    switching_gain_rad_s2: float = Field(
        default=6000.0, gt=0, le=1e9, description="eps: must exceed the disturbance |d| = |TL|/J"
    )
    reaching_rate_per_s: float = Field(default=300.0, ge=0, le=1e6, description="q")
    boundary_layer_rad_s: float = Field(default=1.0, ge=0, le=1e4, description="phi; 0 = pure sign")

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        params = np.zeros(N_PARAMS)
        params[EPS] = self.switching_gain_rad_s2
        params[Q] = self.reaching_rate_per_s
        params[PHI] = self.boundary_layer_rad_s
        params[B] = plant.torque_constant_Nm_per_A / plant.inertia_kgm2
        params[LIMIT] = plant.max_current_A
        return Compiled(sliding_mode_speed, params, np.zeros(1))

    def tunable_ranges(self):
        return {
            "switching_gain_rad_s2": (1e3, 3e4),
            "reaching_rate_per_s": (10.0, 3000.0),
            "boundary_layer_rad_s": (0.05, 20.0),
        }
