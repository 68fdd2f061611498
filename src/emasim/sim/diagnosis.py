"""Why a run diverged: the likely cause, for the one-line message that stops it.

The checks, in order:

1. **A mode too fast for the sub-step.** Classic RK4 is stable on an undamped oscillator only
   while omega h < 2 sqrt(2) (about 2.83) and on a decaying mode while lambda h < 2.78. Each
   present element declares its natural modes (emasim.plant.element.Element.modes): the
   backlash contact between the motor seen at the nut (J / K^2) and the body beyond the gap
   (the compliance's node where the plant has one, else the load), the LuGre bristles,
   sqrt(sigma0 / J), the stator, R / min(Ld, Lq), each spring-damper's two-body rate (the
   screw's compliance, the anchorage, the rudder shaft), the rod's end stops, sqrt(k / m_rod),
   and the load motor's torque loop, 1/tau.
2. **A load beyond the drive.** The peak external load seen at the rod (rod force, motor
   torque / K, rudder torque through the linkage's lever at mid stroke or the lumped arm)
   against the stall force of the drive,
   F_stall = kt I_max eta / K, kt = 1.5 np psi_f.
3. **A limit that was hit.** The state that left its bound is a speed or a current: it ran
   beyond what the drive allows (the bounds are far outside any real motion); or the rod's
   position (or the motor's angle): a runaway, or a run without end stops that drove the rod
   one way for FAR_RUNAWAY strokes (a speed loop holding its speed for a long run).

Otherwise the likely cause is the controller: gains that make the sampled loop unstable.
"""

import numpy as np

from ..plant import actuator as A
from ..plant.element import FAR_RUNAWAY
from ..plant.elements import linkage as L
from ..plant.elements.motor import torque_constant
from ..signals import signal_value

SAFE_FRACTION = 0.5  # suggest a step with this margin below the limit
LOAD_SAMPLES = 2001


def fastest_modes(plant: np.ndarray) -> list[tuple[str, float, float]]:
    """(element, rate in rad/s or 1/s, the largest stable h) of the plant's stiff modes, as
    each present element declares them (emasim.plant.element.Element.modes)."""
    return [(name, rate, limit / rate) for name, rate, limit in A.PLANT.modes(plant)]


def peak_rod_load_N(setup) -> float:
    """The largest |external load| seen at the rod over the run (N)."""
    plant = setup.plant
    times = np.linspace(0.0, setup.duration_s, LOAD_SAMPLES)
    lever = 1.0 / plant[A.P_ARM]
    if plant[A.P_LOAD_MODEL] == A.LOAD_LINKAGE:
        q = plant[A.P_LINK : A.P_LINK_END]
        ds = 1e-6
        lever = abs(L.rigid_pose(ds, q)[L.TD] - L.rigid_pose(-ds, q)[L.TD]) / (2 * ds)
    loads = [
        abs(signal_value(setup.rod_load, t))
        + abs(signal_value(setup.motor_load, t)) / plant[A.P_K]
        + abs(signal_value(setup.rudder_load, t)) * lever
        for t in times
    ]
    return max(loads)


def stall_force_N(setup) -> float | None:
    """F_stall = kt I_max eta / K (N), or None when the Setup does not know the drive."""
    if setup.facts is None:
        return None
    plant = setup.plant
    kt = torque_constant(plant[A.P_NP], plant[A.P_PSI])
    return kt * setup.facts.max_current_A * plant[A.P_ETA] / plant[A.P_K]


def likely_cause(setup, state_index: int) -> str:
    """One sentence naming the likely cause of a divergence (module docstring)."""
    h = setup.step_s
    too_fast = [
        (name, rate, h_max) for name, rate, h_max in fastest_modes(setup.plant) if h > h_max
    ]
    if too_fast:
        name, rate, h_max = max(too_fast, key=lambda mode: mode[1])
        return (
            f"the sub-step solver.step_s = {h:g} s is too large for {name} (a {rate:.3g} 1/s "
            f"mode; RK4 needs step_s < {h_max:.3g} s): use step_s <= "
            f"{SAFE_FRACTION * h_max:.2g} s"
        )
    stall = stall_force_N(setup)
    load = peak_rod_load_N(setup)
    if stall is not None and load > stall:
        return (
            f"the load reaches {load:.4g} N at the rod, beyond the {stall:.4g} N the drive can "
            "hold at its current limit: the load overhauls the actuator"
        )
    name = A.STATE_NAMES[state_index]
    if state_index in (A.X_ID, A.X_IQ):
        return f"'{name}' ran far beyond the drive's current limit: check the current loop gains"
    if state_index in (A.X_WM, A.X_VL):
        return (
            f"'{name}' ran far beyond the drive's speed: the loop ran away; check the gains "
            "and the sign of any user controller"
        )
    if state_index in (A.X_THETA, A.X_XL):
        return (
            f"'{name}' went {FAR_RUNAWAY:g} strokes from mid stroke: the loop ran away (check "
            "the gains and the sign of any user controller), or, on a plant without end stops, "
            "the run drove the rod one way that long (a speed held for a long run does: add "
            "the end stops or shorten the run)"
        )
    return "no stiff mode or load explains it: check the controller gains"
