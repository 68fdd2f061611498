"""The compiled multirate loop: sampled-data control on integer ticks, RK4 sub-steps between.

At tick k (t = k Ts) the sensors are read, the position controller (if the reference is a
position) and the speed controller run, and the current loop computes the stator voltage. The
drive holds its limits on every command (emasim.plant.elements.ratings). After the computation delay
Td (a whole number of sub-steps, at most Ts) the voltage is applied and held (zero-order hold);
until then the previous one acts. The plant is integrated over Ts with n fixed RK4 sub-steps
of h = Ts/n. The LuGre bristle state is not advanced by RK4: in every stage it takes its exact
value for the stage's speed held (friction.bristle_update), and at the end of the sub-step its
exact value for the mean speed of the sub-step, which stays stable at any h although the bristle
eigenvalue reaches -5e5 1/s at speed.

Controllers arrive as first-class function values (:data:`emasim.control.slot.CONTROLLER_TYPE`):
the loop is compiled once, eagerly and cached on disk, whatever the controllers.

What the loop does at every tick (:func:`control_tick`, :func:`record`, :func:`check_state`)
is inlined into it (numba's ``inline="always"``). Called, each took the fields of the records
it reads by value at every tick: ``benchmarks/bench_paired.py --before 443a579`` measured
speed-step 0.0146 against 0.0119 s per simulated second, speed-sine 0.0159 against 0.0135,
position-step 0.0203 against 0.0176, the bench scenarios 0 to 3 % (medians of 3 interleaved
pairs; the traces bit for bit the same), for 3 s more of the first compile (35 against 32 s).
The right-hand side's helpers stay calls: the linkage's contacts inlined made the first
compile 8 minutes (482 s) for 5 % of the bench's time.
"""

import math
import time
from collections.abc import Callable

import numpy as np

from ..errors import SimulationDiverged
from ..interface import (
    LIMIT_CURRENT,
    LIMIT_SPEED,
    LIMIT_VOLTAGE,
    M_ANGLE,
    M_FORCE,
    M_IQ,
    M_POSITION,
    M_RUDDER,
    M_SPEED,
    O_RATE,
    O_UD,
    O_UQ,
    O_VALUE,
    R_ACCEL,
    R_RATE,
    R_VALUE,
)
from ..jit import njit
from ..numerics import clamp
from ..plant import actuator as A
from ..plant import integrator
from ..plant.elements.motor import limit_voltage
from ..plant.elements.ratings import folded_back, heat_update, speed_foldback
from ..plant.sensors import ST_HELD, measure, seed_noise
from ..signals import signal_derivatives, signal_value
from .borrowed import borrowed_record
from .core import (
    CURRENT_SLOT,
    D_CURRENT_LIMIT,
    D_FLAGS,
    D_FOLDED,
    D_HEAT,
    D_LAW,
    D_UD,
    D_UQ,
    FEEDBACK_MOTOR,
    FEEDBACK_RUDDER,
    LOOP_POSITION_CURRENT,
    LOOP_SPEED,
    POSITION_SLOT,
    RUN_SIG,
    SPEED_SLOT,
)
from .diagnosis import likely_cause
from .lawguard import law_failure, watching
from .result import Result, RunDescription
from .setup import Setup
from .spool import TraceSpool, chunk_rows
from .trace import (
    C_CURRENT_LIMIT,
    C_IQ_REF,
    C_LIMIT_FLAGS,
    C_MEASURED_ANGLE,
    C_MEASURED_FORCE,
    C_MEASURED_IQ,
    C_MEASURED_POSITION,
    C_MEASURED_ROD,
    C_MEASURED_RUDDER,
    C_MEASURED_SPEED,
    C_MOTOR_LOAD,
    C_OUTPUTS,
    C_POSITION_REF,
    C_ROD_LOAD,
    C_RUDDER_LOAD,
    C_SPEED_REF,
    C_STATE,
    C_UD,
    C_UQ,
    TRACE,
    TRACE_COLUMNS,
)

VOLTAGE_ROUND_OFF = 1e-9  # a voltage this close to Udc / sqrt(3) is at the inverter's limit
PROGRESS_CHUNKS = 20  # calls of run_ticks in a run with a progress bar (one without)

