"""Fuzzy-adaptive PI for the position loop: a 7x7 Mamdani rule base retunes Kp and Ki online.

Inputs, normalised and clipped to [-1, 1]: e_n = e / E and ec_n = (de/dt) / dE, with e the rod
position error (m). Seven triangular sets NB, NM, NS, ZO, PS, PM, PB evenly spread over
[-1, 1] describe both inputs and both outputs. The rules (tables below, rows e_n, columns ec_n)
follow the usual servo practice (e.g. Tang, Man & Chen, IEEE TIE 48(4), 2001):
  * Kp grows with |e| for a fast approach, and grows further while the error grows (e and ec of
    the same sign), shrinks while it already closes (opposite signs), against overshoot;
  * Ki is small at large |e| (no windup on the approach) and large near the target, where it
    removes the steady error.
Both tables are symmetric, rule(e, ec) = rule(-e, -ec). Mamdani inference (min for AND,
clipping, max aggregation, centroid) gives dKp_n, dKi_n in [-1, 1] on a 41 x 41 grid,
computed once when the controller is built; the compiled law interpolates it bilinearly.

    Kp = Kp0 (1 + span_p dKp_n),   Ki = Ki0 (1 + span_i dKi_n)
    w_ref = (Kp e + I + Kff dx_ref/dt) / K,   dI/dt = Ki e + Kaw (u_sat - u)

Kp0 and Ki0 come from a bandwidth as for the position PI (pid.py).
"""

import math
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from ..interface import M_POSITION, M_SPEED, O_RATE, O_VALUE, R_ACCEL, R_RATE, R_VALUE
from ..jit import njit
from ..numerics import clamp
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

# rule tables, levels -3 (NB) .. +3 (PB); rows e = NB..PB, columns ec = NB..PB
KP_RULES = np.array(
    [
        [3, 3, 3, 3, 2, 2, 1],
        [3, 2, 2, 2, 1, 1, 0],
        [2, 1, 1, 0, -1, -1, -1],
        [0, -1, -2, -3, -2, -1, 0],
        [-1, -1, -1, 0, 1, 1, 2],
        [0, 1, 1, 2, 2, 2, 3],
        [1, 2, 2, 3, 3, 3, 3],
    ],
    dtype=float,
)
KI_RULES = np.array(
    [
        [-3, -3, -3, -3, -3, -3, -3],
        [-2, -2, -2, -2, -2, -2, -2],
        [0, 0, 0, 0, 0, 0, 0],
        [2, 3, 3, 3, 3, 3, 2],
        [0, 0, 0, 0, 0, 0, 0],
        [-2, -2, -2, -2, -2, -2, -2],
        [-3, -3, -3, -3, -3, -3, -3],
    ],
    dtype=float,
)
GRID = 41

KP0, KI0, SPAN_P, SPAN_I, E_SCALE, DE_SCALE, K, W_MAX, KFF, SURFACE = range(10)
INTEGRAL = 0


def _memberships(x: np.ndarray) -> np.ndarray:
    """Degrees (len(x) x 7) of the seven triangular sets centred at -1, -2/3, ..., 1."""
    centres = np.linspace(-1.0, 1.0, 7)
    return np.clip(1.0 - np.abs(x[:, None] - centres[None, :]) * 3.0, 0.0, 1.0)


def mamdani_surface(rules: np.ndarray, grid: int = GRID) -> np.ndarray:
    """Output of the rule table on a grid x grid mesh of (e_n, ec_n) in [-1, 1]^2.

    min for AND, each rule's output set clipped at its firing degree, max over rules, centroid
    over a 401-point output universe.
    """
    axis = np.linspace(-1.0, 1.0, grid)
    universe = np.linspace(-1.0, 1.0, 401)
    mu_in = _memberships(axis)  # grid x 7
    mu_out = _memberships(universe).T  # 7 x 401, set index first
    aggregate = np.zeros((grid, grid, universe.size))
    for i in range(7):
        for j in range(7):
            firing = np.minimum(mu_in[:, i, None], mu_in[None, :, j])  # grid x grid
            output_set = mu_out[int(rules[i, j]) + 3]
            np.maximum(aggregate, np.minimum(firing[..., None], output_set), out=aggregate)
    return (aggregate @ universe) / aggregate.sum(axis=-1)


