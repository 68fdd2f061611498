"""A scenario's loop as a python-control model, linearised from the simulated plant itself.

:func:`linearize` differentiates the compiled right-hand side the engine integrates
(emasim.plant.assembly: every element's terms, so every plant, the bench's included) at an
operating point and closes it with the controllers' linear forms. SI units; every symbol is a
deviation from the operating point.

Plant. A = d rhs / dx over the states that move (emasim.plant.actuator.active_states),
B = d rhs / d(vd, vq, rod force), C = d y / dx for the readings y = (id, iq, motor speed, the
position the loop closes on: emasim.sim.engine.fed_back_position of the noiseless readings
emasim.plant.sensors.true_values), by central differences (emasim.small_signal: each step
a fixed multiple of its state's integration tolerance, or 1e-6 of its value, if larger). A
central difference is the derivative where the right-hand side is smooth, and at a kink (a
transmission between driving and back-driven at rest, a contact at its edge) the mean of the
two one-sided slopes: the describing function of a small sinusoid about the point. Where it
is not continuous the difference grows as the step shrinks: where one side is smooth (a
transmission of efficiency below 1 under load at rest, back-driven at the point itself and
driving just beyond) the slope of the branch the point lies on is taken, its one-sided
difference; where both sides jump the point is refused, naming the state.

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
voltage: (vd, vq) = P(s) (ud*, uq*), P a Pade approximant (emasim.control.continuous).

The feed-forwards differentiate the reference: the loop is built with r, dr/dt (and d2r/dt2)
as separate inputs, T_k(s) = C (sI - A)^-1 b_k + d_k, and combined exactly as
T(s) = sum_k s^k T_k(s) (emasim.control.continuous.with_rates).

``kind`` chooses the model: "closed" (reference -> the fed-back signal), "open" (the loop
broken at a feedback, ``broken_at``: the position or the motor speed, by default the
outermost: L from the reading the controller gets, ``<reading>_fed_back``, to the reading the
plant gives, the references zero and any inner loop closed, so that the loop closed there is
L / (1 + L) and ``control.stability_margins(L)`` gives its margins), or "plant" ((vd, vq) ->
(id, iq, motor speed, fed-back position); its inputs named vd and vq, in V).

``discrete=True`` gives the closed loop at the control rate instead, exactly as the engine
runs it: the Jacobian of one tick of the compiled loop (emasim.sim.engine.run_ticks: the laws
as compiled, the computation delay, the RK4 sub-steps) in the plant's moving states, the
slots' states and the voltage still applied during the delay, and in the reference's value
or (``input="rod_force_N"``) a rod force held over the tick, the reference held
(emasim.discrete_loop.tick_map); its output is the reading the outermost loop closes on. The
reference's rates are not an input of that map, so from the reference a loop with a
feed-forward is refused there; from the rod force the reference is held and its rates are
zero, so the feed-forwards are no part of the small signal.

Not modelled: the current, speed and voltage limits and anti-windup (none acts on a small
signal at an operating point inside them), sensor imperfections (ideal, sampled at every
tick). Refused with InputError: controllers without a linear form (anything but position
'pid'/'pi', speed 'pi'), a plant whose right-hand side is not continuous at the operating
point, and a clearance-joint linkage with a hinge open at the operating point (no load holds
it in contact: it passes no force to a small signal, and the rudder would be loose). The
bench (linkage, compliance, anchorage, shaft, load motor) under a standing load, linearised
about the run's settled state (``at_s``), matches the simulation as the lumped plants do
(tests/test_linear.py); the nominal bench carries no standing load, and is refused.
"""

from collections.abc import Sequence
from pathlib import Path

import control

from .arguments import flag, number, strings
from .config import RPM
from .control import pid
from .control.continuous import current_loop, pade_delay, pid_law, with_rates
from .control.pid import PositionPID, SpeedPI
from .discrete_loop import tick_map
from .errors import InputError
from .plant import actuator as A
from .scenarios.loader import as_scenario
from .scenarios.schema import Scenario
from .sim.setup import plant_facts
from .small_signal import (
    READINGS,
    check_hinges_loaded,
    operating_point,
    plant_model,
    small_signal_plant,
    state_at,
)

GAPS = ("closed", "as is")
KINDS = ("closed", "open", "plant")
PORT_INPUTS = ("reference", "rod_force_N")