# status codes returned by run_ticks
OK = 0
NOT_FINITE = 1
OUT_OF_BOUNDS = 2
LAW_FAILED = 3  # a law's output was not finite (or it raised: emasim.sim.lawguard); index: slot


@njit(cache=True, inline="always", error_model="numpy")
def current_bounds(p, drive, speed):
    """The drive's current command bounds (lower, upper) in A at measured speed ``speed``, and
    the limit in force: max_current_A, or with the ratings the continuous current while the
    I^2 t protection holds it (emasim.plant.elements.ratings), folded back near the rated speed."""
    i_lim = p[A.P_IMAX]
    if p[A.P_RATINGS] == 0.0:
        return -i_lim, i_lim, i_lim
    if drive[D_FOLDED] != 0.0:
        i_lim = p[A.P_I_CONT]
    up, down = speed_foldback(speed, p[A.P_W_RATED])
    return -i_lim * down, i_lim * up, i_lim


@njit(cache=True, inline="always", error_model="numpy")
def _law_failed(drive, slot):
    """Mark law ``slot`` as failed (D_LAW) and end the tick: no command is applied."""
    drive[D_LAW] = slot + 1.0
    return np.nan, np.nan, np.nan, np.nan, np.nan


@njit(cache=True, inline="always", error_model="numpy")
def fed_back_position(meas, p, feedback, rudder_to_rod):
    """The position the loop closes on (m, FEEDBACK_*): the rod sensor's reading, the rod
    position the rigid kinematics give for the rudder encoder's angle, or the motor encoder's
    angle as the nut's travel K theta_m."""
    if feedback == FEEDBACK_RUDDER:
        return signal_value(rudder_to_rod, meas[M_RUDDER])
    if feedback == FEEDBACK_MOTOR:
        return p[A.P_K] * meas[M_ANGLE]
    return meas[M_POSITION]


@njit(cache=True, inline="always", error_model="numpy")
def control_tick(t, tick, model, data, laws):
    """One control sample: read the sensors, run the slots that close (position, speed, then
    current), and return (ud, uq, speed_ref, iq_ref, position_ref) applied from t + Td on.

    The drive's limits hold whatever a slot commands, library or user-written: a speed command
    within +-max_speed, a current command within the bounds of :func:`current_bounds`, the
    voltage within the inverter's Udc/sqrt(3); ``drive`` receives the limit in force and the
    limits the commands sat at (cut by the drive, or already at the limit: the library's laws
    limit their own outputs), and its I^2 t heat advances on the measured current. ``model``
    and ``data`` are the run's records (emasim.sim.core), ``laws`` the slots' compiled
    functions. A law whose output the loop uses is not finite ends the tick at once with
    drive[D_LAW] = 1 + its slot (``data.out`` keeps what it wrote).
    """
    meas, ref, out, drive = data.meas, data.ref, data.out, data.drive
    p = model.params
    timing = model.timing
    ts = timing.sample_period_s
    params, states = model.slot_params, data.slot_states
    measure(data.x, p, model.sensor_table, data.sensor_state, meas, tick)
    meas[M_POSITION] = fed_back_position(meas, p, timing.feedback, model.rudder_to_rod)
    flags = 0
    r, dr, ddr = signal_derivatives(model.reference, t)
    position_ref = np.nan
    if timing.loop != LOOP_SPEED:
        position_ref = r
        ref[R_VALUE], ref[R_RATE], ref[R_ACCEL] = r, dr, ddr
        laws[POSITION_SLOT](states[POSITION_SLOT], params[POSITION_SLOT], meas, ref, ts, out)
        r, dr = out[O_VALUE], out[O_RATE]
        if not (np.isfinite(r) and np.isfinite(dr)):
            return _law_failed(drive, POSITION_SLOT)
    i_low, i_high, i_lim = current_bounds(p, drive, meas[M_SPEED])
    if timing.loop == LOOP_POSITION_CURRENT:
        command = r
        r = np.nan  # no speed reference in this structure
    else:
        w_max = p[A.P_WMAX]
        if abs(r) >= w_max:
            flags |= LIMIT_SPEED
        r = clamp(r, -w_max, w_max)
        ref[R_VALUE], ref[R_RATE], ref[R_ACCEL] = r, dr, 0.0
        laws[SPEED_SLOT](states[SPEED_SLOT], params[SPEED_SLOT], meas, ref, ts, out)
        command = out[O_VALUE]
        if not np.isfinite(command):
            return _law_failed(drive, SPEED_SLOT)
    iq_ref = clamp(command, i_low, i_high)
    if iq_ref >= i_high or iq_ref <= i_low:  # at a bound: the current's, or the fold-back's
        flags |= LIMIT_CURRENT if abs(iq_ref) >= i_lim else LIMIT_SPEED
    ref[R_VALUE], ref[R_RATE], ref[R_ACCEL] = iq_ref, 0.0, 0.0
    laws[CURRENT_SLOT](states[CURRENT_SLOT], params[CURRENT_SLOT], meas, ref, ts, out)
    if not (np.isfinite(out[O_UD]) and np.isfinite(out[O_UQ])):
        return _law_failed(drive, CURRENT_SLOT)
    u_d, u_q = limit_voltage(out[O_UD], out[O_UQ], p[A.P_UDC])
    if math.hypot(u_d, u_q) >= (1.0 - VOLTAGE_ROUND_OFF) * p[A.P_UDC] / math.sqrt(3.0):
        flags |= LIMIT_VOLTAGE
    if p[A.P_RATINGS] != 0.0:
        capacity = p[A.P_HEAT_CAPACITY]
        drive[D_HEAT] = heat_update(drive[D_HEAT], meas[M_IQ], p[A.P_I_CONT], capacity, ts)
        drive[D_FOLDED] = folded_back(drive[D_FOLDED] != 0.0, drive[D_HEAT], capacity)
    drive[D_CURRENT_LIMIT] = i_lim
    drive[D_FLAGS] = flags
    return u_d, u_q, r, iq_ref, position_ref


