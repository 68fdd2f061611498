"""Co-simulation of the drive and the linkage, loosely coupled at a communication step.

The paper coupled SIMULINK (drive and controllers) and ADAMS (the mechanism) this way. Every
communication step Tc:

1. the drive (the compiled engine, rod alone as its load) runs over [t, t + Tc] with the rod
   force the mechanism returned at t held;
2. the mechanism (emasim.sim.mechanism) runs over the same interval with its rod driven at the
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
from ..plant import linkage as L
from ..signals import Constant, encode, signal_value
from .engine import EngineRun
from .mechanism import advance

ROD_FORCE_VALUE = 3  # index of the held value in a one-term constant signal


def cosimulate(scenario, communication_step_s: float, trust_fmu: bool = False):
    """Run a scenario whose plant has the linkage as a drive/mechanism co-simulation.

    Returns the drive's Result with the rudder angle and the linkage states replaced by the
    mechanism's, held between communication points. ``trust_fmu`` allows the scenario's
    ``solver.mechanism_fmu`` to be loaded (see :func:`check_fmu_trust`).
    """
    check_fmu_trust(scenario, trust_fmu)
    plant = scenario.plant
    if plant.linkage is None:
        raise InputError("solver.communication_step_s: co-simulation needs a plant with a linkage")
    if scenario.load.rod_force_N:
        raise InputError("co-simulation takes motor_torque_Nm and rudder_torque_Nm loads only")
    linked = scenario.setup().with_(record_signals=None)  # the mechanism fills every column
    ts = linked.sample_period_s
    ticks = round(communication_step_s / ts)
    if ticks < 1 or abs(ticks * ts - communication_step_s) > 1e-9 * communication_step_s:
        raise InputError(
            f"solver.communication_step_s ({communication_step_s:g} s) must be a whole multiple "
            f"of solver.sample_period_s ({ts:g} s)"
        )
    drive_plant = plant.model_copy(update={"linkage": None})
    rod_force = encode([Constant(value=0.0)])
    drive = EngineRun(
        linked.with_(
            plant=_rod_only(drive_plant.pack(), plant.linkage.rod_mass_kg),
            rod_load=rod_force,
            x0=drive_plant.initial_state(),
        ),
        keep_elements=("linkage",),
    )
    q = plant.linkage.pack()
    y = linked.x0[A.X_LINK : A.X_LINK_END].copy()
    hinges = np.zeros((L.N_HINGES, 2))
    n = linked.n_ticks
    held = np.zeros((n + 1, L.N_LINK))
    start = time.perf_counter()
    fmu = _mechanism_fmu(scenario, linked.step_s, drive.run.x[A.X_XL], y)  # None: built in
    try:
        for k0 in range(0, n, ticks):
            k1 = min(n, k0 + ticks)
            s0 = drive.run.x[A.X_XL]
            drive.advance(k1)
            held[k0:k1] = y  # what the drive saw of the mechanism over this step
            s1 = drive.run.x[A.X_XL]
            span = (k1 - k0) * ts
            substeps = linked.substeps * (k1 - k0)  # the drive's sub-step, h, on both sides
            # the rudder load (opposing positive deflection) held at the step's midpoint
            load = signal_value(linked.rudder_load, (k0 * ts) + 0.5 * span)
            if fmu is None:
                axial = advance(y, s0, (s1 - s0) / span, span, substeps, -load, q, hinges)
            else:
                axial = fmu.advance(y, k0 * ts, s0, (s1 - s0) / span, span, load)
            rod_force[ROD_FORCE_VALUE] = -axial  # the rod load opposes the linkage's push
    finally:
        if fmu is not None:
            fmu.close()
    result = drive.result()  # its linkage columns are filled from the mechanism below
    result.meta["simulation_wall_s"] = time.perf_counter() - start  # drive and mechanism
    rows = np.arange(result.data.shape[0]) * linked.record_every
    for i, name in enumerate(L.LINK_STATE_NAMES):
        result.data[:, result.columns.index(name)] = held[rows, i]
    result.data[:, result.columns.index("rudder_angle_rad")] = held[rows, L.TD]
    _mechanism_outputs(result, held[rows], linked.plant)
    result.meta["communication_step_s"] = communication_step_s
    return result


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


def _mechanism_outputs(result, linkage_states: np.ndarray, packed: np.ndarray) -> None:
    """Fill the rod force and hinge columns from the mechanism states held at each row."""
    first = result.columns.index(L.LINKAGE.outputs[0].name)
    x = np.zeros(A.N_STATE)
    position, velocity = result["actuator_position_m"], result["actuator_velocity_m_s"]
    for i, y in enumerate(linkage_states):
        x[A.X_XL], x[A.X_VL], x[A.X_LINK : A.X_LINK_END] = position[i], velocity[i], y
        A.linkage_outputs(x, packed, result.data[i, first : first + A.N_LINKAGE_OUTPUTS])


def _rod_only(packed: np.ndarray, rod_mass_kg: float) -> np.ndarray:
    """The drive's parameters with the rod alone as its load (the mechanism carries the rest)."""
    packed = packed.copy()
    packed[A.P_ML] = rod_mass_kg
    return packed
