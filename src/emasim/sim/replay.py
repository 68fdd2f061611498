"""The plant replay of the accuracy contract: the plant alone, on the inputs a run applied.

A closed-loop trace never converges in the integration step: the controllers act on encoder
counts, so any change of the arithmetic flips a count somewhere and the run parts. What the
scheme must get right is the plant's response to the inputs it is given. So the contract
(docs/model.md, "The accuracy contract") holds the plant alone to a tight reference:

1. :func:`applied_inputs` runs the closed loop once (the shipped scheme) and keeps the voltages
   the drive applied at every tick and the plant's state at every tick; a voltage computed at
   tick k acts from k Ts + Td on, the previous one before (the computation delay Td);
2. :func:`replay_scheme` integrates the plant alone on those voltages and the scenario's loads
   with the engine's scheme (emasim.plant.integrator.tick: RK4 sub-steps, the bristle split off
   and updated exactly) at any sub-step count. It is the engine itself, its current loop's law
   replaced by one that plays the voltages back (:func:`playback`): what the other laws and the
   sensors compute acts on nothing;
3. :func:`replay_reference` integrates the same with ``scipy.integrate.solve_ivp`` (DOP853 at
   rtol 1e-10, the bristle an ordinary state), restarted wherever the voltage switches;
4. :func:`contract_errors` compares the two at every tick: each state's largest error over the
   window, relative to its range over the closed-loop run (id and iq on the larger of their two
   ranges, since id stays near zero; over a short window a state such as the bristle's barely
   moves, so its own range there would be no scale), against :data:`SENSED_TOLERANCE` for what
   a sensor reads or a controller acts on (:data:`SENSED`) and :data:`INTERNAL_TOLERANCE` for
   every other state (the linkage's internal rates spike at hinge impacts).

A replay can start inside the run (:meth:`AppliedInputs.window`): from the state the run had
there, with the voltage it was applying. The replay at the shipped sub-step count repeats the
closed-loop run's states bit for bit (the same scheme on the same inputs; tests/test_replay.py).
"""

from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import solve_ivp

from ..control.slot import Compiled, controller_law
from ..interface import O_UD, O_UQ
from ..plant import actuator as A
from .core import D_UD, D_UQ
from .engine import EngineRun
from .reference import _rhs
from .setup import Setup

SENSED = ("id_A", "iq_A", "motor_angle_rad", "motor_speed_rad_s", "actuator_position_m",
          "linkage_rudder_angle_rad")  # fmt: skip
"""The states a sensor reads or a controller acts on: the currents, the motor's angle and
speed, the rod position, the rudder angle (the lumped plant's rudder angle is the rod
position's, through the rigid arm)."""
SENSED_TOLERANCE = 1e-3
"""Of a sensed state's range: on bench-step's 4.72 deg rudder step, 0.0047 deg, about a
nineteenth of the rudder encoder's count (360/4096 deg)."""
INTERNAL_TOLERANCE = 1e-2  # of every other state's range
CURRENTS = ("id_A", "iq_A")  # judged on the larger of their two ranges
REFERENCE_RTOL = 1e-10


@dataclass(frozen=True)
class AppliedInputs:
    """What a closed-loop run applied to its plant, tick by tick, from ``setup.x0``: ``u_d``,
    ``u_q`` (V, computed at tick k, acting from k Ts + Td on, Td = ``delay_s``), ``before``
    (the voltages acting before the first tick: 0 V at a run's start), the plant's state at
    every tick (``states``, ticks x N_STATE, the first row ``setup.x0``) and each state's range
    over the whole run (``ranges``, :func:`state_ranges`; a window keeps its run's)."""

    setup: Setup
    u_d: np.ndarray
    u_q: np.ndarray
    states: np.ndarray
    delay_s: float
    ranges: np.ndarray
    before: tuple[float, float] = (0.0, 0.0)

    @property
    def n_ticks(self) -> int:
        return self.u_d.size

    def window(self, start_s: float, end_s: float) -> "AppliedInputs":
        """The ticks from ``start_s`` to ``end_s``, to replay from the state the run had at
        ``start_s``, with the voltages then acting."""
        ts = self.setup.sample_period_s
        k0, k1 = round(start_s / ts), round(end_s / ts)
        if not 0 <= k0 < k1 <= self.n_ticks:
            raise ValueError(f"window {start_s:g} .. {end_s:g} s: outside the run's ticks")
        before = self.before if k0 == 0 else (self.u_d[k0 - 1], self.u_q[k0 - 1])
        return replace(
            self,
            setup=self.setup.with_(x0=self.states[k0].copy(), duration_s=(k1 - k0) * ts),
            u_d=self.u_d[k0:k1],
            u_q=self.u_q[k0:k1],
            states=self.states[k0:k1],
            before=(float(before[0]), float(before[1])),
        )


def applied_inputs(setup: Setup, duration_s: float | None = None) -> AppliedInputs:
    """Run ``setup`` (over ``duration_s``, default its own) on the engine, recording every
    tick, and keep the voltages it applied and its states (module docstring, step 1)."""
    run_setup = setup.with_(
        duration_s=setup.duration_s if duration_s is None else duration_s,
        record_every=1,
        record_signals=("ud_V", "uq_V", *A.STATE_NAMES),
    )
    trace = _run(run_setup)
    states = _states(trace, run_setup)
    return AppliedInputs(
        setup=run_setup,
        u_d=np.ascontiguousarray(trace["ud_V"]),
        u_q=np.ascontiguousarray(trace["uq_V"]),
        states=states,
        delay_s=run_setup.delay_substeps * run_setup.step_s,
        ranges=state_ranges(states),
    )