@njit(cache=True, inline="always", error_model="numpy")
def plant_step(t, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h, work):
    """Advance x by one RK4 sub-step h of every element's right-hand side (the presence of
    each tested in it) with the voltages held (emasim.plant.integrator.sub_step); ``work`` is
    a :class:`emasim.sim.core.Workspace` (its RK4 stages and hinge table are overwritten).
    The loop runs the same scheme (emasim.plant.integrator.tick)."""
    k1, k2, k3, k4, xs = work.rk4
    n = A.active_states(p)
    integrator.sub_step(A.rhs, n, t, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h,
             k1, k2, k3, k4, xs, work.hinges)  # fmt: skip


@njit(cache=True, inline="always", error_model="numpy")
def check_state(x, p, limits, status, tick):
    """Flag the first state this loop integrates (actuator.active_states) that is NaN/inf or
    beyond its limit; True when all are fine."""
    for i in range(A.active_states(p)):
        if not np.isfinite(x[i]):
            status[0], status[1], status[2] = NOT_FINITE, tick, i
            return False
        if abs(x[i]) > limits[i]:
            status[0], status[1], status[2] = OUT_OF_BOUNDS, tick, i
            return False
    return True


@njit(cache=True, inline="always", error_model="numpy")
def record(model, data, r, t, u_d, u_q, speed_ref, iq_ref, position_ref):
    """Store row r of the traces (at r modulo the trace's rows: emasim.sim.spool empties a
    short trace as it fills): the kept columns (Model.trace_columns) of the TRACE row,
    assembled in Data.trace_row."""
    row, x, p, meas, drive = data.trace_row, data.x, model.params, data.meas, data.drive
    row[0] = t
    for i in range(A.N_STATE):
        row[C_STATE + i] = x[i]
    row[C_SPEED_REF] = speed_ref
    row[C_IQ_REF] = iq_ref
    row[C_POSITION_REF] = position_ref
    row[C_UD] = u_d
    row[C_UQ] = u_q
    row[C_CURRENT_LIMIT] = drive[D_CURRENT_LIMIT]
    row[C_LIMIT_FLAGS] = drive[D_FLAGS]
    A.plant_outputs(x, p, row[C_OUTPUTS : C_OUTPUTS + A.N_OUTPUTS])
    row[C_MOTOR_LOAD] = signal_value(model.motor_load, t)
    row[C_ROD_LOAD] = signal_value(model.rod_load, t)
    row[C_RUDDER_LOAD] = signal_value(model.rudder_load, t)
    row[C_MEASURED_SPEED] = meas[M_SPEED]
    row[C_MEASURED_POSITION] = meas[M_POSITION]
    row[C_MEASURED_RUDDER] = meas[M_RUDDER]
    row[C_MEASURED_ANGLE] = meas[M_ANGLE]
    row[C_MEASURED_ROD] = data.sensor_state[M_POSITION, ST_HELD]  # meas: the loop's reading
    row[C_MEASURED_IQ] = meas[M_IQ]
    row[C_MEASURED_FORCE] = meas[M_FORCE]
    columns, trace = model.trace_columns, data.trace
    r = r % trace.shape[1]
    for j in range(columns.size):
        trace[j, r] = row[columns[j]]


