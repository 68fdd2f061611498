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

The observer is linear, so it is discretised exactly (zero-order hold on u and w over one sample:
expm of the block matrix [[A, B], [0, 0]] Ts gives [[Ad, Bd], [0, I]]) and runs as
z[k+1] = Ad z[k] + Bd [u[k], w[k]], stable for any wo Ts.
"""

import math

import numba as nb
import numpy as np
from scipy.linalg import expm


def observer_gains(order: int, bandwidth_rad_s: float) -> np.ndarray:
    """Gains placing all ``order`` poles at -wo: binomial coefficients of (s + wo)^order."""
    return np.array(
        [math.comb(order, i) * bandwidth_rad_s**i for i in range(1, order + 1)], dtype=float
    )


def discrete_observer(order: int, bandwidth_rad_s: float, b: float, ts: float) -> np.ndarray:
    """Packed [Ad (order x order), Bd (order x 2)] of the observer, row-major, for ZOH at ts."""
    gains = observer_gains(order, bandwidth_rad_s)
    a = np.zeros((order, order))
    a[:, 0] = -gains
    a[:-1, 1:] += np.eye(order - 1)  # chain of integrators: z_i' gets z_{i+1}
    inputs = np.zeros((order, 2))
    inputs[0, 0] = b  # b u enters the speed estimate
    inputs[:, 1] = gains  # the measured speed drives every row
    block = np.zeros((order + 2, order + 2))
    block[:order, :order] = a
    block[:order, order:] = inputs
    discrete = expm(block * ts)
    return np.concatenate([discrete[:order, :order].ravel(), discrete[:order, order:].ravel()])


@nb.njit(cache=True, error_model="numpy")
def observer_step(z, packed, u, w):
    """z <- Ad z + Bd [u, w] in place; packed as built by :func:`discrete_observer`."""
    n = z.size
    new = np.empty(n)
    for i in range(n):
        acc = packed[n * n + 2 * i] * u + packed[n * n + 2 * i + 1] * w
        for j in range(n):
            acc += packed[n * i + j] * z[j]
        new[i] = acc
    z[:] = new
