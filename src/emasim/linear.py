"""The closed loop of a scenario as a python-control model, linearised (issue 14, item 6).

:func:`linearize` returns the continuous-time ``control.StateSpace`` from the loop's reference
to the signal it feeds back, for the drive without friction and with its backlash gap closed,
about a steady motor speed w0 (default standstill) with id = 0. SI units throughout; every
symbol below is a deviation from the operating point unless it carries a 0.

Plant (emasim.plant.elements.motor, .drivetrain, .actuator), linearised at (id0 = 0, iq0, w0):

    Ld did/dt = vd - Rs id + np Lq (w0 iq + iq0 wm)                      (V)
    Lq diq/dt = vq - Rs iq - np (Ld w0 id + psi_f wm)                    (V)
    Te        = kt iq + 1.5 np (Ld - Lq) iq0 id,   kt = 1.5 np psi_f     (N m)
    J dwm/dt  = Te - B wm - (K / eta) Fb                                 (N m)
    M_L dv_L/dt = Fb - c_L v_L                                           (N)
    Fb        = k_b (K theta_m - x_L) + c_b (K wm - v_L)                 (N)

iq0 = (B + K^2 c_L / eta) w0 / kt holds the steady speed. The gap is closed by keeping its
contact spring k_b, c_b in permanent contact (width 0, no limit on the damping): it is what the
simulation integrates with plant.backlash.width_mm = 0 (whose damping limit |c_b dv| <=
k_b |dx| only acts while the spring is nearly unloaded), it behaves as the rigid connection
below its contact mode (about 300 Hz on sea805) and it keeps the motor encoder's K theta_m
apart from the rod's x_L. M_L is PlantParams.load_mass_kg, the rod and the rudder inertia
through the arm. The reflected torque is taken on its driving branch, K Fb / eta (steady motion
is always driven: the load only dissipates); a reversing small signal back-drives half of each
cycle, so with eta < 1 this is an approximation. The optional elements add their nodes with
the same equations as emasim.plant.actuator, linear already: the series compliance (node m_n
between the gap and the spring k_s, c_s), the anchorage (body x_h on k_a, c_a, the nut at
x_h + K theta_m) and the rudder shaft (torsion k_t, c_t from the rocker angle x_L / arm to the
disk J_d).

Controllers (emasim.control.current, .pid) in continuous time, with the gains of their
``build`` (the ones the simulation runs):

    current  ud* = Kp_d (0 - id) + I_d - np Lq (w0 iq + iq0 wm),     dI_d/dt = Ki_d (0 - id)
             uq* = Kp_q (iq* - iq) + I_q + np (Ld w0 id + psi_f wm), dI_q/dt = Ki_q (iq* - iq)
    PID      u = Kp e + I - Kd s / (1 + Tf s) y + Kff dr/dt,  dI/dt = Ki e,  e = r - y,
             and its rate output Kff d2r/dt2,

the speed PI (iq* from w* and wm) being the same law with Kd = 0; its Kff (acceleration
feed-forward, J/kt or 0) acts on the rate it is given: dw*/dt of a speed reference, or the
position loop's Kff d2r/dt2. Sample-and-hold and computation delay, Td + Ts/2, act on the
voltage: (vd, vq) = P(s) (ud*, uq*), P the Pade approximant of order PADE_ORDER. Without it the
decoupling would cancel the cross-coupling and the back-EMF exactly, leaving per axis
L di/dt = Kp (i* - i) + I - Rs i, i.e. i = alpha_c / (s + alpha_c) i* with the internal-model
gains; with it what remains of them is np psi_f (P(s) - 1) wm on the q axis and the like.

The feed-forwards differentiate the reference: the loop is built with r, dr/dt (and d2r/dt2)
as separate inputs, T_k(s) = C (sI - A)^-1 b_k + d_k, and combined exactly as
T(s) = sum_k s^k T_k(s) (:func:`_with_rates`).

Not modelled: friction, the backlash's width, end stops, current, speed and voltage limits,
anti-windup, the drive's ratings (none acts on a small signal), sensor imperfections (the
sensors are taken as ideal, sampled at every tick). Refused with InputError: controllers
without a linear form (anything but position 'pid'/'pi', speed 'pi'), the clearance-joint
linkage (with any feedback, 'rudder' included), the load motor, and any element this module
does not write out (:data:`WRITTEN_OUT`: an element added since, such as the gear mesh, is
refused, never left out in silence). On the lumped stage the
'rudder' feedback reads x_L, the 'rod' feedback the rod's extension x_L - x_h and the 'motor'
feedback K theta_m.
"""

import control
import numpy as np

from .config import RPM
from .control import current as cur
from .control import pid
from .control.pid import PositionPID, SpeedPI
from .errors import InputError
from .plant import actuator as A
from .scenarios.schema import Scenario
from .sim.setup import plant_facts

PADE_ORDER = 3  # of the delay's approximant: within 1e-5 rad of its phase up to 1 / (Td + Ts/2)