@njit(RUN_SIG, cache=True, error_model="numpy", nogil=True)
def run_ticks(k0, k1, model, data, position_law, speed_law, current_law):
    """Run ticks k0 .. k1-1 in place on ``data`` (the plant state, the sensors', the drive's and
    the slots' states, the trace), reading ``model`` (emasim.sim.core), every array of both
    borrowed (emasim.sim.borrowed). The plant is integrated over each tick with the drive's
    right-hand side where the plant is the drive alone (emasim.plant.actuator.DRIVE), every
    element's otherwise.

    Row k // record_every of the trace is recorded at every ``record_every``-th tick (modulo
    the trace's rows).
    The sensor noise generator is seeded at k0 == 0. On a NaN/inf or a state beyond the
    plant's limits the run stops and ``data.status`` holds (code, tick, state index); on a
    law's non-finite output, (LAW_FAILED, tick, slot).
    """
    if k0 == 0:
        seed_noise(model.timing.seed)
    model, data = borrowed_record(model), borrowed_record(data)
    timing = model.timing
    ts = timing.sample_period_s
    h = ts / timing.substeps
    x, p, drive, status = data.x, model.params, data.drive, data.status
    (s1, s2, s3, s4, xs), hinges = data.work.rk4, data.work.hinges  # the RK4 stages
    drive_only = A.DRIVE.applies(p)
    motor_load, rod_load, rudder_load = model.motor_load, model.rod_load, model.rudder_load
    laws = (position_law, speed_law, current_law)
    delay = timing.delay_substeps
    for k in range(k0, k1):
        t = k * ts
        u_d, u_q, speed_ref, iq_ref, position_ref = control_tick(t, k, model, data, laws)
        if drive[D_LAW] != 0.0:
            status[0], status[1], status[2] = LAW_FAILED, k, int(drive[D_LAW]) - 1
            return
        if k % timing.record_every == 0:
            r = k // timing.record_every
            record(model, data, r, t, u_d, u_q, speed_ref, iq_ref, position_ref)
        v_d, v_q, n = drive[D_UD], drive[D_UQ], timing.substeps  # v: during the delay
        if drive_only:
            integrator.tick(A.DRIVE.rhs, A.DRIVE.active_states(p), t, x, u_d, u_q, v_d, v_q,
                            delay, n, h, p, motor_load, rod_load, rudder_load, s1, s2, s3, s4,
                            xs, hinges)  # fmt: skip
        else:
            integrator.tick(A.rhs, A.active_states(p), t, x, u_d, u_q, v_d, v_q, delay, n, h,
                            p, motor_load, rod_load, rudder_load, s1, s2, s3, s4, xs,
                            hinges)  # fmt: skip
        drive[D_UD], drive[D_UQ] = u_d, u_q
        if not check_state(x, p, model.limits, status, k + 1):
            return


def _divergence_message(setup, status) -> str:
    code, tick, index = (int(v) for v in status)
    name = A.STATE_NAMES[index]
    what = (
        "became NaN or infinite"
        if code == NOT_FINITE
        else (f"left its bound of +-{setup.limits[index]:g}")
    )
    return (
        f"simulation diverged at t = {tick * setup.sample_period_s:.6g} s: state '{name}' {what}. "
        f"Likely cause: {likely_cause(setup, index)}."
    )


def load_compiled() -> float:
    """Load the compiled loop (numba's disk cache) or, on an empty cache, compile it; the
    seconds it took, about 0 once loaded in this process. Runs call it before their timer
    starts, so a run's ``simulation_wall_s`` never counts the compile."""
    start = time.perf_counter()
    run_ticks.dispatcher  # noqa: B018 - made on first use: numba compiles for RUN_SIG or loads
    return time.perf_counter() - start


