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
from ..plant import linkage as L
from ..plant.sensors import seed_noise
from ..signals import signal_value
from .engine import TRACE_COLUMNS, control_tick, record
from .result import Result

ATOL = A.PLANT.atol()  # absolute tolerance of every state, from the elements' declarations


@njit(cache=True, error_model="numpy")
def _rhs(t, x, u_d, u_q, p, signals, t_end):
    """Plant derivative with the loads read inside [t_start, t_end): a load step on a tick
    boundary belongs to the next tick, as it does in the engine."""
    t_in = min(t, t_end - 1e-9 * (abs(t_end) + 1e-3))
    dx = np.zeros(A.N_STATE)  # the linkage rows stay 0 with the lumped rudder
    hinges = np.empty((L.N_HINGES, 2))
    t_load = signal_value(signals.motor_load, t_in)
    f_load = signal_value(signals.rod_load, t_in)
    r_load = signal_value(signals.rudder_load, t_in)
    A.rhs(x, u_d, u_q, t_load, f_load, r_load, p, dx, hinges)
    return dx


@njit(cache=True, error_model="numpy")
def _tick(
    t,
    tick,
    x,
    plant,
    signals,
    sensors,
    drive,
    position_law,
    speed_law,
    current_law,
    slots,
    timing,
    scratch,
):
    """The engine's control_tick, its three laws given one by one (as run_ticks takes them)."""
    laws = (position_law, speed_law, current_law)
    return control_tick(t, tick, x, plant, signals, sensors, drive, laws, slots, timing, scratch)


def simulate_reference(setup, method: str = "Radau", rtol: float = 1e-10) -> Result:
    """Run ``setup`` with ``solve_ivp(method, rtol)`` between ticks (see module docstring)."""
    ts = setup.sample_period_s
    run = setup.start()
    x = run.x
    plant, signals, sensors, drive, *laws, slots, timing, workspace = run.core
    if timing.delay_substeps:
        raise ValueError("the reference path runs without a computation delay")
    scratch = (workspace.meas, workspace.ref, workspace.out)
    seed_noise(setup.seed)
    start = time.perf_counter()
    for k in range(setup.n_ticks):
        t = k * ts
        u_d, u_q, speed_ref, iq_ref, position_ref = _tick(
            t, k, x, plant, signals, sensors, drive, *laws, slots, timing, scratch
        )
        if k % setup.record_every == 0:
            record(
                run.trace,
                k // setup.record_every,
                t,
                x,
                plant.params,
                signals,
                u_d,
                u_q,
                speed_ref,
                iq_ref,
                position_ref,
                scratch[0],
                drive,
            )
        sol = solve_ivp(
            _rhs,
            (t, t + ts),
            x,
            method=method,
            rtol=rtol,
            atol=ATOL,
            args=(u_d, u_q, plant.params, signals, t + ts),
        )
        if not sol.success:
            raise RuntimeError(f"reference solver failed at t = {t:g} s: {sol.message}")
        x = sol.y[:, -1].copy()
    wall = time.perf_counter() - start
    columns = tuple(TRACE_COLUMNS[i] for i in run.trace.columns)
    return Result(columns, run.trace.data.T, meta={"simulation_wall_s": wall, "solver": method})
