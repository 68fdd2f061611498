"""Co-simulation of the drive and the linkage, loosely coupled at a communication step.

The paper coupled SIMULINK (drive and controllers) and ADAMS (the mechanism) this way. Every
communication step Tc:

1. the drive (the compiled engine, rod alone as its load) runs over [t, t + Tc] with the rod
   force the mechanism returned at t held, and the mechanism's states at t held in its state
   (its rudder encoder reads them);
2. the mechanism (emasim.sim.mechanism: the linkage, and the rudder shaft's disk and the load
   motor when the plant has them) runs over the same interval with its rod driven at the
   drive's mean rod velocity, (s(t + Tc) - s(t)) / Tc, so both sides agree on the rod
   position at every communication point;
3. the mechanism returns the rudder angle and the rod's load force.

With ``solver.mechanism_fmu`` set, an FMI 2.0 FMU loaded with fmpy takes the mechanism's place
(:class:`emasim.sim.fmi.FmuMechanism`): the master sets its rod position and velocity, steps it
over the same interval and reads back the rudder angle and the rod force. Loading an FMU runs
the code inside it, so it needs ``trust_fmu=True`` (the command line's ``--trust-fmu``).

The force reaches the drive one communication step late, which is what limits this scheme. In
the compiled loop the two are solved together (plant.actuator with the linkage): the reference
that co-simulation results are measured against as Tc grows.
"""

import time

import numpy as np

from ..errors import InputError
from ..plant import actuator as A
from ..plant.elements import linkage as L
from ..signals import ZERO, Constant, encode, signal_value
from .engine import EngineRun
from .mechanism import advance_rudder_side

ROD_FORCE_VALUE = 3  # index of the held value in a one-term constant signal


def cosimulate(scenario, communication_step_s: float, trust_fmu: bool = False):
    """Run a scenario whose plant has the linkage as a drive/mechanism co-simulation.

    The drive runs the whole plant state with the rudder side held (emasim.plant.actuator
    LOAD_HELD): the mechanism's states, written into it at every exchange, are what the drive's
    sensors read (a rudder encoder included) and what its trace records, held between
    communication points. ``trust_fmu`` allows the scenario's ``solver.mechanism_fmu`` to be
    loaded (see :func:`check_fmu_trust`); an FMU mechanism is the linkage alone.
    """
    check_fmu_trust(scenario, trust_fmu)
    _check_cosim(scenario, communication_step_s)
    linked = scenario.setup().with_(record_signals=None)  # every column, as the run had
    ts = linked.sample_period_s
    ticks = round(communication_step_s / ts)
    rod_force = encode([Constant(value=0.0)])
    drive = EngineRun(
        linked.with_(
            plant=_rudder_side_held(linked.plant),
            rod_load=rod_force,
            rudder_load=ZERO,  # the mechanism carries it
        )
    )
    mechanism = linked.x0.copy()  # its rudder side (rows X_MECHANISM..) is the mechanism's
    y = mechanism[A.X_LINK : A.X_LINK_END]  # a view: what an FMU mechanism reads and writes
    hinges = np.zeros((L.N_HINGES, 2))
    n = linked.n_ticks
    start = time.perf_counter()
    fmu = _mechanism_fmu(scenario, linked.step_s, drive.x[A.X_XL], y)  # None: built in
    try:
        for k0 in range(0, n, ticks):
            k1 = min(n, k0 + ticks)
            drive.x[A.X_MECHANISM :] = mechanism[A.X_MECHANISM :]  # held over this step
            s0 = drive.x[A.X_XL]
            drive.advance(k1)
            s1 = drive.x[A.X_XL]
            span = (k1 - k0) * ts
            v = (s1 - s0) / span
            substeps = linked.substeps * (k1 - k0)  # the drive's sub-step, h, on both sides
            # the rudder load (opposing positive deflection) held at the step's midpoint
            load = signal_value(linked.rudder_load, (k0 * ts) + 0.5 * span)
            if fmu is None:
                axial = advance_rudder_side(
                    mechanism, s0, v, span, substeps, load, linked.plant, hinges
                )
            else:
                axial = fmu.advance(y, k0 * ts, s0, v, span, load)
            rod_force[ROD_FORCE_VALUE] = -axial  # the rod load opposes the linkage's push
    finally:
        if fmu is not None:
            fmu.close()
    result = drive.result()
    result.meta["simulation_wall_s"] = time.perf_counter() - start  # drive and mechanism
    result.meta["communication_step_s"] = communication_step_s
    return result


def check_runnable(scenario, trust_fmu: bool) -> None:
    """Every rule a run of ``scenario`` checks, checked before anything is compiled or run: an
    FMU needs ``trust_fmu`` (:func:`check_fmu_trust`), and a co-simulation
    (``solver.communication_step_s``) a plant it can split. InputError names the first."""
    check_fmu_trust(scenario, trust_fmu)
    if scenario.solver.communication_step_s is not None:
        _check_cosim(scenario, scenario.solver.communication_step_s)


def _check_cosim(scenario, communication_step_s: float) -> None:
    """The co-simulation's rules on the scenario (cheap: nothing compiled)."""
    plant = scenario.plant
    if plant.linkage is None:
        raise InputError("solver.communication_step_s: co-simulation needs a plant with a linkage")
    if scenario.load.rod_force_N:
        raise InputError("co-simulation takes motor_torque_Nm and rudder_torque_Nm loads only")
    if scenario.solver.mechanism_fmu is not None and (plant.rudder_shaft or plant.load_motor):
        raise InputError(
            "solver.mechanism_fmu: an FMU mechanism is the linkage alone; remove "
            "plant.rudder_shaft and plant.load_motor, or use the built-in mechanism"
        )
    ts = scenario.solver.sample_period_s
    ticks = round(communication_step_s / ts)
    if ticks < 1 or abs(ticks * ts - communication_step_s) > 1e-9 * communication_step_s:
        raise InputError(
            f"solver.communication_step_s ({communication_step_s:g} s) must be a whole multiple "
            f"of solver.sample_period_s ({ts:g} s)"
        )


def check_fmu_trust(scenario, trust_fmu: bool) -> None:
    """Refuse a scenario that would load an external FMU unless the caller trusts it: an FMU
    is a shared library (and, for pythonfmu, Python code) that runs inside this process."""
    path = scenario.solver.mechanism_fmu
    if path is not None and not trust_fmu:
        raise InputError(
            f"solver.mechanism_fmu: loading {path} runs the code inside it; "
            "pass --trust-fmu (trust_fmu=True in Python) only for an FMU you trust"
        )


def _mechanism_fmu(scenario, step_s: float, rod_position_m: float, y: np.ndarray):
    """The FMU named by solver.mechanism_fmu (emasim.sim.fmi.FmuMechanism), its initial
    linkage states written into y; None for the built-in mechanism."""
    if scenario.solver.mechanism_fmu is None:
        return None
    from .fmi import FmuMechanism

    fmu = FmuMechanism(scenario.solver.mechanism_fmu, step_s, float(rod_position_m))
    fmu.read(y)
    return fmu


def _rudder_side_held(packed: np.ndarray) -> np.ndarray:
    """The drive's parameters: those of the coupled plant (the rod alone as its load), with the
    rudder side held (the mechanism carries it)."""
    packed = packed.copy()
    packed[A.P_LOAD_MODEL] = A.LOAD_HELD
    return packed