def linearize(
    scenario: "Scenario | str | Path",
    *,
    label: str | None = None,
    controllers: Sequence[str] = (),
    settings: Sequence[str] = (),
    operating_speed_rpm: float = 0.0,
    at_s: float | None = None,
    gaps: str = "closed",
    friction: bool = False,
    kind: str = "closed",
    broken_at: str | None = None,
    discrete: bool = False,
    input: str = "reference",
    output: str | None = None,
) -> control.StateSpace:
    """The loop of ``scenario`` as a continuous-time state-space model (module docstring).

    Parameters
    ----------
    scenario : a validated Scenario, or a shipped scenario's name or a TOML file's path, read
        with ``label``, ``controllers`` and ``settings`` as ``emasim run`` reads ``--label``,
        ``--controller`` and ``--set``; a comparison's name needs a label or controllers (its
        sets are different loops).
    operating_speed_rpm : the steady motor speed w0 to linearise about (id = 0).
    at_s : linearise about the state the scenario's run reaches at this time instead.
    gaps : "closed" (each play closed, in loaded contact) or "as is".
    friction : linearise the friction at the operating point (default: dropped).
    kind : "closed", "open" or "plant".
    broken_at : where kind="open" cuts: "position" or "speed" (the inner loop, the outer one
        closed); default the outermost feedback.
    discrete : the closed loop at the control rate instead (emasim.discrete_loop), from the
        reference or the rod force (``input``), to the outermost loop's reading.
    input : the closed loop's input: "reference" (the position or speed reference) or
        "rod_force_N" (a rod force, N, positive opposing extension, the references held: the
        loop's compliance x/F for the position output; held over each tick if discrete).
    output : the closed loop's output, one of the plant's readings: "id_A", "iq_A",
        "motor_speed_rad_s" or (in a position loop) "measured_position_m"; default the one
        the outermost loop closes on.

    Returns
    -------
    control.StateSpace. "closed", one input and one output: for a position reference, from
    ``position_ref_m`` (m) to ``measured_position_m`` (m: x_L - x_h on the rod sensor, the rod
    position of the rudder encoder's angle, K theta_m on the motor encoder); for a speed
    reference, from ``speed_ref_rad_s`` to ``motor_speed_rad_s`` (rad/s); with ``input`` and
    ``output``, from that input to that reading. "open": from the fed-back reading to the
    plant's (same unit). "plant": (vd, vq, rod_force_N) -> (id_A, iq_A, motor_speed_rad_s,
    measured_position_m). Its plant states are named as the simulation's.

    Raises
    ------
    InputError : a controller without a linear form, an option out of its range, or a plant
    not continuous at the operating point.
    """
    named = not isinstance(scenario, Scenario)
    controllers = strings("linearize: controllers", controllers)
    settings = strings("linearize: settings", settings)
    friction = flag("linearize: friction", friction)
    discrete = flag("linearize: discrete", discrete)
    scenario = as_scenario(scenario, label, controllers, settings, "linearize")
    if named and scenario.compare:
        sets = ", ".join(entry.label for entry in scenario.compare)
        raise InputError(f"linearize: {scenario.name} compares {sets}: choose one with label=")
    _refuse(scenario, gaps, kind, at_s)
    _refuse_ports(scenario, kind, discrete, input, output)
    max_rpm = scenario.plant.motor.max_speed_rpm
    operating_speed_rpm = number("linearize: operating_speed_rpm", operating_speed_rpm,
                                 -max_rpm, max_rpm)  # fmt: skip
    if broken_at is not None and kind != "open":
        raise InputError(
            f"linearize: broken_at cuts the open loop; give kind='open' or leave it out "
            f"(kind={kind!r})"
        )
    if broken_at not in (None, "speed", "position") or (
        broken_at == "position" and scenario.controllers.position is None
    ):
        cuts = "speed or position" if scenario.controllers.position else "speed (no position loop)"
        raise InputError(f"linearize: broken_at must be {cuts}, got {broken_at!r}")
    if discrete:
        _refuse_discrete(scenario, kind, input)
    setup = scenario.setup()
    p = small_signal_plant(setup.plant, gaps, friction)
    position = scenario.controllers.position is not None
    t0 = 0.0 if at_s is None else at_s
    x0, u0 = (  # the steady state of the plant as it is (its gaps open), its friction dropped
        operating_point(
            setup, small_signal_plant(setup.plant, "as is", friction), operating_speed_rpm * RPM
        )
        if at_s is None
        else state_at(setup, at_s)
    )
    if scenario.plant.linkage is not None:
        check_hinges_loaded(setup, p, x0, u0, t0)
    if discrete:
        return tick_map(scenario, setup, p, x0, at_s, load=input == "rod_force_N")
    plant = plant_model(setup, p, x0, u0, t0, position)
    if kind == "plant":
        return plant
    facts, ts = plant_facts(scenario.plant), scenario.solver.sample_period_s
    c = scenario.controllers
    w0, iq0 = x0[A.X_WM], x0[A.X_IQ]
    delay_s = scenario.loop.computation_delay_s + 0.5 * ts
    blocks = [
        plant,
        current_loop(c.current.build(facts, ts).params, w0, iq0),
        pade_delay(delay_s, "d"),
        pade_delay(delay_s, "q"),
    ]
    broken = broken_at or ("position" if position else "speed")  # the feedback kind="open" cuts
    cut = {"speed": "motor_speed_rad_s", "position": "measured_position_m"}[broken]
    fed = {
        name: f"{name}_fed_back" if kind == "open" and name == cut else name for name in READINGS
    }
    blocks.append(
        pid_law(
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
            pid_law(law, "position_ref", fed["measured_position_m"], "speed_ref", "position_pid")
        )
        references = ["position_ref", "position_ref_rate", "position_ref_accel"]
        reference = "position_ref_m"
    else:
        references = ["speed_ref", "speed_ref_rate"]
        reference = "speed_ref_rad_s"
    output = output or READINGS[len(plant.output_labels) - 1]
    ignore_inputs = ["speed_ref_accel"]  # the engine gives the speed loop no acceleration
    if kind == "open":
        ignore_inputs += references + ["rod_force_N"]
        references, output = [fed[cut]], cut
    elif input == "rod_force_N":  # the references held
        ignore_inputs += references
        references, reference = ["rod_force_N"], "rod_force_N"
    else:
        ignore_inputs.append("rod_force_N")
    closed = control.interconnect(
        blocks,
        inplist=references,
        outlist=[output],
        ignore_inputs=ignore_inputs,
        ignore_outputs=["iq_ref_rate"],  # nor the current loop a rate
    )
    if kind == "open":  # negative feedback: the closed loop is L / (1 + L)
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
    states = closed.state_labels
    if reference != "rod_force_N":
        try:
            closed = control.ss(*with_rates(closed))
        except ArithmeticError as err:
            raise InputError(f"linearize: output={output!r}: {err}; choose another output") from err
    return control.ss(
        closed.A,
        closed.B,
        closed.C,
        closed.D,
        inputs=[reference],
        outputs=[output],
        states=states,
        name=f"{scenario.name}-linear",
    )


def _refuse(scenario: Scenario, gaps: str, kind: str, at_s: float | None) -> None:
    """InputError, one line, for an option out of range or a controller without a linear form."""
    if gaps not in GAPS:
        raise InputError(f"linearize: gaps must be one of {', '.join(GAPS)}, got {gaps!r}")
    if kind not in KINDS:
        raise InputError(f"linearize: kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if at_s is not None:
        number("linearize: at_s", at_s, 0.0, scenario.duration_s)
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


def _refuse_ports(scenario, kind: str, discrete: bool, input: str, output: str | None) -> None:
    """InputError for an input or output the model asked for cannot have: they choose the
    continuous closed loop's ports (the plant has all of them, the open loop its cut)."""
    if input not in PORT_INPUTS:
        raise InputError(f"linearize: input must be one of {', '.join(PORT_INPUTS)}, got {input!r}")
    outputs = READINGS if scenario.controllers.position is not None else READINGS[:3]
    if output is not None and output not in outputs:
        raise InputError(f"linearize: output must be one of {', '.join(outputs)}, got {output!r}")
    chosen = input != "reference" or output is not None
    if chosen and kind != "closed":
        raise InputError(
            f"linearize: input and output choose the closed loop's ports; kind={kind!r} has "
            "its own (leave them out)"
        )
    if discrete and output is not None:
        raise InputError(
            "linearize: discrete=True gives the reading the outermost loop closes on; leave "
            "output out (input may be reference or rod_force_N)"
        )


def _refuse_discrete(scenario: Scenario, kind: str, input: str) -> None:
    """InputError for what the tick's Jacobian does not give: another loop than the closed
    one, and from the reference a feed-forward, which reads the reference's rates (not an
    input of the map; from the rod force the reference is held, its rates zero)."""
    if kind != "closed":
        raise InputError(f"linearize: discrete=True gives the closed loop only, got kind={kind!r}")
    if input == "rod_force_N":
        return
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