@njit(cache=True, error_model="numpy")
def _bilinear(table, x, y):
    """Bilinear interpolation of a square table over [-1, 1]^2 at (x, y)."""
    n = table.shape[0]
    fx = (clamp(x, -1.0, 1.0) + 1.0) * 0.5 * (n - 1)
    fy = (clamp(y, -1.0, 1.0) + 1.0) * 0.5 * (n - 1)
    i = min(int(fx), n - 2)
    j = min(int(fy), n - 2)
    tx, ty = fx - i, fy - j
    return (
        table[i, j] * (1 - tx) * (1 - ty)
        + table[i + 1, j] * tx * (1 - ty)
        + table[i, j + 1] * (1 - tx) * ty
        + table[i + 1, j + 1] * tx * ty
    )


@controller_law
def fuzzy_pi(state, params, meas, ref, ts, out):
    """Fuzzy-adaptive position PI of the module docstring (speed command out)."""
    k_ratio = params[K]
    e = ref[R_VALUE] - meas[M_POSITION]
    de = ref[R_RATE] - k_ratio * meas[M_SPEED]
    size = GRID * GRID
    kp_table = params[SURFACE : SURFACE + size].reshape((GRID, GRID))
    ki_table = params[SURFACE + size : SURFACE + 2 * size].reshape((GRID, GRID))
    e_n, de_n = e / params[E_SCALE], de / params[DE_SCALE]
    kp = params[KP0] * (1.0 + params[SPAN_P] * _bilinear(kp_table, e_n, de_n))
    ki = params[KI0] * (1.0 + params[SPAN_I] * _bilinear(ki_table, e_n, de_n))
    u = (kp * e + state[INTEGRAL] + params[KFF] * ref[R_RATE]) / k_ratio
    u_sat = clamp(u, -params[W_MAX], params[W_MAX])
    kaw = ki / kp if kp > 0.0 else 0.0
    state[INTEGRAL] += ts * (ki * e + kaw * k_ratio * (u_sat - u))
    out[O_VALUE] = u_sat
    out[O_RATE] = params[KFF] * ref[R_ACCEL] / k_ratio


class PositionFuzzyPI(ControllerConfig):
    """Fuzzy-adaptive position PI (speed command out)."""

    loop: ClassVar = "position"
    name: Literal["fuzzy-pi"] = "fuzzy-pi"
    bandwidth_Hz: float = Field(default=4.0, gt=0, le=1e3, description="sets Kp0, Ki0 as for pi")
    kp_span: float = Field(default=0.5, ge=0, lt=1, description="Kp varies by +-span")
    ki_span: float = Field(default=0.5, ge=0, lt=1, description="Ki varies by +-span")
    error_range_mm: float = Field(default=2.0, gt=0, le=1e4, description="E: |e| mapped to 1")
    error_rate_range_mm_s: float = Field(default=50.0, gt=0, le=1e6, description="dE")
    velocity_feedforward: bool = True

    def tunable_ranges(self):
        return {
            "bandwidth_Hz": (0.2, 20.0),
            "kp_span": (0.05, 0.95),
            "ki_span": (0.05, 0.95),
            "error_range_mm": (0.05, 50.0),
        }

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        alpha = 2.0 * math.pi * self.bandwidth_Hz
        k = plant.ratio_m_per_rad
        head = np.zeros(SURFACE)
        head[[KP0, KI0, SPAN_P, SPAN_I]] = 2.0 * alpha, alpha**2, self.kp_span, self.ki_span
        head[E_SCALE] = self.error_range_mm * 1e-3
        head[DE_SCALE] = self.error_rate_range_mm_s * 1e-3
        head[K], head[W_MAX] = k, plant.max_speed_rad_s
        head[KFF] = float(self.velocity_feedforward)
        surfaces = [mamdani_surface(KP_RULES).ravel(), mamdani_surface(KI_RULES).ravel()]
        return Compiled(fuzzy_pi, np.concatenate([head, *surfaces]), np.zeros(1), "speed")