class EngineRun:
    """A run of a Setup on the compiled loop, advanced tick range by tick range.

    ``advance(k_end)`` runs ticks up to k_end (exclusive) and raises
    :class:`emasim.errors.SimulationDiverged` with the time and the state's name on a blow-up;
    ``x`` is the plant state in between (a co-simulation master reads and feeds it).
    A trace larger than emasim.sim.spool.SPOOL_BYTES is recorded one row group at a time and
    appended to a :class:`~emasim.sim.spool.TraceSpool` as each fills: memory holds one row
    group of it, whatever the duration (``stream=False`` keeps it whole in memory, for a
    caller that reads it while the run goes on).
    """

    def __init__(self, setup: Setup, keep_elements: tuple[str, ...] = (), stream: bool = True):
        self.setup = setup
        self.keep_elements = keep_elements
        self.compile_s = load_compiled()
        columns = tuple(setup.kept_columns(keep_elements))
        group = chunk_rows(len(columns))
        streamed = stream and setup.recorded_rows > group
        self.spool = TraceSpool(columns) if streamed else None
        self.run = setup.start(keep_elements, rows=group if streamed else None)
        self.tick = 0
        self.wall_s = 0.0

    @property
    def x(self) -> np.ndarray:
        """The plant state, advanced in place."""
        return self.run.data.x

    @property
    def _group_ticks(self) -> int:
        """The ticks that fill the trace (a spooled one's row group)."""
        return self.run.data.trace.shape[1] * self.setup.record_every

    def advance(self, k_end: int) -> None:
        while self.tick < k_end:  # a spooled trace: up to each full row group, then empty it
            full = self._group_ticks
            stop = k_end if self.spool is None else min(k_end, (self.tick // full + 1) * full)
            self._ticks(stop)
            if self.spool is not None and self.tick % full == 0:
                self.spool.append(self.run.data.trace)

    def _ticks(self, k_end: int) -> None:
        model, data, laws = self.run.model, self.run.data, self.run.laws
        status = data.status
        start = time.perf_counter()
        with watching(data.out) as raised:
            run_ticks(self.tick, k_end, model, data, *laws)
        self.wall_s += time.perf_counter() - start
        if status[0] == LAW_FAILED:
            t = int(status[1]) * self.setup.sample_period_s
            raise law_failure(self.setup, int(status[2]), t, data.out, raised)
        if status[0] != OK:
            raise SimulationDiverged(_divergence_message(self.setup, status))
        self.tick = k_end

    def result(self) -> Result:
        """The traces so far: the kept columns (Setup.kept_columns), without a copy; a spooled
        trace, its rows recorded so far, as the Parquet file they went into (read by column).
        The run ends here for a spooled trace: its file is closed."""
        setup = self.setup
        columns = tuple(TRACE_COLUMNS[i] for i in self.run.model.trace_columns)
        traces = self.run.data.trace
        if self.spool is not None:  # the rows recorded since the last full row group
            flushed = self.tick // self._group_ticks * traces.shape[1]
            recorded = -(-self.tick // setup.record_every) - flushed
            self.spool.append(traces[:, :recorded])
            traces = self.spool.finish()
        units = TRACE.units()
        return Result(
            columns,
            traces if self.spool is not None else traces.T,
            meta={"simulation_wall_s": self.wall_s, "compile_s": self.compile_s},
            description=RunDescription(
                elements=A.PLANT.present_elements(setup.plant, keep=self.keep_elements),
                loops=setup.loop_laws(),
                outer_loop="speed" if setup.position is None else "position",
                sensors=setup.sensor_description(),
                units={name: units[name] for name in columns},
            ),
        )


def simulate(setup: Setup, progress: Callable[[float], None] | None = None) -> Result:
    """Run ``setup`` (a :class:`emasim.sim.setup.Setup`) on the compiled engine.

    progress, if given, is called with the fraction done after each chunk of ticks. Returns a
    :class:`emasim.sim.result.Result`; raises :class:`emasim.errors.SimulationDiverged` with the
    time and the state's name when the run blows up.
    """
    n = setup.n_ticks
    engine = EngineRun(setup)
    chunk = n if progress is None else max(1, n // PROGRESS_CHUNKS)
    for k0 in range(0, n, chunk):
        engine.advance(min(n, k0 + chunk))
        if progress is not None:
            progress(engine.tick / n)
    return engine.result()
