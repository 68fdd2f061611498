"""A ``prange`` batch kernel: many runs of one plant structure in one compiled call.

Issue 12 asks whether such a kernel beats the study facility's two workers. It stacks the
compiled core's inputs of N runs (emasim.sim.core; the same structure, so the same shapes and
laws) along a first axis and runs :func:`emasim.sim.engine.run_ticks` on each row in a numba
``prange`` loop, on numba's own threads. ``bench_engine.batch_scaling`` times it against the
same runs on one and on two Python threads (the loop alone, the GIL released).

Every run writes its own rows of the stacked arrays and seeds its sensor noise at its first
tick on the thread that runs it, so the traces equal a plain run's: :func:`run_stacked`
checks that on the first run.
"""

import numba
import numpy as np
from numba import prange

from emasim.sim.core import PlantArrays, SensorArrays, SignalArrays, Timing, TraceArrays, Workspace
from emasim.sim.engine import EngineRun, run_ticks


@numba.njit(parallel=True, nogil=True, cache=True)
def _run_batch(
    n_ticks,
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
    work,
    trace,
):
    """run_ticks(0, n_ticks) on every row i of the stacked arrays (see :func:`stack`)."""
    params, limits = plant
    reference, motor_load, rod_load, rudder_load = signals
    table, sensor_state, rudder_to_rod = sensors
    (p_params, p_state), (s_params, s_state), (c_params, c_state) = slots
    ts, substeps, record_every, seeds, loop, delay, feedback = timing
    rk4, hinges, meas, ref, out = work
    data, columns, row, status = trace
    for i in prange(x.shape[0]):
        run_ticks(
            0,
            n_ticks,
            x[i],
            PlantArrays(params[i], limits[i]),
            SignalArrays(reference[i], motor_load[i], rod_load[i], rudder_load[i]),
            SensorArrays(table[i], sensor_state[i], rudder_to_rod[i]),
            drive[i],
            position_law,
            speed_law,
            current_law,
            (
                (p_params[i], p_state[i]),
                (s_params[i], s_state[i]),
                (c_params[i], c_state[i]),
            ),
            Timing(ts, substeps, record_every, seeds[i], loop, delay, feedback),
            Workspace(
                (rk4[i, 0], rk4[i, 1], rk4[i, 2], rk4[i, 3], rk4[i, 4]),
                hinges[i],
                meas[i],
                ref[i],
                out[i],
            ),
            TraceArrays(data[i], columns, row[i]),
            status[i],
        )


def _padded(arrays) -> np.ndarray:
    """1-D arrays of possibly different lengths stacked, zero-padded at the end (an encoded
    signal or table reads only its own length, emasim.signals)."""
    out = np.zeros((len(arrays), max(a.size for a in arrays)))
    for i, a in enumerate(arrays):
        out[i, : a.size] = a
    return out


def stack(setups: list) -> tuple:
    """The arguments of :func:`_run_batch` for ``setups`` (one structure, one duration)."""
    runs = [setup.start() for setup in setups]
    cores = [run.core for run in runs]
    first = cores[0]
    timing = first.timing
    laws = (first.position_law, first.speed_law, first.current_law)
    if any((c.position_law, c.speed_law, c.current_law) != laws for c in cores):
        raise ValueError("a batch kernel runs one structure: the same laws in every run")
    slots = tuple(
        (np.stack([c.slots[k][0] for c in cores]), np.stack([c.slots[k][1] for c in cores]))
        for k in range(3)
    )
    return (
        setups[0].n_ticks,
        np.stack([run.x for run in runs]),
        (np.stack([c.plant.params for c in cores]), np.stack([c.plant.limits for c in cores])),
        tuple(_padded([c.signals[k] for c in cores]) for k in range(4)),
        (
            np.stack([c.sensors.table for c in cores]),
            np.stack([c.sensors.state for c in cores]),
            _padded([c.sensors.rudder_to_rod for c in cores]),
        ),
        np.stack([c.drive for c in cores]),
        *laws,  # apart: numba types laws inside a tuple on a path that warns at every call
        slots,
        (
            timing.sample_period_s,
            timing.substeps,
            timing.record_every,
            np.array([c.timing.seed for c in cores], dtype=np.int64),
            timing.loop,
            timing.delay_substeps,
            timing.feedback,
        ),
        (
            np.stack([np.stack(c.workspace.rk4) for c in cores]),
            np.stack([c.workspace.hinges for c in cores]),
            np.stack([c.workspace.meas for c in cores]),
            np.stack([c.workspace.ref for c in cores]),
            np.stack([c.workspace.out for c in cores]),
        ),
        (
            np.stack([run.trace.data for run in runs]),
            runs[0].trace.columns,
            np.stack([run.trace.row for run in runs]),
            np.zeros((len(runs), 3), dtype=np.int64),
        ),
    )


def run_stacked(arguments: tuple, threads: int) -> None:
    """Run a :func:`stack`'s batch on ``threads`` numba threads."""
    numba.set_num_threads(threads)
    _run_batch(*arguments)


def check_against_plain(setups: list, arguments: tuple) -> None:
    """The first run of a finished batch equals the same run on the plain engine (bit for bit),
    and no run diverged."""
    trace, status = arguments[-1][0], arguments[-1][3]
    if status[:, 0].any():
        raise RuntimeError(f"a batch run stopped early: status {status[status[:, 0] != 0][0]}")
    plain = EngineRun(setups[0])
    plain.advance(setups[0].n_ticks)
    if not np.array_equal(trace[0], plain.run.trace.data, equal_nan=True):
        raise RuntimeError("the batch kernel's first run differs from the plain engine's")