def linearize(scenario: Scenario, *, operating_speed_rpm: float = 0.0) -> control.StateSpace:
    """The closed loop of ``scenario`` as a continuous-time state-space model.

    Parameters
    ----------
    scenario : a validated Scenario; its friction is dropped and its backlash gap closed.
    operating_speed_rpm : the steady motor speed w0 to linearise about (id = 0).

    Returns
    -------
    control.StateSpace, one input and one output: for a position reference, from the rod
    position reference ``position_ref_m`` (m) to the position the loop feeds back,
    ``measured_position_m`` (m: x_L - x_h on the rod sensor, x_L on the rudder encoder,
    K theta_m on the motor encoder); for a speed reference, from ``speed_ref_rad_s`` to
    ``motor_speed_rad_s`` (rad/s). Its states are named by block (plant, current_pi,
    delay_d, delay_q, speed_pi, position_pid).

    Raises
    ------
    InputError : a controller or a plant element without a linear form (module docstring,
    which states the equations and the approximations).
    """
    _refuse_nonlinear(scenario)
    p = scenario.plant.pack()
    facts, ts = plant_facts(scenario.plant), scenario.solver.sample_period_s
    c = scenario.controllers
    w0 = operating_speed_rpm * RPM
    iq0 = (p[A.P_B] + p[A.P_K] ** 2 * p[A.P_CL] / p[A.P_ETA]) * w0 / facts.torque_constant_Nm_per_A
    delay = scenario.loop.computation_delay_s + 0.5 * ts
    feedback = None if c.position is None else scenario.loop.position_feedback
    blocks = [
        _plant(p, w0, iq0, feedback),
        _current_loop(c.current.build(facts, ts).params, w0, iq0),
        _delay(delay, "d"),
        _delay(delay, "q"),
        _pid(c.speed.build(facts, ts).params, "speed_ref", "motor_speed", "iq_ref", "speed_pi"),
    ]
    if c.position is None:
        references, output = ["speed_ref", "speed_ref_rate"], "motor_speed"
        labels = ("speed_ref_rad_s", "motor_speed_rad_s")
    else:
        law = c.position.build(facts, ts).params
        blocks.append(_pid(law, "position_ref", "position", "speed_ref", "position_pid"))
        references = ["position_ref", "position_ref_rate", "position_ref_accel"]
        output, labels = "position", ("position_ref_m", "measured_position_m")
    loop = control.interconnect(
        blocks,
        inplist=references,
        outlist=[output],
        ignore_inputs=["speed_ref_accel"],  # the engine gives the speed loop no acceleration
        ignore_outputs=["iq_ref_rate"],  # nor the current loop a rate
    )
    return control.ss(
        *_with_rates(loop),
        inputs=[labels[0]],
        outputs=[labels[1]],
        states=loop.state_labels,
        name=f"{scenario.name}-linear",
    )


# the elements whose small-signal terms _plant writes out, or that act on no small signal
WRITTEN_OUT = frozenset(
    {
        "motor",
        "friction",
        "transmission",
        "backlash",
        "rod",
        "end_stops",
        "ratings",
        "compliance",
        "anchorage",
        "rudder_shaft",
    }
)


def _refuse_nonlinear(scenario: Scenario) -> None:
    """InputError, one line, for a controller or a plant element without a linear form."""
    c, plant = scenario.controllers, scenario.plant
    if not isinstance(c.speed, SpeedPI):
        raise InputError(
            f"linearize: the speed controller '{c.speed.name}' has no linear form; use speed=pi"
        )
    if c.position is not None and not isinstance(c.position, PositionPID):
        raise InputError(
            f"linearize: the position controller '{c.position.name}' has no linear form; "
            "use position=pid or position=pi"
        )
    if plant.linkage is not None:
        what = (
            "rudder feedback through the" if scenario.loop.position_feedback == "rudder" else "the"
        )
        raise InputError(
            f"linearize: {what} clearance-joint linkage (plant.linkage) has no linear form; "
            "use the lumped rudder stage"
        )
    if plant.load_motor is not None:
        raise InputError("linearize: plant.load_motor has no linear form; remove it")
    unknown = sorted(set(A.PLANT.present_elements(plant.pack())) - WRITTEN_OUT)
    if unknown:
        raise InputError(
            f"linearize: plant.{unknown[0]} is not written out in emasim.linear yet; remove it"
        )


