"""The linkage alone, its rod motion prescribed: the mechanism side of a co-simulation.

As in the paper's ADAMS model, a velocity driver moves the rod: over an interval the rod
extension is s(t) = s0 + v (t - t0). The 16 linkage states are integrated with fixed RK4 steps
(emasim.plant.linkage.linkage_rhs); what comes back is what the paper's co-simulation
exchanged: the rudder angle and the rod's load force.
"""

import numpy as np

from ..jit import njit
from ..plant import linkage as L


@njit(cache=True, error_model="numpy")
def advance(y, s0, v, duration, substeps, rudder_torque, q, hinges):
    """Integrate y over ``duration`` with the rod at s0 + v t; return the final axial force.

    RK4 with ``substeps`` equal steps; ``hinges`` (4 x 2) ends with the last penetrations and
    normal forces. The axial force is the linkage's push on the rod along its axis (N).
    """
    n = y.size
    h = duration / substeps
    k1, k2, k3, k4, ys = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for j in range(substeps):
        s = s0 + v * j * h
        L.linkage_rhs(y, s, v, rudder_torque, q, k1, hinges)
        for i in range(n):
            ys[i] = y[i] + 0.5 * h * k1[i]
        L.linkage_rhs(ys, s + 0.5 * h * v, v, rudder_torque, q, k2, hinges)
        for i in range(n):
            ys[i] = y[i] + 0.5 * h * k2[i]
        L.linkage_rhs(ys, s + 0.5 * h * v, v, rudder_torque, q, k3, hinges)
        for i in range(n):
            ys[i] = y[i] + h * k3[i]
        L.linkage_rhs(ys, s + h * v, v, rudder_torque, q, k4, hinges)
        for i in range(n):
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    dy = np.empty(n)
    return L.linkage_rhs(y, s0 + v * duration, v, rudder_torque, q, dy, hinges)
