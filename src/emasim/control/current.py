"""Field-oriented current control: PI on id and iq with decoupling and anti-windup.

    ud* = Kp_d (id* - id) + I_d - we Lq iq
    uq* = Kp_q (iq* - iq) + I_q + we (Ld id + psi_f)
    (ud, uq) = (ud*, uq*) limited to |u| <= Udc/sqrt(3)
    dI_x/dt = Ki_x (e_x + (u_x - u_x*) / Kp_x)          (back-calculation, realised voltage)

id* = 0. Internal-model gains for bandwidth alpha_c: Kp_d = alpha_c Ld, Kp_q = alpha_c Lq,
Ki = alpha_c Rs, which cancel the R-L pole and leave a first-order current response of
bandwidth alpha_c (Harnefors & Nee, IEEE TIA 34(1), 1998). The current loop is the same for
every speed and position controller.
"""

import math

import numpy as np
from pydantic import BaseModel, Field

from ..config import STRICT
from ..interface import M_ID, M_IQ, M_SPEED, O_UD, O_UQ, R_VALUE
from ..jit import njit
from ..numerics import limit_magnitude
from .slot import Compiled, PlantFacts, controller_law

KP_D, KP_Q, KI_D, KI_Q, LD, LQ, PSI, NP, U_MAX = range(9)
N_PARAMS = 9
I_D, I_Q = range(2)
N_STATE = 2


@njit(cache=True, error_model="numpy")
def current_control(state, params, i_d, i_q, w_m, id_ref, iq_ref, ts):
    """One sample of the current loop; returns the realised (ud, uq) in V."""
    w_e = params[NP] * w_m
    e_d = id_ref - i_d
    e_q = iq_ref - i_q
    ud_req = params[KP_D] * e_d + state[I_D] - w_e * params[LQ] * i_q
    uq_req = params[KP_Q] * e_q + state[I_Q] + w_e * (params[LD] * i_d + params[PSI])
    u_d, u_q = limit_magnitude(ud_req, uq_req, params[U_MAX])
    state[I_D] += ts * params[KI_D] * (e_d + (u_d - ud_req) / params[KP_D])
    state[I_Q] += ts * params[KI_Q] * (e_q + (u_q - uq_req) / params[KP_Q])
    return u_d, u_q


@controller_law
def current_loop(state, params, meas, ref, ts, out):
    """:func:`current_control` in the slot convention: iq* = ref[R_VALUE], id* = 0, the
    measured currents and speed from ``meas``; writes (ud, uq) to out[O_UD], out[O_UQ]."""
    out[O_UD], out[O_UQ] = current_control(
        state, params, meas[M_ID], meas[M_IQ], meas[M_SPEED], 0.0, ref[R_VALUE], ts
    )


class CurrentPI(BaseModel):
    """Current-loop design by bandwidth (default 2 pi 500 rad/s)."""

    model_config = STRICT
    bandwidth_Hz: float = Field(default=500.0, gt=0, le=5e4, description="alpha_c / (2 pi)")

    def pack(self, plant: PlantFacts) -> tuple[np.ndarray, np.ndarray]:
        """(params, initial state) of :func:`current_control`."""
        alpha = 2.0 * math.pi * self.bandwidth_Hz
        params = np.zeros(N_PARAMS)
        params[KP_D] = alpha * plant.inductance_d_H
        params[KP_Q] = alpha * plant.inductance_q_H
        params[KI_D] = params[KI_Q] = alpha * plant.resistance_ohm
        params[LD], params[LQ] = plant.inductance_d_H, plant.inductance_q_H
        params[PSI], params[NP] = plant.flux_linkage_Wb, plant.pole_pairs
        params[U_MAX] = plant.max_voltage_V
        return params, np.zeros(N_STATE)

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        """The current loop for its slot (:func:`current_loop`); ``ts`` is not needed: the PI
        is designed in continuous time."""
        params, state = self.pack(plant)
        return Compiled(current_loop, params, state, commands="voltage")
