"""A scenario's loop as a python-control model, linearised from the simulated plant itself.

:func:`linearize` differentiates the compiled right-hand side the engine integrates
(emasim.plant.assembly: every element's terms, so every plant, the bench's included) at an
operating point and closes it with the controllers' linear forms. SI units; every symbol is a
deviation from the operating point.

Plant. A = d rhs / dx over the states that move (emasim.plant.actuator.active_states),
B = d rhs / d(vd, vq), C = d y / dx for the readings y = (id, iq, motor speed, the position the
loop closes on: emasim.sim.engine.fed_back_position of the noiseless readings
emasim.plant.sensors.true_values), by central differences with steps of 1000 times each
state's integration tolerance (or 1e-6 of its value, if larger). A central difference is the
derivative where the right-hand side is smooth, and at a kink (a transmission between driving
and back-driven at rest, a contact at its edge) the mean of the two one-sided slopes: the
describing function of a small sinusoid about the point. Where it is not continuous the
difference grows as the step shrinks: where one side is smooth (a transmission of efficiency
below 1 under load at rest, back-driven at the point itself and driving just beyond) the
slope of the branch the point lies on is taken, its one-sided difference; where both sides
jump the point is refused, naming the state.

The operating point. By default the steady state at the motor speed w0 (``operating_speed_rpm``,
default standstill) with id = 0 and the scenario's loads at t = 0: every rate zero but the
motor angle's, the nodes moving with the rotor (the rigid motion r, A r = 0), solved for the
other states and the voltages (scipy.optimize.root). With ``at_s`` instead: the state the
scenario's own run reaches at that time, with the voltages applied then (the bench at rest
under its standing preload, say).

Gaps. With ``gaps="closed"`` (default) each element's play is closed (Element.closed: its
contact kept in permanent contact, loaded by emasim.plant.element.CLOSED_OVERLAP so that its
damping acts on a small signal): the rigid connection below its contact mode, which keeps the
motor encoder's K theta_m apart from the rod. With ``gaps="as is"`` the plant is linearised as
it stands at the operating point: a gap open there passes no force. The clearance-joint
linkage's hinges are taken as they stand at the operating point either way. Friction is dropped
(``friction=False``, the default) or linearised at the operating point (``friction=True``: the
LuGre bristles' pre-sliding stiffness at rest).

A speed loop never sees where the drive stands: its states are taken less the rigid motion,
x - r theta_m / r_theta (theta_m dropped), which leaves out that pole at s = 0.

Controllers (emasim.control.current, .pid) in continuous time, with the gains of their
``build`` (the ones the simulation runs):

    current  ud* = Kp_d (0 - id) + I_d - np Lq (w0 iq + iq0 wm),     dI_d/dt = Ki_d (0 - id)
             uq* = Kp_q (iq* - iq) + I_q + np (Ld w0 id + psi_f wm), dI_q/dt = Ki_q (iq* - iq)
    PID      u = Kp e + I - Kd s / (1 + Tf s) y + Kff dr/dt,  dI/dt = Ki e,  e = r - y,
             and its rate output Kff d2r/dt2,

the speed PI (iq* from w* and wm) being the same law with Kd = 0; its Kff (acceleration
feed-forward, J/kt or 0) acts on the rate it is given: dw*/dt of a speed reference, or the
position loop's Kff d2r/dt2. Sample-and-hold and computation delay, Td + Ts/2, act on the
voltage: (vd, vq) = P(s) (ud*, uq*), P the Pade approximant of order PADE_ORDER.

The feed-forwards differentiate the reference: the loop is built with r, dr/dt (and d2r/dt2)
as separate inputs, T_k(s) = C (sI - A)^-1 b_k + d_k, and combined exactly as
T(s) = sum_k s^k T_k(s) (:func:`_with_rates`).

``loop`` chooses the model: "closed" (reference -> the fed-back signal), "open" (the loop
broken at a feedback, ``broken_at``: the position or the motor speed, by default the
outermost: L from the reading the controller gets, ``<reading>_fed_back``, to the reading the
plant gives, the references zero and any inner loop closed, so that the loop closed there is
L / (1 + L) and ``control.stability_margins(L)`` gives its margins), or "plant" ((vd, vq) ->
(id, iq, motor speed, fed-back position); its inputs named vd and vq, in V).

``discrete=True`` gives the closed loop at the control rate instead, exactly as the engine
runs it: the Jacobian of one tick of the compiled loop (emasim.sim.engine.run_ticks: the laws
as compiled, the computation delay, the RK4 sub-steps) in the plant's moving states, the
slots' states and the voltage still applied during the delay, and in the reference's value
(:func:`_tick_map`). The reference's rates are not an input of that map, so a loop with a
feed-forward is refused there.

Not modelled: the current, speed and voltage limits and anti-windup (none acts on a small
signal at an operating point inside them), sensor imperfections (ideal, sampled at every
tick). Refused with InputError: controllers without a linear form (anything but position
'pid'/'pi', speed 'pi'), a plant whose right-hand side is not continuous at the operating
point, and, until their small-signal models are checked against the simulation as the lumped
plants' are (tests/test_linear.py), the clearance-joint linkage and the load motor: the bench.
"""

