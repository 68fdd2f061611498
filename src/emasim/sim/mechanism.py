"""The rudder side alone, its rod motion prescribed: the mechanism side of a co-simulation.

As in the paper's ADAMS model, a velocity driver moves the rod: over an interval the rod
extension is s(t) = s0 + v (t - t0). The rudder side's states, the linkage's 16 and, when the
plant has them, the rudder shaft's disk and the load motor (rows X_MECHANISM.. of the plant
state, emasim.plant.actuator), are integrated with fixed RK4 steps; what comes back is what the
paper's co-simulation exchanged: the rudder angle and the rod's load force.
"""

import numpy as np

from ..jit import njit
from ..plant import actuator as A


@njit(cache=True, inline="always", error_model="numpy")
def mechanism_rates(x, s, v, t_rudder, p, dx, hinges):
    """dx/dt of the rudder side of the plant state x with the rod at s moving at v (the rod
    rows of x are set to them; the drive's rows of dx are of no use here); return the
    linkage's axial force on the rod (N), the force the plant's right-hand side exchanges.
    t_rudder is the rudder load, opposing positive deflection."""
    x[A.X_XL], x[A.X_VL] = s, v
    return A.rhs(x, 0.0, 0.0, 0.0, 0.0, t_rudder, p, dx, hinges)


@njit(cache=True, error_model="numpy")
def advance_rudder_side(x, s0, v, duration, substeps, t_rudder, p, hinges):
    """Integrate the rudder side of x (rows X_MECHANISM..) over ``duration`` with the rod at
    s0 + v t; return the final axial force (N). RK4 with ``substeps`` equal steps; ``hinges``
    (4 x 2) ends with the last penetrations and normal forces."""
    n = x.size
    h = duration / substeps
    k1, k2, k3, k4, xs = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), x.copy()
    for j in range(substeps):
        s = s0 + v * j * h
        mechanism_rates(x, s, v, t_rudder, p, k1, hinges)
        for i in range(A.X_MECHANISM, n):
            xs[i] = x[i] + 0.5 * h * k1[i]
        mechanism_rates(xs, s + 0.5 * h * v, v, t_rudder, p, k2, hinges)
        for i in range(A.X_MECHANISM, n):
            xs[i] = x[i] + 0.5 * h * k2[i]
        mechanism_rates(xs, s + 0.5 * h * v, v, t_rudder, p, k3, hinges)
        for i in range(A.X_MECHANISM, n):
            xs[i] = x[i] + h * k3[i]
        mechanism_rates(xs, s + h * v, v, t_rudder, p, k4, hinges)
        for i in range(A.X_MECHANISM, n):
            x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    return mechanism_rates(x, s0 + v * duration, v, t_rudder, p, k1, hinges)


@njit(cache=True, error_model="numpy")
def advance(y, s0, v, duration, substeps, rudder_torque, q, hinges):
    """The linkage alone (its 16 states y, parameters q) over ``duration`` with the rod at
    s0 + v t and an external torque on the rudder shaft (N m, driving positive deflection);
    return the final axial force (see :func:`advance_rudder_side`)."""
    x = np.zeros(A.N_STATE)
    p = np.zeros(A.N_PARAMS)
    p[A.P_LOAD_MODEL] = A.LOAD_LINKAGE
    p[A.P_LINK : A.P_LINK_END] = q
    x[A.X_LINK : A.X_LINK_END] = y
    axial = advance_rudder_side(x, s0, v, duration, substeps, -rudder_torque, p, hinges)
    y[:] = x[A.X_LINK : A.X_LINK_END]
    return axial