def _plant(p: np.ndarray, w0: float, iq0: float, feedback: str | None) -> control.StateSpace:
    """The motor's dq currents and the drive train, linearised: inputs (vd, vq), outputs
    (id, iq, motor speed and, in a position loop, the position read through ``feedback``).

    A speed loop never sees where the drive stands: its position states are the coordinates
    less the rigid motion with the rotor, q - r theta_m (r moves every node with the nut, so
    no spring deflects), which leaves out the pole at s = 0 of that motion."""
    coords, masses, stiffness, damping, rigid = _drive_train(p)
    n = len(coords)
    names = [A.STATE_NAMES[i] for i in coords]
    if feedback is None:
        to_states = np.eye(n)[1:] - np.outer(rigid[1:], np.eye(n)[0])  # theta_m is q[0]
        from_states = np.eye(n)[:, 1:]  # the deflections: K q = K (q - r theta_m)
        names = [f"{name}_less_rigid" for name in names[1:]]
    else:
        to_states = from_states = np.eye(n)
    m = len(names)
    rs, ld, lq, psi, n_p = p[A.P_RS], p[A.P_LD], p[A.P_LQ], p[A.P_PSI], p[A.P_NP]
    i_d, i_q, q, v = 0, 1, slice(2, 2 + m), slice(2 + m, 2 + m + n)
    w = 2 + m  # the motor speed, the first velocity
    a = np.zeros((2 + m + n, 2 + m + n))
    a[i_d, [i_d, i_q, w]] = np.array([-rs, n_p * lq * w0, n_p * lq * iq0]) / ld
    a[i_q, [i_d, i_q, w]] = np.array([-n_p * ld * w0, -rs, -n_p * psi]) / lq
    a[q, v] = to_states
    a[v, q] = -stiffness @ from_states / masses[:, None]
    a[v, v] = -damping / masses[:, None]
    a[w, [i_d, i_q]] += np.array([1.5 * n_p * (ld - lq) * iq0, 1.5 * n_p * psi]) / masses[0]
    b = np.zeros((2 + m + n, 2))
    b[i_d, 0], b[i_q, 1] = 1.0 / ld, 1.0 / lq
    c = np.zeros((3 if feedback is None else 4, 2 + m + n))
    c[0, i_d] = c[1, i_q] = c[2, w] = 1.0
    if feedback == "motor":
        c[3, 2] = p[A.P_K]
    elif feedback is not None:  # the rudder through the lumped arm reads x_L, the rod sensor
        c[3, 2 + coords.index(A.X_XL)] = 1.0  # its extension x_L - x_h
        if feedback == "rod" and A.X_XH in coords:
            c[3, 2 + coords.index(A.X_XH)] = -1.0
    velocities = [A.STATE_NAMES[i + 1] for i in coords]  # each position's rate follows it
    return control.ss(
        a,
        b,
        c,
        0,
        inputs=["vd", "vq"],
        outputs=["id", "iq", "motor_speed", "position"][: c.shape[0]],
        states=["id_A", "iq_A", *names, *velocities],
        name="plant",
    )


def _drive_train(p: np.ndarray) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The linear drive train M q'' + C q' + K q = Te e_theta: (the coordinates q, motor angle
    first, as their state indices in emasim.plant.actuator; the masses M; K; C; the rigid
    motion r per motor radian, K r = 0).

    Each spring-damper F = k d + c d' acts across d = g . q and pushes the coordinates by
    -h F, h = g but on the motor, where the gap's force arrives as K F / eta."""
    coords = [A.X_THETA]
    coords += [A.X_XN] if p[A.P_COMPLIANCE] else []
    coords += [A.X_XH] if p[A.P_ANCHORAGE] else []
    coords += [A.X_XL]
    coords += [A.X_DISK] if p[A.P_SHAFT] else []
    masses = {A.X_THETA: A.P_J, A.X_XN: A.P_MN, A.X_XH: A.P_MH, A.X_XL: A.P_ML, A.X_DISK: A.P_JD}
    n = len(coords)
    stiffness, damping = np.zeros((n, n)), np.zeros((n, n))

    def vector(weights: dict[int, float]) -> np.ndarray:
        g = np.zeros(n)
        for coord, weight in weights.items():
            g[coords.index(coord)] += weight
        return g

    def element(k: float, c: float, across: dict, on_motor: float = 1.0) -> None:
        g = vector(across)
        h = g.copy()
        h[0] *= on_motor
        stiffness[:] += k * np.outer(h, g)
        damping[:] += c * np.outer(h, g)

    k, far = p[A.P_K], A.X_XN if p[A.P_COMPLIANCE] else A.X_XL
    nut = {A.X_THETA: k, far: -1.0} | ({A.X_XH: 1.0} if p[A.P_ANCHORAGE] else {})
    element(p[A.P_KB], p[A.P_CB], nut, on_motor=1.0 / p[A.P_ETA])
    element(0.0, p[A.P_B], {A.X_THETA: 1.0})
    element(0.0, p[A.P_CL], {A.X_XL: 1.0})
    if p[A.P_COMPLIANCE]:
        element(p[A.P_KS], p[A.P_CS], {A.X_XN: 1.0, A.X_XL: -1.0})
    if p[A.P_ANCHORAGE]:
        element(p[A.P_KA], p[A.P_CA], {A.X_XH: 1.0})
    if p[A.P_SHAFT]:
        element(p[A.P_KT], p[A.P_CT], {A.X_XL: 1.0 / p[A.P_ARM], A.X_DISK: -1.0})
    rigid = np.array(
        [{A.X_THETA: 1.0, A.X_XH: 0.0, A.X_DISK: k / p[A.P_ARM]}.get(i, k) for i in coords]
    )
    return coords, np.array([p[masses[i]] for i in coords]), stiffness, damping, rigid


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
        inputs=["iq_ref", "id", "iq", "motor_speed"],
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