import control
import numpy as np
from scipy import optimize

from .config import RPM
from .control import current as cur
from .control import pid
from .control.pid import PositionPID, SpeedPI
from .errors import InputError
from .interface import M_ID, M_IQ, M_SPEED, N_MEAS
from .plant import actuator as A
from .plant.elements import friction as fr
from .plant.sensors import ideal_table, true_values
from .scenarios.schema import Scenario
from .signals import KIND_CONSTANT, signal_value
from .sim.core import D_UD, D_UQ
from .sim.engine import EngineRun, fed_back_position, run_ticks
from .sim.setup import plant_facts

PADE_ORDER = 3  # of the delay's approximant: within 1e-5 rad of its phase up to 1 / (Td + Ts/2)
STEP_TOLERANCES = 1e3  # a state's difference step, in its integration tolerances
CONTINUITY = 10.0  # a column whose difference grows this much at a tenth of the step: a jump
GAPS = ("closed", "as is")
READINGS = ("id_A", "iq_A", "motor_speed_rad_s", "measured_position_m")  # the plant's outputs
LOOPS = ("closed", "open", "plant")


def linearize(
    scenario: Scenario,
    *,
    operating_speed_rpm: float = 0.0,
    at_s: float | None = None,
    gaps: str = "closed",
    friction: bool = False,
    loop: str = "closed",
    broken_at: str | None = None,
    discrete: bool = False,
) -> control.StateSpace:
    """The loop of ``scenario`` as a continuous-time state-space model (module docstring).

    Parameters
    ----------
    scenario : a validated Scenario.
    operating_speed_rpm : the steady motor speed w0 to linearise about (id = 0).
    at_s : linearise about the state the scenario's run reaches at this time instead.
    gaps : "closed" (each play closed, in loaded contact) or "as is".
    friction : linearise the friction at the operating point (default: dropped).
    loop : "closed", "open" or "plant".
    broken_at : where loop="open" cuts: "position" or "speed" (the inner loop, the outer one
        closed); default the outermost feedback.
    discrete : the closed loop at the control rate instead (:func:`_tick_map`).

    Returns
    -------
    control.StateSpace. "closed", one input and one output: for a position reference, from
    ``position_ref_m`` (m) to ``measured_position_m`` (m: x_L - x_h on the rod sensor, the rod
    position of the rudder encoder's angle, K theta_m on the motor encoder); for a speed
    reference, from ``speed_ref_rad_s`` to ``motor_speed_rad_s`` (rad/s). "open": from the
    fed-back reading to the plant's (same unit). "plant": (vd_V, vq_V) -> (id_A, iq_A,
    motor_speed_rad_s, measured_position_m). Its plant states are named as the simulation's.

    Raises
    ------
    InputError : a controller without a linear form, an option out of its range, or a plant
    not continuous at the operating point.
    """
    _refuse(scenario, gaps, loop, at_s)
    if broken_at not in (None, "speed", "position") or (
        broken_at == "position" and scenario.controllers.position is None
    ):
        cuts = "speed or position" if scenario.controllers.position else "speed (no position loop)"
        raise InputError(f"linearize: broken_at must be {cuts}, got {broken_at!r}")
    if discrete:
        _refuse_discrete(scenario, loop)
    setup = scenario.setup()
    p = _small_signal_plant(setup.plant, gaps, friction)
    position = scenario.controllers.position is not None
    t0 = 0.0 if at_s is None else at_s
    x0, u0 = (  # the steady state of the plant as it is (its gaps open), its friction dropped
        _operating_point(
            setup, _small_signal_plant(setup.plant, "as is", friction), operating_speed_rpm * RPM
        )
        if at_s is None
        else _state_at(setup, at_s)
    )
    if discrete:
        return _tick_map(scenario, setup, p, x0, at_s)
    plant = _plant(setup, p, x0, u0, t0, position)
    if loop == "plant":
        return plant
    facts, ts = plant_facts(scenario.plant), scenario.solver.sample_period_s
    c = scenario.controllers
    w0, iq0 = x0[A.X_WM], x0[A.X_IQ]
    delay = scenario.loop.computation_delay_s + 0.5 * ts
    blocks = [
        plant,
        _current_loop(c.current.build(facts, ts).params, w0, iq0),
        _delay(delay, "d"),
        _delay(delay, "q"),
    ]
    broken = broken_at or ("position" if position else "speed")  # the feedback loop="open" cuts
    cut = {"speed": "motor_speed_rad_s", "position": "measured_position_m"}[broken]
    fed = {
        name: f"{name}_fed_back" if loop == "open" and name == cut else name for name in READINGS
    }
    blocks.append(
        _pid(
            c.speed.build(facts, ts).params,
            "speed_ref",
            fed["motor_speed_rad_s"],
            "iq_ref",
            "speed_pi",
        )
    )
    if position:
        law = c.position.build(facts, ts).params
        blocks.append(
            _pid(law, "position_ref", fed["measured_position_m"], "speed_ref", "position_pid")
        )
        references = ["position_ref", "position_ref_rate", "position_ref_accel"]
        output, labels = "measured_position_m", ("position_ref_m", "measured_position_m")
    else:
        references = ["speed_ref", "speed_ref_rate"]
        output, labels = "motor_speed_rad_s", ("speed_ref_rad_s", "motor_speed_rad_s")
    ignore_inputs = ["speed_ref_accel"]  # the engine gives the speed loop no acceleration
    if loop == "open":
        ignore_inputs += references
        references, output = [fed[cut]], cut
    closed = control.interconnect(
        blocks,
        inplist=references,
        outlist=[output],
        ignore_inputs=ignore_inputs,
        ignore_outputs=["iq_ref_rate"],  # nor the current loop a rate
    )
    if loop == "open":  # negative feedback: the closed loop is L / (1 + L)
        return control.ss(
            closed.A,
            closed.B,
            -closed.C,
            -closed.D,
            inputs=[fed[cut]],
            outputs=[cut],
            states=closed.state_labels,
            name=f"{scenario.name}-open-loop-{broken}",
        )
    return control.ss(
        *_with_rates(closed),
        inputs=[labels[0]],
        outputs=[labels[1]],
        states=closed.state_labels,
        name=f"{scenario.name}-linear",
    )


