"""The compiled multirate loop: sampled-data control on integer ticks, RK4 sub-steps between.

At tick k (t = k Ts) the sensors are read, the position controller (if the reference is a
position) and the speed controller run, and the current loop computes the stator voltage, held
over the tick (zero-order hold). The plant is then integrated over Ts with n fixed RK4 sub-steps
of h = Ts/n. The LuGre bristle state is not advanced by RK4: in every stage it takes its exact
value for the stage's speed held (friction.bristle_update), and at the end of the sub-step its
exact value for the mean speed of the sub-step, which stays stable at any h although the bristle
eigenvalue reaches -5e5 1/s at speed.

Controllers arrive as first-class function values (:data:`emasim.control.slot.CONTROLLER_TYPE`):
the loop is compiled once, eagerly and cached on disk, whatever the controllers.
"""

import time

import numba as nb
import numpy as np
from numba import types

from ..control.current import current_control
from ..control.slot import CONTROLLER_TYPE
from ..errors import SimulationDiverged
from ..interface import M_ID, M_IQ, M_POSITION, M_SPEED, N_MEAS, N_OUT, N_REF, O_RATE, O_VALUE
from ..plant import actuator as A
from ..plant import linkage as L
from ..plant.element import Layout, Quantity
from ..plant.motor import limit_voltage
from ..plant.sensors import measure, seed_noise
from ..signals import signal_derivatives, signal_value
from .diagnosis import likely_cause
from .result import Result

LOOP_SPEED = 0  # reference is a motor speed: speed controller -> current loop
LOOP_POSITION = 1  # reference is a rod position: position -> speed -> current (cascade)
LOOP_POSITION_CURRENT = 2  # position controller commands the current loop directly

# trace columns: time, the plant's states, the loops' signals, the elements' outputs, the
# loads, the measurements the controllers saw; each with its unit (TRACE.units())
CONTROL_COLUMNS = (
    Quantity("speed_ref_rad_s", "rad/s", "speed command (NaN when the position loop commands iq)"),
    Quantity("iq_ref_A", "A", "q-axis current command"),
    Quantity("position_ref_m", "m", "rod position reference (NaN in a speed-loop run)"),
    Quantity("ud_V", "V", "d-axis stator voltage, limited by the inverter"),
    Quantity("uq_V", "V", "q-axis stator voltage, limited by the inverter"),
)
LOAD_COLUMNS = (
    Quantity("load_torque_Nm", "N m", "external load torque on the motor shaft"),
    Quantity("rod_load_N", "N", "external force on the rod, positive opposing extension"),
    Quantity("rudder_load_Nm", "N m", "load torque on the rudder shaft (linkage)"),
)
MEASURED_COLUMNS = (
    Quantity("measured_speed_rad_s", "rad/s", "speed sensor reading"),
    Quantity("measured_position_m", "m", "rod position sensor reading"),
)
TRACE = Layout(
    (
        Quantity("t_s", "s", "time"),
        *A.PLANT.states.quantities,
        *CONTROL_COLUMNS,
        *A.PLANT.outputs.quantities,
        *LOAD_COLUMNS,
        *MEASURED_COLUMNS,
    )
)
TRACE_COLUMNS = TRACE.names
N_COLUMNS = len(TRACE)
C_STATE = TRACE.index(A.STATE_NAMES[0])
C_SPEED_REF = TRACE.index("speed_ref_rad_s")
C_IQ_REF = TRACE.index("iq_ref_A")
C_POSITION_REF = TRACE.index("position_ref_m")
C_UD = TRACE.index("ud_V")
C_UQ = TRACE.index("uq_V")
C_OUTPUTS = TRACE.index(A.PLANT.outputs.names[0])
C_MOTOR_LOAD = TRACE.index("load_torque_Nm")
C_ROD_LOAD = TRACE.index("rod_load_N")
C_RUDDER_LOAD = TRACE.index("rudder_load_Nm")
C_MEASURED_SPEED = TRACE.index("measured_speed_rad_s")
C_MEASURED_POSITION = TRACE.index("measured_position_m")
LINKAGE_TRACE_COLUMNS = frozenset((*L.LINK_STATE_NAMES, *(q.name for q in L.LINKAGE.outputs)))

# status codes returned by run_ticks
OK = 0
NOT_FINITE = 1
OUT_OF_BOUNDS = 2


