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

from emasim.sim.core import Data, Model, Timing, Workspace
from emasim.sim.engine import EngineRun, run_ticks


@numba.njit(parallel=True, nogil=True, cache=True)
def _run_batch(n_ticks, model, data, position_law, speed_law, current_law):
    """run_ticks(0, n_ticks) on every row i of the stacked records (see :func:`stack`): each
    array field of ``model`` and ``data`` carries the runs along its first axis, and the
    timing's seed is one per run."""
    # every field unpacked before the parallel loop: numba's parfors take arrays, not records
    params, limits, reference, motor_load, rod_load, rudder_load = model[:6]
    table, rudder_to_rod, (p_params, s_params, c_params), columns = model[6:10]
    ts, substeps, record_every, seeds, loop, delay, feedback = model.timing
    x, sensor_state, drive, (p_state, s_state, c_state) = data[:4]
    (k1, k2, k3, k4, stage), hinges = data.work
    meas, ref, out, trace, trace_row, status = data[5:]
    for i in prange(x.shape[0]):
        row_model = Model(
            params[i],
            limits[i],
            reference[i],
            motor_load[i],
            rod_load[i],
            rudder_load[i],
            table[i],
            rudder_to_rod[i],
            (p_params[i], s_params[i], c_params[i]),
            columns,
            Timing(ts, substeps, record_every, seeds[i], loop, delay, feedback),
        )
        row_data = Data(
            x[i],
            sensor_state[i],
            drive[i],
            (p_state[i], s_state[i], c_state[i]),
            Workspace((k1[i], k2[i], k3[i], k4[i], stage[i]), hinges[i]),
            meas[i],
            ref[i],
            out[i],
            trace[i],
            trace_row[i],
            status[i],
        )
        run_ticks(0, n_ticks, row_model, row_data, position_law, speed_law, current_law)


def _padded(arrays) -> np.ndarray:
    """1-D arrays of possibly different lengths stacked, zero-padded at the end (an encoded
    signal or table reads only its own length, emasim.signals)."""
    out = np.zeros((len(arrays), max(a.size for a in arrays)), dtype=arrays[0].dtype)
    for i, a in enumerate(arrays):
        out[i, : a.size] = a
    return out


def _stacked(values: list):
    """One field of every run stacked along a first axis: arrays (1-D ones zero-padded to one
    length), tuples field by field."""
    first = values[0]
    if isinstance(first, tuple):
        fields = [_stacked([v[k] for v in values]) for k in range(len(first))]
        return type(first)(*fields) if hasattr(first, "_fields") else tuple(fields)
    if first.ndim == 1:
        return _padded(values)
    return np.stack(values)


def stack(setups: list) -> tuple:
    """The arguments of :func:`_run_batch` for ``setups`` (one structure, one duration)."""
    runs = [setup.start() for setup in setups]
    laws = runs[0].laws
    if any(run.laws != laws for run in runs):
        raise ValueError("a batch kernel runs one structure: the same laws in every run")
    shared = {  # one for all runs: the kept columns, and the timing but for its seeds
        "trace_columns": runs[0].model.trace_columns,
        "timing": runs[0].model.timing._replace(
            seed=np.array([run.model.timing.seed for run in runs], dtype=np.int64)
        ),
    }
    model = Model(
        *(
            shared[f] if f in shared else _stacked([getattr(run.model, f) for run in runs])
            for f in Model._fields
        )
    )
    data = Data(*(_stacked([getattr(run.data, f) for run in runs]) for f in Data._fields))
    return (setups[0].n_ticks, model, data, *laws)


def run_stacked(arguments: tuple, threads: int) -> None:
    """Run a :func:`stack`'s batch on ``threads`` numba threads."""
    numba.set_num_threads(threads)
    _run_batch(*arguments)


def check_against_plain(setups: list, arguments: tuple) -> None:
    """The first run of a finished batch equals the same run on the plain engine (bit for bit),
    and no run diverged."""
    data = arguments[2]
    trace, status = data.trace, data.status
    if status[:, 0].any():
        raise RuntimeError(f"a batch run stopped early: status {status[status[:, 0] != 0][0]}")
    plain = EngineRun(setups[0])
    plain.advance(setups[0].n_ticks)
    if not np.array_equal(trace[0], plain.run.data.trace, equal_nan=True):
        raise RuntimeError("the batch kernel's first run differs from the plain engine's")