def _refuse(scenario: Scenario, gaps: str, loop: str, at_s: float | None) -> None:
    """InputError, one line, for an option out of range or a controller without a linear form."""
    if gaps not in GAPS:
        raise InputError(f"linearize: gaps must be one of {', '.join(GAPS)}, got {gaps!r}")
    if loop not in LOOPS:
        raise InputError(f"linearize: loop must be one of {', '.join(LOOPS)}, got {loop!r}")
    if at_s is not None and not 0.0 <= at_s <= scenario.duration_s:
        raise InputError(
            f"linearize: at_s must be within the run, 0 to {scenario.duration_s:g} s, got {at_s}"
        )
    plant = scenario.plant
    if plant.linkage is not None or plant.load_motor is not None:  # differentiated, not checked
        what = "clearance-joint linkage (plant.linkage)" if plant.linkage else "plant.load_motor"
        raise InputError(
            f"linearize: the {what} is not yet validated against the simulation; "
            "use the lumped rudder stage without it"
        )
    c = scenario.controllers
    if not isinstance(c.speed, SpeedPI):
        raise InputError(
            f"linearize: the speed controller '{c.speed.name}' has no linear form; use speed=pi"
        )
    if c.position is not None and not isinstance(c.position, PositionPID):
        raise InputError(
            f"linearize: the position controller '{c.position.name}' has no linear form; "
            "use position=pid or position=pi"
        )


