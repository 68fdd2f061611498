"""Linear active disturbance rejection control (ADRC) of the speed loop.

An order-2 extended state observer (observers.py) estimates the speed z1 and the lumped
disturbance z2 of dw/dt = b u + d; the control cancels z2 and leaves a first-order loop of
bandwidth wc:

    iq* = u = (wc (w_ref - z1) + dw_ref/dt - z2) / b

(Gao, "Scaling and bandwidth-parameterization based controller tuning", ACC 2003: observer
bandwidth wo a few times wc.) It is the baseline a practitioner sets beside the GPIO: the same
idea with one extended state fewer.
"""

import math
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from ..interface import M_SPEED, O_RATE, O_VALUE, R_RATE, R_VALUE
from ..numerics import clamp
from .observers import discrete_observer, observer_step
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

WC, B, LIMIT, OBS = range(4)
STARTED, Z = range(2)
ESO_ORDER = 2


@controller_law
def adrc(state, params, meas, ref, ts, out):
    """Linear ADRC law of the module docstring, one sample."""
    w = meas[M_SPEED]
    z = state[Z : Z + ESO_ORDER]
    if state[STARTED] == 0.0:
        z[0] = w
        state[STARTED] = 1.0
    u = (params[WC] * (ref[R_VALUE] - z[0]) + ref[R_RATE] - z[1]) / params[B]
    u = clamp(u, -params[LIMIT], params[LIMIT])
    observer_step(z, params[OBS:], u, w)
    out[O_VALUE] = u
    out[O_RATE] = 0.0


class SpeedADRC(ControllerConfig):
    """Linear ADRC speed controller (iq* out)."""

    loop: ClassVar = "speed"
    name: Literal["adrc"] = "adrc"
    bandwidth_Hz: float = Field(default=50.0, gt=0, le=1e4, description="wc / (2 pi)")
    observer_bandwidth_Hz: float = Field(default=200.0, gt=0, le=1e4, description="wo / (2 pi)")

    def tunable_ranges(self):
        return {"bandwidth_Hz": (5.0, 300.0), "observer_bandwidth_Hz": (20.0, 2000.0)}

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        b = plant.torque_constant_Nm_per_A / plant.inertia_kgm2
        head = np.zeros(OBS)
        head[WC], head[B], head[LIMIT] = 2.0 * math.pi * self.bandwidth_Hz, b, plant.max_current_A
        observer = discrete_observer(ESO_ORDER, 2.0 * math.pi * self.observer_bandwidth_Hz, b, ts)
        return Compiled(adrc, np.concatenate([head, observer]), np.zeros(Z + ESO_ORDER))