def _run(setup: Setup, before: tuple[float, float] = (0.0, 0.0)):
    """The engine's trace of ``setup``, the voltages ``before`` acting until the first tick's
    delay has passed (the drive's record of the last voltage applied)."""
    engine = EngineRun(setup, stream=False)
    engine.run.data.drive[D_UD], engine.run.data.drive[D_UQ] = before
    engine.advance(setup.n_ticks)
    return engine.result()


def _states(trace, setup: Setup) -> np.ndarray:
    """Every state at every tick (ticks x N_STATE) of an every-tick trace; an absent element's
    stay at their initial values (idle)."""
    states = np.tile(setup.x0, (setup.n_ticks, 1))
    for i, name in enumerate(A.STATE_NAMES):
        if name in trace.columns:
            states[:, i] = trace[name]
    return states


def _delay_substeps(inputs: AppliedInputs, substeps: int) -> int:
    """The computation delay as a whole number of sub-steps of Ts / ``substeps``."""
    exact = inputs.delay_s * substeps / inputs.setup.sample_period_s
    whole = round(exact)
    if abs(exact - whole) > 1e-9 * max(1.0, exact):
        raise ValueError(
            f"the delay {inputs.delay_s:g} s is no whole number of {substeps} sub-steps a tick"
        )
    return whole


@controller_law
def playback(state, params, meas, ref, ts, out):
    """The current loop's law of a replay: the voltages of tick k = state[0] from ``params``
    (every tick's u_d, then every tick's u_q), whatever the measurements."""
    k = int(state[0])
    ticks = params.size // 2
    out[O_UD] = params[k]
    out[O_UQ] = params[ticks + k]
    state[0] = k + 1.0


def replay_scheme(inputs: AppliedInputs, substeps: int) -> np.ndarray:
    """The plant alone on ``inputs`` by the engine's scheme at ``substeps`` RK4 sub-steps a
    tick, on the engine itself (module docstring, step 2): its state at every tick."""
    current = Compiled(playback, np.concatenate([inputs.u_d, inputs.u_q]), np.zeros(1),
                       commands="voltage")  # fmt: skip
    setup = inputs.setup.with_(
        current=current, substeps=substeps, delay_substeps=_delay_substeps(inputs, substeps)
    )
    return _states(_run(setup, inputs.before), setup)


def replay_reference(inputs: AppliedInputs, method: str = "DOP853") -> np.ndarray:
    """The plant alone on ``inputs`` by ``solve_ivp(method, rtol=1e-10)`` (the bristle an
    ordinary state, the states' absolute tolerances their elements'), restarted where the
    voltage switches: its state at every tick."""
    model = inputs.setup.start().model
    ts, td = inputs.setup.sample_period_s, inputs.delay_s
    x = inputs.setup.x0.astype(np.float64)
    states = np.empty_like(inputs.states)
    atol = A.PLANT.atol()
    acting = inputs.before
    for k in range(inputs.n_ticks):
        states[k] = x
        t = k * ts
        new = (inputs.u_d[k], inputs.u_q[k])
        for start, end, (u_d, u_q) in ((t, t + td, acting), (t + td, t + ts, new)):
            if end - start <= 1e-9 * ts:
                continue
            sol = solve_ivp(_rhs, (start, end), x, method=method, rtol=REFERENCE_RTOL,
                            atol=atol, args=(u_d, u_q, model, t + ts))  # fmt: skip
            if not sol.success:
                raise RuntimeError(f"reference solver failed at t = {start:g} s: {sol.message}")
            x = sol.y[:, -1]
        acting = new
    return states


def state_ranges(states: np.ndarray) -> np.ndarray:
    """Each state's range over ``states`` (max - min), the currents' the larger of the two."""
    ranges = np.ptp(states, axis=0)
    currents = [A.STATE_NAMES.index(name) for name in CURRENTS]
    ranges[currents] = ranges[currents].max()
    return ranges


def contract_errors(inputs: AppliedInputs, reference: np.ndarray, replayed: np.ndarray) -> dict:
    """Each moving state's largest error over the window relative to its range over the run
    (``inputs.ranges``), by name; a state that stayed still has no range and is left out."""
    errors = np.max(np.abs(replayed - reference), axis=0)
    active = A.STATE_NAMES[: A.active_states(inputs.setup.plant)]
    return {
        name: float(errors[i] / inputs.ranges[i])
        for i, name in enumerate(active)
        if inputs.ranges[i] > 0.0
    }


def tolerance(name: str) -> float:
    """The contract's bound on a state's relative error (module docstring, step 4)."""
    return SENSED_TOLERANCE if name in SENSED else INTERNAL_TOLERANCE


def breaches(errors: dict) -> dict:
    """The states of ``errors`` (:func:`contract_errors`) beyond their bound."""
    return {name: error for name, error in errors.items() if error > tolerance(name)}
