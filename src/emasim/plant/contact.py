"""Contact of a pin in a hole: the ADAMS IMPACT normal force and its stiction/dynamic friction.

Normal force at penetration delta >= 0 and penetration rate delta_dot (Ding & Zhou 2025,
Table 1; MSC ADAMS IMPACT):

    Fn = max(0, K delta^e + STEP(delta, 0, 0, d, C) delta_dot)

The damping ramps in over the first d of penetration (the cubic STEP), so the force is
continuous at first contact, and the max() means the contact never pulls on separation.
Friction opposes the slip speed v_t with a coefficient odd and continuous in v_t (ADAMS):

    mu(v) = STEP(v, -Vs, -mu_s, Vs, mu_s)                     |v| <= Vs
          = STEP(|v|, Vs, mu_s, Vd, mu_d) sign(v)             Vs < |v| < Vd
          = mu_d sign(v)                                      |v| >= Vd

and Ft = -mu(v_t) Fn. STEP(x, x0, h0, x1, h1) = h0 + (h1 - h0) a^2 (3 - 2 a),
a = (x - x0)/(x1 - x0) clipped to [0, 1].

Units: SI inside (m, m/s, N). Table 1 gives K in N/mm^e, so K_SI = K_mm * 1000^e (3.98e11 N/m^2.2
for the paper's 1e5 N/mm^2.2 and e = 2.2), C in N s/mm (x1000), d and speeds in mm (/1000).
"""

import numpy as np
from pydantic import Field, model_validator

from ..config import MM, Strict
from ..jit import njit

# packed contact parameters (SI)
C_K, C_E, C_DAMP, C_DEPTH, C_MU_S, C_MU_D, C_VS, C_VD = range(8)
N_CONTACT = 8


@njit(cache=True, inline="always", error_model="numpy")
def step(x, x0, h0, x1, h1):
    """ADAMS STEP: a cubic from (x0, h0) to (x1, h1) with zero slope at both ends."""
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    a = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * a * a * (3.0 - 2.0 * a)


@njit(cache=True, inline="always", error_model="numpy")
def penetration_power(delta, c):
    """delta ** e (0 when apart): the IMPACT law's one call of libm. The linkage calls it for
    its four hinges together, before their other work, so that the processor overlaps the
    four (emasim.plant.elements.linkage.linkage_rhs)."""
    return delta ** c[C_E] if delta > 0.0 else 0.0


@njit(cache=True, inline="always", error_model="numpy")
def normal_force_of(power, delta, delta_dot, c):
    """:func:`normal_force` with its ``power`` = penetration_power(delta, c) given."""
    if delta <= 0.0:
        return 0.0
    damping = step(delta, 0.0, 0.0, c[C_DEPTH], c[C_DAMP])
    return max(0.0, c[C_K] * power + damping * delta_dot)


@njit(cache=True, inline="always", error_model="numpy")
def normal_force(delta, delta_dot, c):
    """IMPACT normal force (N) for penetration delta (m) and its rate (m/s); 0 when apart."""
    return normal_force_of(penetration_power(delta, c), delta, delta_dot, c)


@njit(cache=True, inline="always", error_model="numpy")
def friction_coefficient(v, c):
    """ADAMS friction coefficient mu(v) for slip speed v (m/s): odd, continuous, |mu| <= mu_s."""
    vs, vd, mu_s, mu_d = c[C_VS], c[C_VD], c[C_MU_S], c[C_MU_D]
    speed = abs(v)
    if speed <= vs:
        return step(v, -vs, -mu_s, vs, mu_s)
    magnitude = step(speed, vs, mu_s, vd, mu_d)
    return magnitude if v > 0.0 else -magnitude


class ContactParams(Strict):
    """Hinge contact law, in the units of the paper's Table 1."""

    stiffness_N_per_mm_e: float = Field(gt=0, le=1e12, description="K, in N/mm^exponent")
    exponent: float = Field(ge=1, le=5, description="e (Hertz: 1.5; the paper 2.2)")
    damping_Ns_per_mm: float = Field(
        ge=0, le=1e6, description="C, reached at full penetration depth"
    )
    penetration_depth_mm: float = Field(gt=0, le=10, description="d, where damping is fully on")
    mu_static: float = Field(ge=0, le=2)
    mu_dynamic: float = Field(ge=0, le=2)
    stiction_speed_mm_s: float = Field(gt=0, le=1e6, description="Vs")
    dynamic_speed_mm_s: float = Field(gt=0, le=1e6, description="Vd > Vs")

    @model_validator(mode="after")
    def _ordered(self):
        """ADAMS requires Vs < Vd and mu_s >= mu_d (the paper: "Vs < Vd and mu_s > mu_d")."""
        if self.dynamic_speed_mm_s <= self.stiction_speed_mm_s:
            raise ValueError(
                f"dynamic_speed_mm_s ({self.dynamic_speed_mm_s}) must exceed "
                f"stiction_speed_mm_s ({self.stiction_speed_mm_s})"
            )
        if self.mu_dynamic > self.mu_static:
            raise ValueError(
                f"mu_dynamic ({self.mu_dynamic}) must not exceed mu_static ({self.mu_static})"
            )
        return self

    def pack(self) -> np.ndarray:
        """SI array read by :func:`normal_force` and :func:`friction_coefficient`."""
        c = np.zeros(N_CONTACT)
        c[C_K] = self.stiffness_N_per_mm_e * 1000.0**self.exponent
        c[C_E] = self.exponent
        c[C_DAMP] = self.damping_Ns_per_mm * 1000.0
        c[C_DEPTH] = self.penetration_depth_mm * MM
        c[C_MU_S], c[C_MU_D] = self.mu_static, self.mu_dynamic
        c[C_VS] = self.stiction_speed_mm_s * MM
        c[C_VD] = self.dynamic_speed_mm_s * MM
        return c
