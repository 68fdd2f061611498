"""The plant's small-signal model, from the simulated plant itself (emasim.linear).

A = d rhs / dx over the states that move (:func:`moving_states`), B = d rhs / d(vd, vq, rod
force) and C = d y / dx for the readings the loops close on (:data:`READINGS`), by central
differences of the generated right-hand side (emasim.plant.assembly) with steps of
STEP_TOLERANCES times each state's integration tolerance (or 1e-6 of its value, if larger), the
rod force's ROD_FORCE_STEP_N (the right-hand side is affine in it). At a kink the central
difference is the mean of the one-sided slopes (the describing function of a small sinusoid
about the point); at a jump, the slope of the smooth side; where both sides jump, InputError
(:func:`difference`). The operating point is the steady state at a motor speed
(:func:`operating_point`) or a run's state (:func:`state_at`); the plays are closed and the
friction dropped by :func:`small_signal_plant`.
"""

import control
import numpy as np
from scipy import optimize

from .config import RPM
from .errors import InputError
from .interface import M_ID, M_IQ, M_SPEED, N_MEAS
from .plant import actuator as A
from .plant.elements import friction as fr
from .plant.sensors import true_values
from .signals import signal_value
from .sim.core import D_UD, D_UQ
from .sim.engine import EngineRun, fed_back_position

STEP_TOLERANCES = 1e3  # a state's difference step, in its integration tolerances
CONTINUITY = 10.0  # a column whose difference grows this much at a tenth of the step: a jump
READINGS = ("id_A", "iq_A", "motor_speed_rad_s", "measured_position_m")  # the plant's outputs
INPUTS = ("vd", "vq", "rod_force_N")  # the plant's inputs: V, V, and N opposing extension
ROD_LOAD = 3  # the rod force's place in the plant's inputs (vd, vq, motor, rod, rudder load)
ROD_FORCE_STEP_N = 1.0  # its difference step (the right-hand side is affine in it)


def small_signal_plant(params: np.ndarray, gaps: str, friction: bool) -> np.ndarray:
    """The packed plant with its plays closed (gaps="closed") and its friction dropped."""
    p = params.copy()
    present = A.PLANT.present_elements(p)
    for element in A.PLANT.elements:
        if gaps == "closed" and element.name in present:
            for name, value in element.closed:
                p[A.PLANT.params.index(name)] = value
    if not friction:
        p[A.P_FRICTION] = fr.FRICTION_NONE
    return p


def loads_at(setup, t: float) -> np.ndarray:
    """The three loads (motor N m, rod N, rudder N m) at time t."""
    return np.array(
        [signal_value(s, t) for s in (setup.motor_load, setup.rod_load, setup.rudder_load)]
    )


