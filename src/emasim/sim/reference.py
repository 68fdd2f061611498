"""The same sampled-data system on scipy's stiff solvers, for validation only.

The controllers, sensors and current loop run exactly as in the engine (the same compiled
``control_tick``); between ticks the voltages are held and the plant's right-hand side,
bristle state included as an ordinary state, is integrated by ``solve_ivp`` (Radau or LSODA)
at a tight tolerance. It is slow (one solver call per tick) and exists so tests and benchmarks
can measure the engine's error. Users' runs never go through it.
"""

import time

import numpy as np
from scipy.integrate import solve_ivp

from ..jit import njit
from ..plant import actuator as A
from ..plant.elements import linkage as L
from ..plant.sensors import seed_noise
from ..signals import signal_value
from .engine import TRACE_COLUMNS, control_tick, record
from .result import Result

ATOL = A.PLANT.atol()  # absolute tolerance of every state, from the elements' declarations


@njit(cache=True, error_model="numpy")
def _rhs(t, x, u_d, u_q, model, t_end):
    """Plant derivative with the loads read inside [t_start, t_end): a load step on a tick
    boundary belongs to the next tick, as it does in the engine."""
    t_in = min(t, t_end - 1e-9 * (abs(t_end) + 1e-3))
    dx = np.zeros(A.N_STATE)  # the linkage rows stay 0 with the lumped rudder
    hinges = np.empty((L.N_HINGES, 2))
    t_load = signal_value(model.motor_load, t_in)
    f_load = signal_value(model.rod_load, t_in)
    r_load = signal_value(model.rudder_load, t_in)
    A.rhs(x, u_d, u_q, t_load, f_load, r_load, model.params, dx, hinges)
    return dx


@njit(cache=True, error_model="numpy")
def _tick(t, tick, model, data, position_law, speed_law, current_law):
    """The engine's control_tick, its three laws given one by one (as run_ticks takes them),
    and the row of the trace at a recording tick."""
    laws = (position_law, speed_law, current_law)
    u_d, u_q, speed_ref, iq_ref, position_ref = control_tick(t, tick, model, data, laws)
    if tick % model.timing.record_every == 0:
        r = tick // model.timing.record_every
        record(model, data, r, t, u_d, u_q, speed_ref, iq_ref, position_ref)
    return u_d, u_q


def simulate_reference(setup, method: str = "Radau", rtol: float = 1e-10) -> Result:
    """Run ``setup`` with ``solve_ivp(method, rtol)`` between ticks (see module docstring)."""
    ts = setup.sample_period_s
    run = setup.start()
    model, data = run.model, run.data
    if model.timing.delay_substeps:
        raise ValueError("the reference path runs without a computation delay")
    seed_noise(setup.seed)
    start = time.perf_counter()
    for k in range(setup.n_ticks):
        t = k * ts
        u_d, u_q = _tick(t, k, model, data, *run.laws)
        sol = solve_ivp(
            _rhs,
            (t, t + ts),
            data.x,
            method=method,
            rtol=rtol,
            atol=ATOL,
            args=(u_d, u_q, model, t + ts),
        )
        if not sol.success:
            raise RuntimeError(f"reference solver failed at t = {t:g} s: {sol.message}")
        data.x[:] = sol.y[:, -1]
    wall = time.perf_counter() - start
    columns = tuple(TRACE_COLUMNS[i] for i in model.trace_columns)
    return Result(columns, data.trace.T, meta={"simulation_wall_s": wall, "solver": method})
