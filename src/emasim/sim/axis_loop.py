"""The force-driven axis in closed loop: the sampled controller, the drive, RK4 in between.

At tick k (t_k = k Ts) the encoder reads the carriage position, quantised to its resolution,
the controller (emasim.control.nested_p) computes the command from it and the reference r_k,
and the drive's range limits it to +-u_max (the benchmark's +-10 V). The drive adds to it the
command ``added[k]`` (V: the benchmark's cross-validation pulses, added at the drive's input)
and applies the force g_tau (u + added), held over the tick (zero-order hold). A computation
delay of ``delay`` sub-steps (0 to all of them: a whole tick) keeps the previous tick's
command acting that long. Between ticks the plant (emasim.plant.axis) is integrated with
``substeps`` fixed RK4 sub-steps.

The measured reference and added command drive it sample by sample (``reference[k]``,
``added[k]``): the loop runs on the measured trace's own clock.
"""

from dataclasses import dataclass

import numpy as np

from ..control.nested_p import FIR_HISTORY, nested_p_command
from ..errors import SimulationDiverged
from ..jit import njit
from ..plant import axis as AX
from ..plant.element import RK4_DECAY_LIMIT

# the trace's columns, one row per tick
COLUMNS = (
    "time_s",
    "position_m",
    "velocity_m_s",
    "measured_position_m",
    "command_V",
    "drive_force_N",
    "friction_force_N",
    "added_command_V",
)
OK, NOT_FINITE, OUT_OF_BOUNDS = 0, 1, 2


@njit(cache=True, inline="always", error_model="numpy")
def _rk4(x, u, p, h, k1, k2, k3, k4, xs, hinges):
    """One RK4 sub-step h of the axis with the drive's command u (V) held."""
    n = x.size
    AX.rhs(x, 0.0, u, 0.0, 0.0, 0.0, p, k1, hinges)
    for i in range(n):
        xs[i] = x[i] + 0.5 * h * k1[i]
    AX.rhs(xs, 0.0, u, 0.0, 0.0, 0.0, p, k2, hinges)
    for i in range(n):
        xs[i] = x[i] + 0.5 * h * k2[i]
    AX.rhs(xs, 0.0, u, 0.0, 0.0, 0.0, p, k3, hinges)
    for i in range(n):
        xs[i] = x[i] + h * k3[i]
    AX.rhs(xs, 0.0, u, 0.0, 0.0, 0.0, p, k4, hinges)
    for i in range(n):
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, error_model="numpy")
def run_axis(x, p, limits, reference, added, ts, substeps, resolution, kp, kv, u_max,
             delay, trace, status):  # fmt: skip
    """Run the closed loop over every sample of ``reference`` from the state x (changed in
    place), writing one row of COLUMNS per tick into ``trace``; ``status`` receives
    (code, tick, state) where a state is not finite or beyond ``limits``."""
    n_ticks = reference.size
    h = ts / substeps
    history = np.empty(FIR_HISTORY)
    stages = np.empty((5, x.size))
    k1, k2, k3, k4, xs = stages[0], stages[1], stages[2], stages[3], stages[4]
    hinges = np.empty((1, 1))
    friction_out = np.empty(AX.N_OUTPUTS)
    for j in range(FIR_HISTORY):  # the readings of the ticks before, at the initial speed
        q = x[AX.X_POSITION] - (j + 1) * ts * x[AX.X_VELOCITY]
        history[j] = round(q / resolution) * resolution if resolution > 0.0 else q
    held = 0.0  # the command computed a tick ago (the delayed one)
    for k in range(n_ticks):
        q = x[AX.X_POSITION]
        if resolution > 0.0:
            q = round(q / resolution) * resolution
        u = nested_p_command(history, q, reference[k], kp, kv, ts)
        u = min(max(u, -u_max), u_max)
        AX.plant_outputs(x, p, friction_out)
        row = trace[k]
        row[0] = k * ts
        row[1] = x[AX.X_POSITION]
        row[2] = x[AX.X_VELOCITY]
        row[3] = q
        row[4] = u + added[k]  # the drive's input, what the benchmark records as vir
        row[5] = p[AX.P_GAIN] * row[4]  # the force, once the delay has passed
        row[6] = friction_out[AX.O_FRICTION]
        row[7] = added[k]
        for j in range(substeps):
            applied = (held if j < delay else u) + added[k]
            _rk4(x, applied, p, h, k1, k2, k3, k4, xs, hinges)
        for i in range(x.size):
            if not np.isfinite(x[i]):
                status[0], status[1], status[2] = NOT_FINITE, k, i
                return
            if abs(x[i]) > limits[i]:
                status[0], status[1], status[2] = OUT_OF_BOUNDS, k, i
                return
        held = u
    status[0] = OK