def rates(p: np.ndarray, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """dx/dt of the plant p at x, inputs (vd, vq, motor load, rod load, rudder load)."""
    return rates_and_hinges(p, x, inputs)[0]


def rates_and_hinges(p: np.ndarray, x: np.ndarray, inputs: np.ndarray):
    """(dx/dt, the linkage's hinges: (penetration m, normal force N) a row, hinges 1 to 4)."""
    dx, hinges = np.zeros(A.N_STATE), np.zeros((4, 2))
    A.rhs(x, *inputs, p, dx, hinges)
    return dx, hinges


def check_hinges_loaded(setup, p: np.ndarray, x0, u0, t0: float) -> None:
    """InputError where a hinge of the clearance-joint linkage is open at the operating point:
    no contact force holds it, so it passes no force to a small signal and the linear loop
    would have the rudder loose (a free mode, no gain at DC)."""
    _, hinges = rates_and_hinges(p, x0, np.concatenate([u0, loads_at(setup, t0)]))
    open_ = [h + 1 for h in range(4) if hinges[h, 1] <= 0.0]
    if open_:
        raise InputError(
            f"linearize: hinge {open_[0]} of the clearance-joint linkage is open at the "
            "operating point (no load holds it in contact), so it passes no force to a small "
            "signal; give a standing load (plant.load_motor.preload_Nm, load.rudder_torque_Nm) "
            "and linearise about the run's state once it has settled (at_s)"
        )


def readings(setup, p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(id, iq, motor speed, fed-back position): the noiseless readings the loops close on."""
    meas = np.zeros(N_MEAS)
    true_values(x, p, meas)
    position = fed_back_position(meas, p, setup.feedback, setup.rudder_to_rod)
    return np.array([meas[M_ID], meas[M_IQ], meas[M_SPEED], position])


def difference(function, z0, steps, names: list[str], rows: list[str]) -> np.ndarray:
    """d function / dz at z0 by central differences (steps per entry of z, named ``names``; the
    function's values named ``rows``). Where the difference grows by CONTINUITY at a tenth of
    the step (a jump, not a slope), the one-sided difference on the side that does not jump
    (the slope of the branch z0 lies on); InputError where both sides jump."""

    def slope(i, step, side):
        e = np.zeros_like(z0)
        e[i] = step
        ahead = function(z0 + e) if side >= 0 else function(z0)
        behind = function(z0 - e) if side <= 0 else function(z0)
        return (ahead - behind) / (step * (2.0 if side == 0 else 1.0))

    def jumps(coarse, fine):
        # a jump J gives J / h, ten times more at a tenth of the step; round-off, far less
        return np.abs(fine) > 0.5 * CONTINUITY * np.abs(coarse) + 1e-6 * np.max(np.abs(fine))

    columns = []
    for i, h in enumerate(steps):
        for side in (0, 1, -1):
            coarse, fine = slope(i, h, side), slope(i, 0.1 * h, side)
            jumped = jumps(coarse, fine)
            if not np.any(jumped):
                columns.append(coarse)
                break
            if side == 0:
                worst = rows[int(np.argmax(jumped))]
        else:
            raise InputError(
                f"linearize: the plant is not continuous at the operating point in "
                f"{names[i]} (d {worst}); drop friction (friction=False) or choose "
                "another operating point (at_s)"
            )
    return np.column_stack(columns)


def steps_for(x: np.ndarray, states: list[int]) -> np.ndarray:
    atol = np.asarray(A.PLANT.atol())[states]
    return np.maximum(STEP_TOLERANCES * atol, 1e-6 * np.abs(x[states]))


def with_states(x: np.ndarray, states: list[int], z: np.ndarray) -> np.ndarray:
    """A copy of the state x with its entries ``states`` set to z."""
    out = x.copy()
    out[states] = z
    return out


def jacobians(setup, p, x0, u0, t0, states):
    """(A, B over (vd, vq, rod force), C of the readings) at (x0, u0) and the loads at t0,
    over the moving ``states``."""
    inputs0 = np.concatenate([u0, loads_at(setup, t0)])

    def at(z):
        return with_states(x0, states, z)

    def with_inputs(v):
        out = inputs0.copy()
        out[[0, 1, ROD_LOAD]] = v
        return out

    names = [A.STATE_NAMES[i] for i in states]
    z0, steps = x0[states], steps_for(x0, states)
    a = difference(lambda z: rates(p, at(z), inputs0)[states], z0, steps, names, names)
    b = difference(
        lambda v: rates(p, x0, with_inputs(v))[states],
        inputs0[[0, 1, ROD_LOAD]],
        np.array([1e-3, 1e-3, ROD_FORCE_STEP_N]),
        list(INPUTS),
        names,
    )
    c = difference(lambda z: readings(setup, p, at(z)), z0, steps, names, list(READINGS))
    return a, b, c


def moving_states(p: np.ndarray) -> list[int]:
    """The states the plant integrates, but an absent element's (held at zero) and the
    bristle state of dropped friction (it neither moves nor acts)."""
    present = A.PLANT.present_elements(p)
    idle = {A.X_Z} if p[A.P_FRICTION] == fr.FRICTION_NONE else set()
    indices = (
        A.PLANT.states.index(s.name)
        for e in A.PLANT.elements
        if e.name in present
        for s in e.states
    )
    return [i for i in indices if i < A.active_states(p) and i not in idle]


def rigid_motion(m: np.ndarray, theta: int) -> np.ndarray:
    """The rigid motion r (m r = 0: m = A of a continuous model, A - I of a discrete one)
    with the motor angle's entry (``theta``) 1: every node moved with the rotor, no spring
    deflected."""
    rest = [i for i in range(m.shape[0]) if i != theta]
    r = np.zeros(m.shape[0])
    r[theta] = 1.0
    r[rest] = np.linalg.lstsq(m[:, rest], -m[:, theta], rcond=None)[0]
    if np.linalg.norm(m @ r) > 1e-9 * np.linalg.norm(m[:, theta]) + 1e-300:
        raise InputError(
            "linearize: the plant has no rigid motion with the rotor to run at speed (a load "
            "holds it: the load motor, the linkage); linearise about the run's state (at_s)"
        )
    return r


def less_rigid(a, b, c, r, theta: int, names: list[str]):
    """(A, B, C, names) in the states less the rigid motion, z = x - r theta (theta dropped):
    r is a motion the model keeps (A r = 0, or A r = r in discrete time), so the new state
    moves as (I - r e_theta) A P z, P putting theta = 0 back in."""
    keep = [i for i in range(a.shape[0]) if i != theta]
    project = (np.eye(a.shape[0]) - np.outer(r, np.eye(a.shape[0])[theta]))[keep]
    names = [f"{names[i]}less_rigid" if r[i] else names[i] for i in keep]
    return project @ a[:, keep], project @ b, c[:, keep], names


def operating_point(setup, p, w0: float) -> tuple[np.ndarray, np.ndarray]:
    """The steady state at motor speed w0 with id = 0 (module docstring): (x0, (vd, vq))."""
    states = moving_states(p)
    x0 = setup.x0.copy()
    x0[states] = 0.0
    if w0 == 0.0 and not np.any(loads_at(setup, 0.0)) and not np.any(rates(p, x0, np.zeros(5))):
        return x0, np.zeros(2)
    a, _, _ = jacobians(setup, p, x0, np.zeros(2), 0.0, states)
    r = rigid_motion(a, states.index(A.X_THETA))
    fixed = {A.X_THETA, A.X_WM, A.X_ID}
    free = [k for k, i in enumerate(states) if i not in fixed]
    steady = [k for k, i in enumerate(states) if i != A.X_THETA]
    loads = loads_at(setup, 0.0)

    def state(y):
        x = x0.copy()
        x[A.X_WM] = w0
        x[[states[k] for k in free]] = y[:-2]
        return x

    def residual(y):
        x = state(y)
        dx = rates(p, x, np.concatenate([y[-2:], loads]))[states]
        return (dx - r * w0)[steady]

    # unknowns scaled by a million integration tolerances (a micrometre of deflection) and a
    # volt: hybr's steps are relative, and the deflections are a thousandth of the speeds
    scale = np.concatenate([1e6 * np.asarray(A.PLANT.atol())[[states[k] for k in free]], [1, 1]])
    solution = optimize.root(
        residual, np.zeros(len(free) + 2), method="hybr", options={"xtol": 1e-13, "diag": 1 / scale}
    )
    if not solution.success or np.max(np.abs(residual(solution.x))) > 1e-6:
        raise InputError(
            f"linearize: no steady state found at {w0 / RPM:g} rpm ({solution.message.strip()}); "
            "linearise about the run's state with at_s"
        )
    return state(solution.x), solution.x[-2:]


def state_at(setup, at_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The run's state at ``at_s`` and the voltages applied then."""
    run = EngineRun(setup)
    run.advance(round(at_s / setup.sample_period_s))
    return run.x.copy(), np.array(run.run.data.drive[[D_UD, D_UQ]])


def plant_model(setup, p, x0, u0, t0, position: bool) -> control.StateSpace:
    """The plant linearised at (x0, u0) and the loads at t0: inputs (vd, vq, rod force),
    outputs (id, iq, motor speed, and in a position loop the fed-back position); a speed
    loop's states less the rigid motion."""
    states = moving_states(p)
    a, b, c = jacobians(setup, p, x0, u0, t0, states)
    names = [A.STATE_NAMES[i] for i in states]
    if not position:
        theta = states.index(A.X_THETA)
        a, b, c, names = less_rigid(a, b, c[:3], rigid_motion(a, theta), theta, names)
    outputs = list(READINGS[: c.shape[0]])
    return control.ss(a, b, c, 0, inputs=list(INPUTS), outputs=outputs, states=names, name="plant")
