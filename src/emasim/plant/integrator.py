"""The plant's integration over one control tick: RK4 sub-steps of a right-hand side.

:func:`sub_step` and :func:`tick` take the right-hand side as their first argument and are
inlined where they are called, with it: the compiled loop (emasim.sim.engine.run_ticks) runs
them with the drive's right-hand side (emasim.plant.actuator.DRIVE) or every element's, the
FMU and the tests with every element's (emasim.sim.engine.plant_step).
"""

from ..jit import njit
from ..signals import signal_value
from . import actuator as A


@njit(cache=True, inline="always", error_model="numpy")
def _stage(xs, x, k, dt, z, n):
    """xs = x + dt k for the first n states but the bristle, which is set to z."""
    for i in range(n):
        xs[i] = x[i] + dt * k[i]
    xs[A.X_Z] = z


@njit(cache=True, inline="always", error_model="numpy")
def sub_step(rhs, n, t, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h, k1, k2, k3, k4,
             xs, hinges):  # fmt: skip
    """Advance the first n states of x by one RK4 sub-step h of ``rhs`` with the voltages
    held; the stages k1, k2, k3, k4, xs and ``hinges`` are overwritten. Everything comes as
    arrays and scalars, never as a record: a record passed into the function called at
    every sub-step cost 15 % of the lumped loop (0.87 against 0.75 us per sub-step,
    interleaved in one process).

    The bristle state is split off: in the RK4 stages it takes its exact value for the speed
    at the start of the sub-step held, and at the end of the sub-step its exact value for the
    mean speed over the sub-step. The loads are held at their value at the sub-step's
    midpoint: exact for steps that fall on sub-step boundaries (a step evaluated at a stage on
    its edge would leak into the step before it, a first-order error) and second-order
    accurate for smooth loads.
    """
    z0 = x[A.X_Z]
    w0 = x[A.X_WM]
    z_half, z_full = A.bristle_half_and_full_step(z0, w0, h, p)
    t_load = signal_value(motor_load, t + 0.5 * h)
    f_load = signal_value(rod_load, t + 0.5 * h)
    r_load = signal_value(rudder_load, t + 0.5 * h)
    rhs(x, u_d, u_q, t_load, f_load, r_load, p, k1, hinges)
    _stage(xs, x, k1, 0.5 * h, z_half, n)
    rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k2, hinges)
    _stage(xs, x, k2, 0.5 * h, z_half, n)
    rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k3, hinges)
    _stage(xs, x, k3, h, z_full, n)
    rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k4, hinges)
    for i in range(n):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    x[A.X_Z] = A.bristle_step(z0, 0.5 * (w0 + x[A.X_WM]), h, p)


@njit(cache=True, inline="always", error_model="numpy")
def tick(rhs, n, t, x, u_d, u_q, v_d, v_q, delay, substeps, h, p, motor_load, rod_load,
         rudder_load, k1, k2, k3, k4, xs, hinges):  # fmt: skip
    """One tick from t: ``substeps`` sub-steps of h, the first ``delay`` of them with the
    previous voltages (v_d, v_q) still applied (the computation delay), the rest with the new
    ones (u_d, u_q); the three encoded loads (motor, rod, rudder); the RK4 stages k1..k4, xs.
    The arrays come one by one, never in a tuple: a tuple made here would count references
    to its arrays at every call."""
    for j in range(substeps):
        a, b = (v_d, v_q) if j < delay else (u_d, u_q)
        sub_step(rhs, n, t + j * h, x, a, b, p, motor_load, rod_load, rudder_load, h,
                 k1, k2, k3, k4, xs, hinges)  # fmt: skip
