"""The same sampled-data system on scipy's stiff solvers, for validation only.

The controllers, sensors and current loop run exactly as in the engine (the same compiled
``control_tick``); between ticks the voltages are held and the plant's right-hand side,
bristle state included as an ordinary state, is integrated by ``solve_ivp`` (Radau or LSODA)
at a tight tolerance. It is slow (one solver call per tick) and exists so tests and benchmarks
can measure the engine's error. Users' runs never go through it.
"""

import time

import numba as nb
import numpy as np
from scipy.integrate import solve_ivp

from ..interface import N_MEAS, N_OUT, N_REF
from ..plant import actuator as A
from ..plant.sensors import seed_noise
from ..signals import signal_value
from .engine import TRACE_COLUMNS, control_tick, record
from .result import Result

ATOL = A.PLANT.atol()  # absolute tolerance of every state, from the elements' declarations


@nb.njit(cache=True, error_model="numpy")
def _rhs(t, x, u_d, u_q, p, motor_load, rod_load, rudder_load, t_end):
    """Plant derivative with the loads read inside [t_start, t_end): a load step on a tick
    boundary belongs to the next tick, as it does in the engine."""
    t_in = min(t, t_end - 1e-9 * (abs(t_end) + 1e-3))
    dx = np.zeros(A.N_STATE)  # the linkage rows stay 0 with the lumped rudder
    t_load = signal_value(motor_load, t_in)
    f_load = signal_value(rod_load, t_in)
    r_load = signal_value(rudder_load, t_in)
    A.rhs(x, u_d, u_q, t_load, f_load, r_load, p, dx)
    return dx


def simulate_reference(setup, method: str = "Radau", rtol: float = 1e-10) -> Result:
    """Run ``setup`` with ``solve_ivp(method, rtol)`` between ticks (see module docstring)."""
    ts = setup.sample_period_s
    run = setup.start()
    x = run.x
    meas, ref, out = np.empty(N_MEAS), np.empty(N_REF), np.empty(N_OUT)
    seed_noise(setup.seed)
    start = time.perf_counter()
    for k in range(setup.n_ticks):
        t = k * ts
        u_d, u_q, speed_ref, iq_ref, position_ref = control_tick(
            t,
            x,
            setup.plant,
            setup.sensors,
            run.gap,
            run.loop,
            setup.reference,
            run.position.function,
            run.position.params,
            run.position_state,
            setup.speed.function,
            setup.speed.params,
            run.speed_state,
            setup.current_params,
            run.current_state,
            ts,
            meas,
            ref,
            out,
        )
        if k % setup.record_every == 0:
            record(
                run.trace[k // setup.record_every],
                t,
                x,
                setup.plant,
                setup.motor_load,
                setup.rod_load,
                setup.rudder_load,
                u_d,
                u_q,
                speed_ref,
                iq_ref,
                position_ref,
                meas,
            )
        sol = solve_ivp(
            _rhs,
            (t, t + ts),
            x,
            method=method,
            rtol=rtol,
            atol=ATOL,
            args=(
                u_d,
                u_q,
                setup.plant,
                setup.motor_load,
                setup.rod_load,
                setup.rudder_load,
                t + ts,
            ),
        )
        if not sol.success:
            raise RuntimeError(f"reference solver failed at t = {t:g} s: {sol.message}")
        x = sol.y[:, -1].copy()
    wall = time.perf_counter() - start
    return Result(TRACE_COLUMNS, run.trace, meta={"simulation_wall_s": wall, "solver": method})
