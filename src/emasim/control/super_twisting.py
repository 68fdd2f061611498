"""Super-twisting speed control: classic (eq. 24), improved (eq. 36), and with a GPIO (eq. 51).

Speed error x1 = w - w_ref (rad/s), plant dx1/dt = b u + d(t), output u = iq* (A):

    classic   u = -beta |x1|^(1/2) sign(x1) + u1,   du1/dt = -u if |u| > Umax else -k sign(x1)
    improved  u = -beta |x1|^(1/2) sat1(x1) + u1,   du1/dt = -k sat2(x1)
              sat1(x) = sign(x) if |x| >= mu else x / mu^alpha
              sat2(x) = sign(x) if |x| >= mu else x |x| / mu^(2 alpha)
    st-gpio   u = improved law - z2 / b   (z2: the GPIO's estimate of d, see observers.py)

(Ding & Zhou 2025, eqs. 24, 36, 50, 51; Levant, Int. J. Control 58(6), 1993.) With alpha != 1
sat1 jumps at |x1| = mu, as the paper designed it; alpha = 1 makes the law continuous.
The output is limited to the drive's current; u1 stops integrating while the output is held at
the limit in the direction it pushes (conditional integration).

Gains. For |dd/dt| <= L (rad/s^3), Levant's rule on the normalised plant x1' = v + d, v = b u,
is beta_n = 1.5 sqrt(L), k_n = 1.1 L; beta = beta_n / b, k = k_n / b. The paper's eq. 37
(beta_n > 2 D, k_n > beta_n (5 D beta_n + 4 D^2) / (2 beta_n - 4 D)) is checked and a warning
names the inequality it violates. Its D is not L: in the paper's proof it bounds the part of
the disturbance that vanishes with the error, |d1| <= D |x1|^(1/2) (d1 = l Psi1, Moreno &
Osorio's delta1), so it is a separate input, ``eq37_bound``.
"""

import math
import warnings
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from ..interface import M_SPEED, O_RATE, O_VALUE, R_RATE, R_VALUE
from ..jit import njit
from ..numerics import clamp, sign
from .observers import discrete_observer, observer_step
from .slot import Compiled, ControllerConfig, PlantFacts, controller_law

BETA, K, MU, ALPHA, IMPROVED, U_MAX, B, LIMIT, OBSERVER, FEEDFORWARD, OBS = range(11)
U1, STARTED, Z = range(3)  # Z: first of the 3 GPIO states
GPIO_ORDER = 3


@njit(cache=True, inline="always", error_model="numpy")
def _sat1(x, mu, alpha):
    return sign(x) if abs(x) >= mu else x / mu**alpha


@njit(cache=True, inline="always", error_model="numpy")
def _sat2(x, mu, alpha):
    return sign(x) if abs(x) >= mu else x * abs(x) / mu ** (2.0 * alpha)


@controller_law
def super_twisting(state, params, meas, ref, ts, out):
    """The three super-twisting laws of the module docstring, one sample."""
    w = meas[M_SPEED]
    z = state[Z : Z + GPIO_ORDER]
    if params[OBSERVER] != 0.0 and state[STARTED] == 0.0:
        z[0] = w
    state[STARTED] = 1.0
    x1 = w - ref[R_VALUE]
    beta, k, b, limit = params[BETA], params[K], params[B], params[LIMIT]
    if params[IMPROVED] != 0.0:
        s1 = _sat1(x1, params[MU], params[ALPHA])
        du1 = -k * _sat2(x1, params[MU], params[ALPHA])
    else:
        s1 = sign(x1)
        du1 = -k * s1
    u = -beta * math.sqrt(abs(x1)) * s1 + state[U1]
    if params[OBSERVER] != 0.0:
        u -= z[1] / b
    if params[FEEDFORWARD] != 0.0:
        u += ref[R_RATE] / b
    if params[IMPROVED] == 0.0 and abs(u) > params[U_MAX]:
        du1 = -u  # eq. 24: pull the control back into [-Umax, Umax]
    u_sat = clamp(u, -limit, limit)
    if u_sat != u and du1 * (u - u_sat) > 0.0:
        du1 = 0.0  # held at the limit: do not wind u1 further
    state[U1] += ts * du1
    if params[OBSERVER] != 0.0:
        observer_step(z, params[OBS:], u_sat, w)
    out[O_VALUE] = u_sat
    out[O_RATE] = 0.0


