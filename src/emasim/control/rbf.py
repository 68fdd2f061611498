"""Position sliding-mode control, with an RBF network learning the unknown dynamics (eqs. 52-64).

Model of the rod: x'' = g u + f(x', t), u = iq*, g = K kt / J (m/s^2 per A; the paper's
printed 3 np psi_f / (2 J K) has K in the wrong place). With e = x_d - x, s = c e + de/dt:

    h_j   = exp(-||z - c_j||^2 / (2 b^2)),   z = [e / E, de / dE]   (inputs scaled by their range)
    f_hat = W' h
    a*    = c de/dt + xdd_d - f_hat + eps sat(s / phi) + q s          (wanted x'', m/s^2)
    dW/dt = -gamma s h                                                 (Lyapunov-consistent sign)

Along s: ds/dt = -(f - f_hat) - eps sat(s/phi) - q s, and L = s^2/2 + |W~|^2/(2 gamma) decreases
with this adaptation. The q s term (exponential reaching) is ours: with the paper's constant
reaching law alone, a 120 mm step would take eps-limited seconds to reach the surface.
Classic SMC is the same law with no network (f_hat = 0) and a larger eps.

Output, as SPEC 2.3 offers both:
  "current": iq* = a* / g, straight to the current loop;
  "cascade": the speed loop's reference integrates the wanted acceleration,
             w_ref[k+1] = w_ref[k] + Ts a* / K, from the measured speed at the start.
The rod velocity is taken as K times the motor speed (the motor encoder), the position from the
rod sensor. Centres sit on a grid over [-1, 1]^2 of the scaled inputs; widths a quarter of the
range (b = 0.5), the paper's choice; W(0) = 0.
"""

import math
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from ..interface import M_POSITION, M_SPEED, O_RATE, O_VALUE, R_ACCEL, R_RATE, R_VALUE
from ..numerics import boundary_layer, clamp
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

C, EPS, PHI, Q, GAMMA, G, K, I_MAX, W_MAX, CURRENT_MODE = range(10)
E_SCALE, DE_SCALE, WIDTH, N_NODES, CENTRES = range(10, 15)
STARTED, W_REF, F_HAT, WEIGHTS = range(4)


@controller_law
def rbf_sliding_mode(state, params, meas, ref, ts, out):
    """RBF-network sliding-mode position law of the module docstring, one sample."""
    k_ratio = params[K]
    e = ref[R_VALUE] - meas[M_POSITION]
    de = ref[R_RATE] - k_ratio * meas[M_SPEED]
    s = params[C] * e + de
    n = int(params[N_NODES])
    ze, zde = e / params[E_SCALE], de / params[DE_SCALE]
    inv = 1.0 / (2.0 * params[WIDTH] ** 2)
    f_hat = 0.0
    for j in range(n):
        d_e = ze - params[CENTRES + j]
        d_de = zde - params[CENTRES + n + j]
        h = math.exp(-(d_e * d_e + d_de * d_de) * inv)
        f_hat += state[WEIGHTS + j] * h
        state[WEIGHTS + j] -= ts * params[GAMMA] * s * h
    state[F_HAT] = f_hat
    accel = params[C] * de + ref[R_ACCEL] - f_hat + params[EPS] * boundary_layer(s, params[PHI])
    accel += params[Q] * s
    if params[CURRENT_MODE] != 0.0:
        out[O_VALUE] = clamp(accel / params[G], -params[I_MAX], params[I_MAX])
        out[O_RATE] = 0.0
        return
    if state[STARTED] == 0.0:
        state[W_REF] = meas[M_SPEED]
        state[STARTED] = 1.0
    state[W_REF] = clamp(state[W_REF] + ts * accel / k_ratio, -params[W_MAX], params[W_MAX])
    out[O_VALUE] = state[W_REF]
    out[O_RATE] = accel / k_ratio


def grid_centres(per_axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres of a per_axis x per_axis grid on [-1, 1]^2: (e coordinates, de coordinates)."""
    axis = np.linspace(-1.0, 1.0, per_axis) if per_axis > 1 else np.zeros(1)
    e_c, de_c = np.meshgrid(axis, axis, indexing="ij")
    return e_c.ravel(), de_c.ravel()


class PositionSlidingMode(ControllerConfig):
    """``rbf-smc``: sliding mode with an adaptive RBF network; ``smc``: the same, no network."""

    loop: ClassVar = "position"
    name: Literal["rbf-smc", "smc"] = "rbf-smc"
    output: Literal["cascade", "current"] = Field(
        default="cascade", description="command the speed loop, or iq* directly"
    )
    surface_slope_per_s: float = Field(default=20.0, gt=0, le=1e4, description="c")
    switching_gain_m_s2: float | None = Field(
        default=None, ge=0, le=1e6, description="eps; default 0.05 with the network, 1.0 without"
    )
    boundary_layer_m_s: float = Field(default=2e-3, ge=0, le=10, description="phi; 0 = pure sign")
    reaching_rate_per_s: float = Field(default=20.0, ge=0, le=1e6, description="q")
    nodes_per_axis: int = Field(default=3, ge=1, le=6, description="grid of n^2 nodes")
    error_range_mm: float = Field(default=5.0, gt=0, le=1e4, description="E: expected |e|")
    error_rate_range_mm_s: float = Field(
        default=100.0, gt=0, le=1e6, description="dE: expected |de/dt|"
    )
    width: float = Field(default=0.5, gt=0, le=100, description="b, in units of the scaled inputs")
    adaptation_gain: float = Field(default=2e4, ge=0, le=1e9, description="gamma")

    def tunable_ranges(self):
        ranges = {
            "surface_slope_per_s": (1.0, 200.0),
            "reaching_rate_per_s": (1.0, 200.0),
            "switching_gain_m_s2": (1e-3, 10.0),
            "boundary_layer_m_s": (1e-4, 0.1),
        }
        if self.name == "rbf-smc":
            ranges["adaptation_gain"] = (1e2, 1e6)
        return ranges

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        network = self.name == "rbf-smc"
        eps = self.switching_gain_m_s2
        if eps is None:
            eps = 0.05 if network else 1.0
        e_c, de_c = grid_centres(self.nodes_per_axis) if network else (np.zeros(0), np.zeros(0))
        k = plant.ratio_m_per_rad
        head = np.zeros(CENTRES)
        head[[C, EPS, PHI, Q]] = (
            self.surface_slope_per_s,
            eps,
            self.boundary_layer_m_s,
            self.reaching_rate_per_s,
        )
        head[GAMMA] = self.adaptation_gain
        head[G] = k * plant.torque_constant_Nm_per_A / plant.inertia_kgm2
        head[K], head[I_MAX], head[W_MAX] = k, plant.max_current_A, plant.max_speed_rad_s
        head[CURRENT_MODE] = float(self.output == "current")
        head[E_SCALE] = self.error_range_mm * 1e-3
        head[DE_SCALE] = self.error_rate_range_mm_s * 1e-3
        head[WIDTH], head[N_NODES] = self.width, e_c.size
        params = np.concatenate([head, e_c, de_c])
        commands = "current" if self.output == "current" else "speed"
        return Compiled(rbf_sliding_mode, params, np.zeros(WEIGHTS + e_c.size), commands)