@dataclass(frozen=True)
class AxisLoop:
    """The benchmark's loop: sample period (s), RK4 sub-steps per tick, the encoder's
    resolution (m, 0 for none), the gains kp (1/s) and kv (V/(m/s)), the drive's range
    +-u_max (V) and the computation delay in sub-steps (0 to ``substeps``)."""

    sample_period_s: float
    substeps: int
    resolution_m: float
    kp_per_s: float
    kv_V_s_per_m: float
    command_limit_V: float
    delay_substeps: int


def stable_substeps(axis: AX.AxisParams, loop: AxisLoop) -> None:
    """Refuse, in one line, a sub-step too long for RK4 on the axis's fastest mode: the
    smoothed Coulomb slope Fc / (v_s M) or the LuGre bristle's oscillation."""
    p = AX.pack(axis)
    value = AX.AXIS.value_of(p)
    h = loop.sample_period_s / loop.substeps
    f = axis.friction
    slope = max(f.coulomb_N, f.negative()[0]) / (f.smoothing_speed_m_s * axis.mass_kg)
    modes = [("the smoothed Coulomb slope", slope, RK4_DECAY_LIMIT)]
    modes += [
        (what, rate, limit)
        for element in AX.AXIS.elements
        for what, rate, limit in element.modes(value, lambda port: axis.mass_kg)
    ]
    for what, rate, limit in modes:
        if h * rate >= limit:
            raise ValueError(
                f"solver.substeps={loop.substeps} gives h = {h:.3g} s, too long for {what} "
                f"({rate:.4g} 1/s): RK4 needs h * rate < {limit:.3g}, so at least "
                f"{int(np.ceil(loop.sample_period_s * rate / limit))} sub-steps"
            )


def simulate_axis(
    axis: AX.AxisParams,
    loop: AxisLoop,
    reference: np.ndarray,
    added: np.ndarray | None = None,
    position0: float | None = None,
    velocity0: float = 0.0,
) -> dict[str, np.ndarray]:
    """The closed loop driven by ``reference`` (m, one sample per tick) and ``added`` (V,
    added to the command at the drive), from ``position0`` (the reference's first sample by
    default) at ``velocity0`` (m/s; the encoder's earlier readings on that motion): the
    trace's COLUMNS by name. Raises SimulationDiverged naming the
    time, the state and its value."""
    stable_substeps(axis, loop)
    reference = np.ascontiguousarray(reference, dtype=np.float64)
    added = (
        np.zeros_like(reference) if added is None else np.ascontiguousarray(added, dtype=np.float64)
    )
    p = AX.pack(axis)
    x = np.zeros(AX.N_STATE)
    x[AX.X_POSITION] = reference[0] if position0 is None else position0
    x[AX.X_VELOCITY] = velocity0
    limits = AX.AXIS.limits(axis)
    trace = np.empty((reference.size, len(COLUMNS)))
    status = np.zeros(3, dtype=np.int64)
    run_axis(x, p, limits, reference, added, loop.sample_period_s, loop.substeps,
             loop.resolution_m, loop.kp_per_s, loop.kv_V_s_per_m, loop.command_limit_V,
             loop.delay_substeps, trace, status)  # fmt: skip
    if status[0] != OK:
        tick, state = int(status[1]), AX.AXIS.states.names[int(status[2])]
        what = "not finite" if status[0] == NOT_FINITE else "beyond its bound"
        raise SimulationDiverged(
            f"the axis diverged at t = {tick * loop.sample_period_s:.6g} s: {state} is {what} "
            f"({x[int(status[2])]:.6g}); likely cause: a sub-step too long for the friction's "
            "slope or a mass or gain far from the axis's"
        )
    return {name: trace[:, i] for i, name in enumerate(COLUMNS)}