def _refuse_discrete(scenario: Scenario, loop: str) -> None:
    """InputError for what the tick's Jacobian does not give: another loop than the closed
    one, and a feed-forward, which reads the reference's rates (not an input of the map)."""
    if loop != "closed":
        raise InputError(f"linearize: discrete=True gives the closed loop only, got loop={loop!r}")
    facts, ts = plant_facts(scenario.plant), scenario.solver.sample_period_s
    c = scenario.controllers
    laws = [("speed", c.speed)] + ([("position", c.position)] if c.position else [])
    for slot, law in laws:
        if law.build(facts, ts).params[pid.KFF] != 0.0:
            raise InputError(
                f"linearize: discrete=True leaves the reference's rates out, and the {slot} "
                f"law's feed-forward reads them; turn it off (controllers.{slot}) or use the "
                "continuous model"
            )


def _small_signal_plant(params: np.ndarray, gaps: str, friction: bool) -> np.ndarray:
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


def _loads(setup, t: float) -> np.ndarray:
    """The three loads (motor N m, rod N, rudder N m) at time t."""
    return np.array(
        [signal_value(s, t) for s in (setup.motor_load, setup.rod_load, setup.rudder_load)]
    )


def _rates(p: np.ndarray, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """dx/dt of the plant p at x, inputs (vd, vq, motor load, rod load, rudder load)."""
    dx = np.zeros(A.N_STATE)
    A.rhs(x, *inputs, p, dx, np.zeros((4, 2)))
    return dx


def _readings(setup, p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(id, iq, motor speed, fed-back position): the noiseless readings the loops close on."""
    meas = np.zeros(N_MEAS)
    true_values(x, p, meas)
    position = fed_back_position(meas, p, setup.feedback, setup.rudder_to_rod)
    return np.array([meas[M_ID], meas[M_IQ], meas[M_SPEED], position])


def _difference(function, z0, steps, names: list[str], rows: list[str]) -> np.ndarray:
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


def _steps(x: np.ndarray, states: list[int]) -> np.ndarray:
    atol = np.asarray(A.PLANT.atol())[states]
    return np.maximum(STEP_TOLERANCES * atol, 1e-6 * np.abs(x[states]))


def _jacobians(setup, p, x0, u0, t0, states):
    """(A, B over (vd, vq), C of the readings) at (x0, u0) and the loads at t0, over the
    moving ``states``."""
    inputs0 = np.concatenate([u0, _loads(setup, t0)])

    def at(z):
        x = x0.copy()
        x[states] = z
        return x

    names = [A.STATE_NAMES[i] for i in states]
    z0, steps = x0[states], _steps(x0, states)
    a = _difference(lambda z: _rates(p, at(z), inputs0)[states], z0, steps, names, names)
    b = _difference(
        lambda v: _rates(p, x0, np.concatenate([v, inputs0[2:]]))[states],
        np.asarray(u0, dtype=float),
        np.full(2, 1e-3),
        ["vd", "vq"],
        names,
    )
    c = _difference(lambda z: _readings(setup, p, at(z)), z0, steps, names, list(READINGS))
    return a, b, c


def _moving(p: np.ndarray) -> list[int]:
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


def _rigid_motion(m: np.ndarray, theta: int) -> np.ndarray:
    """The rigid motion r (m r = 0: m = A of a continuous model, A - I of a discrete one)
    with the motor angle's entry (``theta``) 1: every node moved with the rotor, no spring
    deflected."""
    rest = [i for i in range(m.shape[0]) if i != theta]
    r = np.zeros(m.shape[0])
    r[theta] = 1.0
    r[rest] = np.linalg.lstsq(m[:, rest], -m[:, theta], rcond=None)[0]
    if np.linalg.norm(m @ r) > 1e-9 * np.linalg.norm(m[:, theta]) + 1e-300:
        raise InputError("linearize: the plant has no rigid motion with the rotor to run at speed")
    return r


def _less_rigid(a, b, c, r, theta: int, names: list[str]):
    """(A, B, C, names) in the states less the rigid motion, z = x - r theta (theta dropped):
    r is a motion the model keeps (A r = 0, or A r = r in discrete time), so the new state
    moves as (I - r e_theta) A P z, P putting theta = 0 back in."""
    keep = [i for i in range(a.shape[0]) if i != theta]
    project = (np.eye(a.shape[0]) - np.outer(r, np.eye(a.shape[0])[theta]))[keep]
    names = [f"{names[i]}_less_rigid" if r[i] else names[i] for i in keep]
    return project @ a[:, keep], project @ b, c[:, keep], names


def _operating_point(setup, p, w0: float) -> tuple[np.ndarray, np.ndarray]:
    """The steady state at motor speed w0 with id = 0 (module docstring): (x0, (vd, vq))."""
    states = _moving(p)
    x0 = setup.x0.copy()
    x0[states] = 0.0
    if w0 == 0.0 and not np.any(_loads(setup, 0.0)) and not np.any(_rates(p, x0, np.zeros(5))):
        return x0, np.zeros(2)
    a, _, _ = _jacobians(setup, p, x0, np.zeros(2), 0.0, states)
    r = _rigid_motion(a, states.index(A.X_THETA))
    fixed = {A.X_THETA, A.X_WM, A.X_ID}
    free = [k for k, i in enumerate(states) if i not in fixed]
    steady = [k for k, i in enumerate(states) if i != A.X_THETA]
    loads = _loads(setup, 0.0)

    def state(y):
        x = x0.copy()
        x[A.X_WM] = w0
        x[[states[k] for k in free]] = y[:-2]
        return x

    def residual(y):
        x = state(y)
        dx = _rates(p, x, np.concatenate([y[-2:], loads]))[states]
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


def _state_at(setup, at_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The run's state at ``at_s`` and the voltages applied then."""
    run = EngineRun(setup)
    run.advance(round(at_s / setup.sample_period_s))
    return run.x.copy(), np.array(run.run.data.drive[[D_UD, D_UQ]])


def _plant(setup, p, x0, u0, t0, position: bool) -> control.StateSpace:
    """The plant linearised at (x0, u0) and the loads at t0: inputs (vd, vq), outputs (id,
    iq, motor speed, and in a position loop the fed-back position); a speed loop's states
    less the rigid motion."""
    states = _moving(p)
    a, b, c = _jacobians(setup, p, x0, u0, t0, states)
    names = [A.STATE_NAMES[i] for i in states]
    if not position:
        theta = states.index(A.X_THETA)
        a, b, c, names = _less_rigid(a, b, c[:3], _rigid_motion(a, theta), theta, names)
    outputs = list(READINGS[: c.shape[0]])
    return control.ss(a, b, c, 0, inputs=["vd", "vq"], outputs=outputs, states=names, name="plant")


def _current_loop(params: np.ndarray, w0: float, iq0: float) -> control.StateSpace:
    """The current PI with its decoupling, linearised: (iq*, id, iq, wm) -> (ud*, uq*)."""
    kp_d, kp_q, ki_d, ki_q = params[[cur.KP_D, cur.KP_Q, cur.KI_D, cur.KI_Q]]
    ld, lq, psi, n_p = params[[cur.LD, cur.LQ, cur.PSI, cur.NP]]
    b = [[0.0, -ki_d, 0.0, 0.0], [ki_q, 0.0, -ki_q, 0.0]]
    d = [
        [0.0, -kp_d, -n_p * lq * w0, -n_p * lq * iq0],
        [kp_q, n_p * ld * w0, -kp_q, n_p * psi],
    ]
    return control.ss(
        np.zeros((2, 2)),
        b,
        np.eye(2),
        d,
        inputs=["iq_ref", "id_A", "iq_A", "motor_speed_rad_s"],
        outputs=["ud", "uq"],
        states=["integral_d", "integral_q"],
        name="current_pi",
    )


def _delay(seconds: float, axis: str) -> control.StateSpace:
    """The Pade approximant of the delay from the commanded to the applied voltage: that of
    a unit delay, P1(s), in time scaled by the delay, P(s) = P1(s T) (a well-scaled
    realisation: its matrices are of order 1/T, not 1/T^n)."""
    unit = control.ss(control.tf(*control.pade(1.0, PADE_ORDER)))
    return control.ss(
        unit.A / seconds,
        unit.B / seconds,
        unit.C,
        unit.D,
        inputs=[f"u{axis}"],
        outputs=[f"v{axis}"],
        name=f"delay_{axis}",
    )


def _pid(
    params: np.ndarray, ref: str, measured: str, command: str, name: str
) -> control.StateSpace:
    """The law of emasim.control.pid.pid in continuous time: inputs (ref, its rate and its
    acceleration, the measurement), outputs (command, its rate). The filtered derivative of
    v = c r - y (c the set-point weight), Kd s / (1 + Tf s) v, is Kd/Tf v + xi with
    Tf dxi/dt = -Kd/Tf v - xi."""
    kp, ki, kd, tf, kff, w = params[[pid.KP, pid.KI, pid.KD, pid.TF, pid.KFF, pid.D_WEIGHT]]
    a = [[0.0, 0.0], [0.0, -1.0 / tf]]
    b = [[ki, 0.0, 0.0, -ki], [-w * kd / tf**2, 0.0, 0.0, kd / tf**2]]
    c = [[1.0, 1.0], [0.0, 0.0]]
    d = [[kp + w * kd / tf, kff, 0.0, -kp - kd / tf], [0.0, 0.0, kff, 0.0]]
    states = ["integral", "derivative"]
    if kd == 0.0:  # a PI: no derivative state
        a, b, c, states = [[0.0]], [b[0]], [[1.0], [0.0]], states[:1]
    return control.ss(
        a,
        b,
        c,
        d,
        inputs=[ref, f"{ref}_rate", f"{ref}_accel", measured],
        outputs=[command, f"{command}_rate"],
        states=states,
        name=name,
    )


def _with_rates(loop: control.StateSpace) -> tuple[np.ndarray, ...]:
    """(A, B, C, D) of T(s) = sum_k s^k T_k(s), T_k the loop from its input k (the k-th
    derivative of the reference) to its one output.

    With T_k = C (sI - A)^-1 b_k + d_k, s^k C (sI - A)^-1 b_k = sum_{j<k} s^(k-1-j) C A^j b_k
    + C A^k (sI - A)^-1 b_k, so T has the same A and C, B = sum_k A^k b_k and
    D = d_0 + sum_{k>=1} C A^(k-1) b_k, provided the rest of the polynomial vanishes: d_k = 0
    and C A^j b_k = 0 for j < k - 1 (the output lags the reference's derivatives by the
    current loop and the inertia; checked).
    """
    a, b, c, d = loop.A, loop.B, loop.C, loop.D
    b_total, d_total = b[:, :1].copy(), d[:, :1].copy()
    for k in range(1, b.shape[1]):
        powers = [np.linalg.matrix_power(a, j) for j in range(k + 1)]
        rest = [d[0, k]] + [(c @ powers[j] @ b[:, k]).item() for j in range(k - 1)]
        if any(value != 0.0 for value in rest):
            raise ArithmeticError(f"the loop's response to d^{k}r/dt^{k} is not proper")
        b_total += powers[k] @ b[:, k : k + 1]
        d_total += c @ powers[k - 1] @ b[:, k : k + 1]
    return a, b_total, c, d_total


REFERENCE_STEP = {True: 1e-9, False: 1e-6}  # m of a position reference, rad/s of a speed one
START_TICKS = 2  # ticks run at the operating point before the map is taken (the laws start)


def _shifted(signal: np.ndarray, offset: float) -> np.ndarray:
    """An encoded signal (emasim.signals.encode) plus a constant ``offset``."""
    return np.concatenate([[signal[0] + 1.0], signal[1:], [KIND_CONSTANT, 1.0, offset]])


def _tick_map(scenario: Scenario, setup, p, x0, at_s) -> control.StateSpace:
    """The closed loop at the control rate: the Jacobian of one tick of the compiled loop
    (emasim.sim.engine.run_ticks: the sensors, the laws as compiled, the drive's limits, the
    computation delay and the RK4 sub-steps) in the plant's moving states, the slots' states
    and the voltage still applied during the delay, and in the reference's value.

    The operating point: the run's state at ``at_s``, or the steady state x0 held with the
    reference at its fed-back value, after START_TICKS ticks there (so that each law has made
    its first call). A speed loop's states are taken less the rigid motion, as in continuous
    time. The sensors are ideal; the reference's rates, which feed the
    feed-forwards, are not an input (its value steps, its rates stay). Laws that do not move
    or act (a slot's unused entries) are left out."""
    position = scenario.controllers.position is not None
    ideal = setup.with_(sensors=ideal_table())
    if at_s is None:
        y0 = _readings(setup, p, x0)[3 if position else 2]
        start = ideal.with_(plant=p, x0=x0, reference=_shifted(np.array([0.0]), y0))
        k0 = START_TICKS
    else:
        start = ideal.with_(plant=p)
        k0 = max(START_TICKS, round(at_s / setup.sample_period_s))
    run = EngineRun(start)
    run.advance(k0)
    model, data, laws = run.run.model, run.run.data, run.run.laws
    states = _moving(p)
    slots = [len(s) for s in data.slot_states]
    base = np.concatenate([data.x[states], *data.slot_states, data.drive[[D_UD, D_UQ]]])

    def tick(z, offset=0.0):
        x = data.x.copy()
        x[states] = z[: len(states)]
        chunks = np.split(z[len(states) : -2], np.cumsum(slots)[:-1])
        drive = data.drive.copy()
        drive[[D_UD, D_UQ]] = z[-2:]
        trial = data._replace(
            x=x,
            slot_states=tuple(c.copy() for c in chunks),
            drive=drive,
            sensor_state=data.sensor_state.copy(),
            status=np.zeros(3, dtype=np.int64),
        )
        shifted = model._replace(reference=_shifted(model.reference, offset))
        run_ticks(k0, k0 + 1, shifted, trial, *laws)
        return np.concatenate([trial.x[states], *trial.slot_states, trial.drive[[D_UD, D_UQ]]])

    names = [A.STATE_NAMES[i] for i in states]
    names += [
        f"{slot}_law_{i}"
        for slot, n in zip(("position", "speed", "current"), slots, strict=True)
        for i in range(n)
    ]
    names += ["vd_applied", "vq_applied"]
    steps = np.concatenate([_steps(data.x, states), np.full(len(base) - len(states), 1e-6)])
    a = _difference(tick, base, steps, names, names)
    b = _difference(
        lambda r: tick(base, r[0]),
        np.zeros(1),
        np.array([REFERENCE_STEP[position]]),
        ["reference"],
        names,
    )
    c = np.zeros((1, len(base)))
    c[0, : len(states)] = _difference(
        lambda z: _readings(setup, p, _with(data.x, states, z)),
        data.x[states],
        steps[: len(states)],
        names,
        list(READINGS),
    )[3 if position else 2]
    if not position:  # the speed loop never sees where the drive stands
        theta = states.index(A.X_THETA)
        r = _rigid_motion(a - np.eye(len(base)), theta)
        a, b, c, names = _less_rigid(a, b, c, r, theta, names)
    keep = _acting(a, c)
    labels = (
        ("position_ref_m", "measured_position_m")
        if position
        else ("speed_ref_rad_s", "motor_speed_rad_s")
    )
    return control.ss(
        a[np.ix_(keep, keep)],
        b[keep],
        c[:, keep],
        0,
        dt=setup.sample_period_s,
        inputs=[labels[0]],
        outputs=[labels[1]],
        states=[names[i] for i in keep],
        name=f"{scenario.name}-discrete",
    )


def _with(x: np.ndarray, states: list[int], z: np.ndarray) -> np.ndarray:
    out = x.copy()
    out[states] = z
    return out


def _acting(a: np.ndarray, c: np.ndarray) -> list[int]:
    """The states that act on another state or on the output (the others, a slot's unused
    entries, only hold or reset themselves)."""
    keep = list(range(a.shape[0]))
    while True:
        others = [i for i in keep if np.any(a[[j for j in keep if j != i], i]) or np.any(c[:, i])]
        if others == keep:
            return keep
        keep = others
