"""Extended-state observers for the speed loop: the linear ESO (order 2) and the GPIO (order 3).

For the speed loop written as dw/dt = b u + d(t) (b = kt/J, d the lumped disturbance), an
observer of order n estimates w and the first n - 1 "derivatives" of the disturbance:

    order 2 (ESO, ADRC):  dz1/dt = z2 + l1 (w - z1) + b u,   dz2/dt = l2 (w - z1)
    order 3 (GPIO, paper eq. 50):
        dz1/dt = b1 (w - z1) + b u + z2,  dz2/dt = b2 (w - z1) + z3,  dz3/dt = b3 (w - z1)

so z1 ~ w, z2 ~ d, z3 ~ dd/dt. The gains put every observer pole at -wo:
(l1, l2) = (2 wo, wo^2) and (b1, b2, b3) = (3 wo, 3 wo^2, wo^3). The order-2 observer assumes d
constant: under a ramp disturbance d = a t its estimate settles at z2 = d - 2a/wo (error
dynamics e1' = e2 - l1 e1, e2' = a - l2 e1 at rest give e2 = l1 a / l2). The GPIO also models
dd/dt and tracks the ramp with no steady error (Sira-Ramirez, GPI observers).

The controllers run it in discrete time, designed on the exactly sampled plant rather than by
discretising the continuous observer (which would treat the measured w as held over a sample
and bias z2 by about (wo Ts)^2/4): with x = [w, d, dd/dt, ...] the chain of integrators
sampled with u held gives x[k+1] = Phi x[k] + Gamma u[k] exactly, and the observer

    z[k+1] = Phi z[k] + Gamma u[k] + L (w[k] - z1[k])

has its error poles, the eigenvalues of Phi - L C, all at exp(-wo Ts): the images of the
continuous design's -wo (Ackermann's formula). A constant (ESO) or ramp (GPIO) disturbance is
then estimated with no steady error, for any wo Ts; under a ramp the ESO's lag is the
continuous 2a/wo made larger by a relative wo Ts / 4 + O((wo Ts)^2).
"""

import math

import numpy as np

from ..jit import njit


def observer_gains(order: int, bandwidth_rad_s: float) -> np.ndarray:
    """Gains placing all ``order`` poles at -wo: binomial coefficients of (s + wo)^order."""
    return np.array(
        [math.comb(order, i) * bandwidth_rad_s**i for i in range(1, order + 1)], dtype=float
    )


def sampled_plant(order: int, b: float, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) of x = [w, d, dd/dt, ...] (order states), sampled exactly with u held."""
    from scipy.linalg import expm  # here: checking a scenario needs no scipy

    block = np.zeros((order + 1, order + 1))
    block[: order - 1, 1:order] = np.eye(order - 1)  # w' = d + b u, d' = d1, ...
    block[0, order] = b
    discrete = expm(block * ts)
    return discrete[:order, :order], discrete[:order, order]


def discrete_observer(order: int, bandwidth_rad_s: float, b: float, ts: float) -> np.ndarray:
    """Packed [Phi (order x order), Gamma (order), L (order)] of the sampled observer.

    L places every eigenvalue of Phi - L C at exp(-wo Ts) (Ackermann: L = P(Phi) O^-1 e_n, P
    the desired characteristic polynomial, O the observability matrix of (Phi, C)).
    """
    phi, gamma = sampled_plant(order, b, ts)
    c = np.zeros(order)
    c[0] = 1.0
    observability = np.array([c @ np.linalg.matrix_power(phi, i) for i in range(order)])
    # P(Phi) = (Phi - p I)^order with p = exp(-wo Ts); written as (Phi - I + q I), q = 1 - p
    # from expm1, so that small wo Ts loses no digits to cancellation
    q = -math.expm1(-bandwidth_rad_s * ts)
    nilpotent = phi - np.eye(order)  # exact: Phi has ones on its diagonal
    p_of_phi = np.linalg.matrix_power(nilpotent + q * np.eye(order), order)
    unit = np.zeros(order)
    unit[-1] = 1.0
    gain = p_of_phi @ np.linalg.solve(observability, unit)
    return np.concatenate([phi.ravel(), gamma, gain])


@njit(cache=True, error_model="numpy")
def observer_step(z, packed, u, w):
    """z <- Phi z + Gamma u + L (w - z1) in place; packed as built by discrete_observer."""
    n = z.size
    innovation = w - z[0]
    new = np.empty(n)
    for i in range(n):
        acc = packed[n * n + i] * u + packed[n * n + n + i] * innovation
        for j in range(n):
            acc += packed[n * i + j] * z[j]
        new[i] = acc
    z[:] = new