@nb.njit(cache=True, error_model="numpy")
def control_tick(
    t,
    x,
    p,
    sensor_table,
    gap_state,
    loop,
    ref_sig,
    pos_fn,
    pos_p,
    pos_s,
    speed_fn,
    speed_p,
    speed_s,
    cur_p,
    cur_s,
    ts,
    meas,
    ref,
    out,
):
    """One control sample: returns (ud, uq, speed_ref, iq_ref, position_ref) applied from t on."""
    measure(x, p, sensor_table, gap_state, meas)
    r, dr, ddr = signal_derivatives(ref_sig, t)
    position_ref = np.nan
    if loop != LOOP_SPEED:
        position_ref = r
        ref[0], ref[1], ref[2] = r, dr, ddr
        pos_fn(pos_s, pos_p, meas, ref, ts, out)
        r, dr = out[O_VALUE], out[O_RATE]
    if loop == LOOP_POSITION_CURRENT:
        iq_ref = r
        r = np.nan  # no speed reference in this structure
    else:
        ref[0], ref[1], ref[2] = r, dr, 0.0
        speed_fn(speed_s, speed_p, meas, ref, ts, out)
        iq_ref = out[O_VALUE]
    u_d, u_q = current_control(cur_s, cur_p, meas[M_ID], meas[M_IQ], meas[M_SPEED], 0.0, iq_ref, ts)
    u_d, u_q = limit_voltage(u_d, u_q, p[A.P_UDC])
    return u_d, u_q, r, iq_ref, position_ref


@nb.njit(cache=True, error_model="numpy")
def _stage(xs, x, k, dt, z, n):
    """xs = x + dt k for the first n states but the bristle, which is set to z."""
    for i in range(n):
        xs[i] = x[i] + dt * k[i]
    xs[A.X_Z] = z


@nb.njit(cache=True, error_model="numpy")
def plant_step(t, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h, work):
    """Advance x by one RK4 sub-step h with the voltages held; work is a (5, N_STATE) scratch.

    The bristle state is split off: in the RK4 stages it takes its exact value for the speed
    at the start of the sub-step held, and at the end of the sub-step its exact value for the
    mean speed over the sub-step. The loads are held at their value at the sub-step's
    midpoint: exact for steps that fall on sub-step boundaries (a step evaluated at a stage on
    its edge would leak into the step before it, a first-order error) and second-order
    accurate for smooth loads.
    """
    k1, k2, k3, k4, xs = work[0], work[1], work[2], work[3], work[4]
    n = A.active_states(p)
    z0 = x[A.X_Z]
    w0 = x[A.X_WM]
    z_half, z_full = A.bristle_half_and_full_step(z0, w0, h, p)
    t_load = signal_value(motor_load, t + 0.5 * h)
    f_load = signal_value(rod_load, t + 0.5 * h)
    r_load = signal_value(rudder_load, t + 0.5 * h)
    A.rhs(x, u_d, u_q, t_load, f_load, r_load, p, k1)
    _stage(xs, x, k1, 0.5 * h, z_half, n)
    A.rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k2)
    _stage(xs, x, k2, 0.5 * h, z_half, n)
    A.rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k3)
    _stage(xs, x, k3, h, z_full, n)
    A.rhs(xs, u_d, u_q, t_load, f_load, r_load, p, k4)
    for i in range(n):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    x[A.X_Z] = A.bristle_step(z0, 0.5 * (w0 + x[A.X_WM]), h, p)


@nb.njit(cache=True, error_model="numpy")
def check_state(x, limits, status, tick):
    """Flag the first state that is NaN/inf or beyond its limit; True when all are fine."""
    for i in range(A.N_STATE):
        if not np.isfinite(x[i]):
            status[0], status[1], status[2] = NOT_FINITE, tick, i
            return False
        if abs(x[i]) > limits[i]:
            status[0], status[1], status[2] = OUT_OF_BOUNDS, tick, i
            return False
    return True


@nb.njit(cache=True, error_model="numpy")
def record(
    row,
    t,
    x,
    p,
    motor_load,
    rod_load,
    rudder_load,
    u_d,
    u_q,
    speed_ref,
    iq_ref,
    position_ref,
    meas,
):
    """Write one trace row (layout TRACE)."""
    row[0] = t
    for i in range(A.N_STATE):
        row[C_STATE + i] = x[i]
    row[C_SPEED_REF] = speed_ref
    row[C_IQ_REF] = iq_ref
    row[C_POSITION_REF] = position_ref
    row[C_UD] = u_d
    row[C_UQ] = u_q
    A.plant_outputs(x, p, row[C_OUTPUTS : C_OUTPUTS + A.N_OUTPUTS])
    row[C_MOTOR_LOAD] = signal_value(motor_load, t)
    row[C_ROD_LOAD] = signal_value(rod_load, t)
    row[C_RUDDER_LOAD] = signal_value(rudder_load, t)
    row[C_MEASURED_SPEED] = meas[M_SPEED]
    row[C_MEASURED_POSITION] = meas[M_POSITION]


F8 = types.float64
I8 = types.int64
F8A = types.float64[::1]
F8A2 = types.float64[:, ::1]
RUN_SIG = types.void(
    I8,
    I8,
    I8,
    F8,  # k0, k1, substeps, ts
    F8A,
    F8A,
    F8A,
    F8A,
    F8A,
    F8A,
    I8,  # x, p, motor_load, rod_load, rudder_load, ref_sig, loop
    F8A2,
    F8A,
    I8,  # sensor_table, gap_state, seed
    CONTROLLER_TYPE,
    F8A,
    F8A,  # position controller
    CONTROLLER_TYPE,
    F8A,
    F8A,  # speed controller
    F8A,
    F8A,
    F8A,  # current params, current state, state limits
    I8,
    F8A2,
    types.int64[::1],  # record_every, trace, status
)