def eq37_violations(beta_n: float, k_n: float, bound: float) -> list[str]:
    """The inequalities of the paper's eq. 37 that normalised gains (b*beta, b*k) violate."""
    problems = []
    if not beta_n > 2.0 * bound:
        problems.append(f"beta*b > 2D fails: {beta_n:.4g} <= {2 * bound:.4g}")
    else:
        needed = beta_n * (5 * bound * beta_n + 4 * bound**2) / (2 * beta_n - 4 * bound)
        if not k_n > needed:
            problems.append(
                f"k*b > beta(5 D beta + 4 D^2)/(2 beta - 4 D) fails: {k_n:.4g} <= {needed:.4g}"
            )
    return problems


class SpeedSuperTwisting(ControllerConfig):
    """Super-twisting speed controllers: ``st`` (eq. 24), ``st-improved`` (36), ``st-gpio`` (51)."""

    loop: ClassVar = "speed"
    name: Literal["st", "st-improved", "st-gpio"] = "st-gpio"
    disturbance_rate_bound_rad_s3: float = Field(
        default=2e5, gt=0, le=1e12, description="L >= |dd/dt|; sets beta and k by Levant's rule"
    )
    beta: float | None = Field(default=None, gt=0, le=1e6, description="A/(rad/s)^0.5; overrides L")
    k_A_per_s: float | None = Field(default=None, gt=0, le=1e9, description="overrides L")
    boundary_layer_rad_s: float = Field(
        default=0.5,
        gt=0,
        lt=1,
        description="mu (improved): the boundary layer, 0 < mu < 1 as the paper sets it "
        "(the text of its eq. 36)",
    )
    exponent: float = Field(default=0.6, gt=0, le=1, description="alpha (improved), 1 = continuous")
    observer_bandwidth_Hz: float = Field(default=150.0, gt=0, le=1e4, description="GPIO wo/(2 pi)")
    acceleration_feedforward: bool = Field(default=False, description="add dw_ref/dt / b")
    eq37_bound: float = Field(
        default=10.0, ge=0, le=1e6, description="D of eq. 37: |d1| <= D |x1|^0.5, normalised units"
    )

    def tunable_ranges(self):
        ranges = {"disturbance_rate_bound_rad_s3": (1e4, 1e7)}
        if self.name != "st":
            ranges["boundary_layer_rad_s"] = (0.05, 0.95)
        if self.name == "st-gpio":
            ranges["observer_bandwidth_Hz"] = (20.0, 1000.0)
        return ranges

    def gains(self, b: float) -> tuple[float, float]:
        """(beta, k) in A/(rad/s)^0.5 and A/s, from the overrides or from the bound L."""
        bound = self.disturbance_rate_bound_rad_s3
        beta = self.beta if self.beta is not None else 1.5 * math.sqrt(bound) / b
        k = self.k_A_per_s if self.k_A_per_s is not None else 1.1 * bound / b
        return beta, k

    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        b = plant.torque_constant_Nm_per_A / plant.inertia_kgm2
        beta, k = self.gains(b)
        for problem in eq37_violations(b * beta, b * k, self.eq37_bound):
            warnings.warn(f"{self.name}: paper eq. 37: {problem}", stacklevel=2)
        gpio = self.name == "st-gpio"
        head = np.zeros(OBS)
        head[[BETA, K, MU, ALPHA]] = beta, k, self.boundary_layer_rad_s, self.exponent
        head[IMPROVED] = float(self.name != "st")
        head[U_MAX] = head[LIMIT] = plant.max_current_A
        head[B] = b
        head[OBSERVER] = float(gpio)
        head[FEEDFORWARD] = float(self.acceleration_feedforward)
        wo = 2.0 * math.pi * self.observer_bandwidth_Hz
        observer = discrete_observer(GPIO_ORDER, wo, b, ts)
        return Compiled(super_twisting, np.concatenate([head, observer]), np.zeros(Z + GPIO_ORDER))
