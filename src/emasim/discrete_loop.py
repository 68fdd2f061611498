"""The closed loop at the control rate: the Jacobian of one tick of the compiled loop
(emasim.linear, ``discrete=True``)."""

import control
import numpy as np

from .plant import actuator as A
from .plant.sensors import ideal_table
from .scenarios.schema import Scenario
from .signals import KIND_CONSTANT
from .sim.core import D_UD, D_UQ
from .sim.engine import EngineRun, run_ticks
from .small_signal import (
    READINGS,
    ROD_FORCE_STEP_N,
    difference,
    less_rigid,
    moving_states,
    readings,
    rigid_motion,
    steps_for,
    with_states,
)

REFERENCE_STEP = {True: 1e-9, False: 1e-6}  # m of a position reference, rad/s of a speed one
START_TICKS = 2  # ticks run at the operating point before the map is taken (the laws start)


def _shifted(signal: np.ndarray, offset: float) -> np.ndarray:
    """An encoded signal (emasim.signals.encode) plus a constant ``offset``."""
    return np.concatenate([[signal[0] + 1.0], signal[1:], [KIND_CONSTANT, 1.0, offset]])


def tick_map(scenario: Scenario, setup, p, x0, at_s, load: bool = False) -> control.StateSpace:
    """The closed loop at the control rate: the Jacobian of one tick of the compiled loop
    (emasim.sim.engine.run_ticks: the sensors, the laws as compiled, the drive's limits, the
    computation delay and the RK4 sub-steps) in the plant's moving states, the slots' states
    and the voltage still applied during the delay, and in the reference's value or, with
    ``load``, in a rod force held over the tick (the engine reads the loads at each sub-step's
    midpoint: a constant over the tick), the reference held. Either input acts on the reading
    one tick later (no feed-through): the reference through the laws, the force through the
    plant.

    The operating point: the run's state at ``at_s``, or the steady state x0 held with the
    reference at its fed-back value, after START_TICKS ticks there (so that each law has made
    its first call). A speed loop's states are taken less the rigid motion, as in continuous
    time. The sensors are ideal; the reference's rates, which feed the feed-forwards, are not
    an input (its value steps, its rates stay). Laws that do not move
    or act (a slot's unused entries) are left out."""
    position = scenario.controllers.position is not None
    ideal = setup.with_(sensors=ideal_table())
    if at_s is None:
        y0 = readings(setup, p, x0)[3 if position else 2]
        start = ideal.with_(plant=p, x0=x0, reference=_shifted(np.array([0.0]), y0))
        k0 = START_TICKS
    else:
        start = ideal.with_(plant=p)
        k0 = max(START_TICKS, round(at_s / setup.sample_period_s))
    run = EngineRun(start)
    run.advance(k0)
    model, data, laws = run.run.model, run.run.data, run.run.laws
    states = moving_states(p)
    slots = [len(s) for s in data.slot_states]
    base = np.concatenate([data.x[states], *data.slot_states, data.drive[[D_UD, D_UQ]]])

    def tick(z, offset=0.0, force=0.0):
        x = with_states(data.x, states, z[: len(states)])
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
        shifted = model._replace(
            reference=_shifted(model.reference, offset),
            rod_load=_shifted(model.rod_load, force),
        )
        run_ticks(k0, k0 + 1, shifted, trial, *laws)
        return np.concatenate([trial.x[states], *trial.slot_states, trial.drive[[D_UD, D_UQ]]])

    names = [A.STATE_NAMES[i] for i in states]
    names += [
        f"{slot}_law_{i}"
        for slot, n in zip(("position", "speed", "current"), slots, strict=True)
        for i in range(n)
    ]
    names += ["vd_applied", "vq_applied"]
    steps = np.concatenate([steps_for(data.x, states), np.full(len(base) - len(states), 1e-6)])
    a = difference(tick, base, steps, names, names)
    if load:  # N, positive opposing extension (the right-hand side is affine in it)
        column, step, label = (lambda f: tick(base, force=f[0])), ROD_FORCE_STEP_N, "rod_force_N"
    else:
        column, step, label = (lambda r: tick(base, r[0])), REFERENCE_STEP[position], "reference"
    b = difference(column, np.zeros(1), np.array([step]), [label], names)
    c = np.zeros((1, len(base)))
    c[0, : len(states)] = difference(
        lambda z: readings(setup, p, with_states(data.x, states, z)),
        data.x[states],
        steps[: len(states)],
        names,
        list(READINGS),
    )[3 if position else 2]
    if not position:  # the speed loop never sees where the drive stands
        theta = states.index(A.X_THETA)
        r = rigid_motion(a - np.eye(len(base)), theta)
        a, b, c, names = less_rigid(a, b, c, r, theta, names)
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
        inputs=["rod_force_N" if load else labels[0]],
        outputs=[labels[1]],
        states=[names[i] for i in keep],
        name=f"{scenario.name}-discrete",
    )


def _acting(a: np.ndarray, c: np.ndarray) -> list[int]:
    """The states that act on another state or on the output (the others, a slot's unused
    entries, only hold or reset themselves)."""
    keep = list(range(a.shape[0]))
    while True:
        others = [i for i in keep if np.any(a[[j for j in keep if j != i], i]) or np.any(c[:, i])]
        if others == keep:
            return keep
        keep = others