@nb.njit(RUN_SIG, cache=True, error_model="numpy", nogil=True)
def run_ticks(
    k0,
    k1,
    substeps,
    ts,
    x,
    p,
    motor_load,
    rod_load,
    rudder_load,
    ref_sig,
    loop,
    sensor_table,
    gap_state,
    seed,
    pos_fn,
    pos_p,
    pos_s,
    speed_fn,
    speed_p,
    speed_s,
    cur_p,
    cur_s,
    limits,
    record_every,
    trace,
    status,
):
    """Run ticks k0 .. k1-1 in place on x and the controller states.

    Rows of ``trace`` are written at every ``record_every``-th tick (row k // record_every).
    The sensor noise generator is seeded at k0 == 0. On a NaN/inf or a state beyond
    ``limits`` the run stops and ``status`` holds (code, tick, state index).
    """
    if k0 == 0:
        seed_noise(seed)
    h = ts / substeps
    work = np.zeros((5, A.N_STATE))
    meas = np.empty(N_MEAS)
    ref = np.empty(N_REF)
    out = np.empty(N_OUT)
    for k in range(k0, k1):
        t = k * ts
        u_d, u_q, speed_ref, iq_ref, position_ref = control_tick(
            t,
            x,
            p,
            sensor_table,
            gap_state,
            loop,
            ref_sig,
            pos_fn,
            pos_p,
            pos_s,
            speed_fn,
            speed_p,
            speed_s,
            cur_p,
            cur_s,
            ts,
            meas,
            ref,
            out,
        )
        if k % record_every == 0:
            record(
                trace[k // record_every],
                t,
                x,
                p,
                motor_load,
                rod_load,
                rudder_load,
                u_d,
                u_q,
                speed_ref,
                iq_ref,
                position_ref,
                meas,
            )
        for j in range(substeps):
            plant_step(t + j * h, x, u_d, u_q, p, motor_load, rod_load, rudder_load, h, work)
        if not check_state(x, limits, status, k + 1):
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


class EngineRun:
    """A run of a Setup on the compiled loop, advanced tick range by tick range.

    ``advance(k_end)`` runs ticks up to k_end (exclusive) and raises
    :class:`emasim.errors.SimulationDiverged` with the time and the state's name on a blow-up;
    ``run.x`` is the plant state in between (a co-simulation master reads and feeds it).
    """

    def __init__(self, setup):
        self.setup = setup
        self.run = setup.start()
        self.status = np.zeros(3, dtype=np.int64)
        self.tick = 0
        self.wall_s = 0.0

    def advance(self, k_end: int) -> None:
        setup, run = self.setup, self.run
        start = time.perf_counter()
        run_ticks(
            self.tick,
            k_end,
            setup.substeps,
            setup.sample_period_s,
            run.x,
            setup.plant,
            setup.motor_load,
            setup.rod_load,
            setup.rudder_load,
            setup.reference,
            run.loop,
            setup.sensors,
            run.gap,
            setup.seed,
            run.position.function,
            run.position.params,
            run.position_state,
            setup.speed.function,
            setup.speed.params,
            run.speed_state,
            setup.current_params,
            run.current_state,
            setup.limits,
            setup.record_every,
            run.trace,
            self.status,
        )
        self.wall_s += time.perf_counter() - start
        if self.status[0] != OK:
            raise SimulationDiverged(_divergence_message(setup, self.status))
        self.tick = k_end

    def result(self, linkage_columns: bool | None = None) -> Result:
        """The traces so far. The linkage's columns are kept when the plant has a linkage
        (or when ``linkage_columns`` says so); without one they are idle and left out."""
        if linkage_columns is None:
            linkage_columns = self.setup.plant[A.P_LOAD_MODEL] == A.LOAD_LINKAGE
        keep = [
            i
            for i, name in enumerate(TRACE_COLUMNS)
            if linkage_columns or name not in LINKAGE_TRACE_COLUMNS
        ]
        return Result(
            tuple(TRACE_COLUMNS[i] for i in keep),
            np.ascontiguousarray(self.run.trace[:, keep]),
            meta={"simulation_wall_s": self.wall_s},
        )


def simulate(setup, progress=None):
    """Run ``setup`` (a :class:`emasim.sim.setup.Setup`) on the compiled engine.

    progress, if given, is called with the fraction done after each chunk of ticks. Returns a
    :class:`emasim.sim.result.Result`; raises :class:`emasim.errors.SimulationDiverged` with the
    time and the state's name when the run blows up.
    """
    n = setup.n_ticks
    engine = EngineRun(setup)
    chunk = max(1, n // 50)
    for k0 in range(0, n, chunk):
        engine.advance(min(n, k0 + chunk))
        if progress is not None:
            progress(engine.tick / n)
    return engine.result()
