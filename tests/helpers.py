"""Shared builders for the plant-level validation tests (a plain module, not a conftest).

Everything is built by hand from the public pieces (PlantParams, the packed parameter array,
the controller configs and :class:`emasim.sim.setup.Setup`) so the tests do not depend on a
scenario layer.
"""

import importlib.util
import math
from pathlib import Path

import numba as nb
import numpy as np

from emasim.control.current import CurrentPI
from emasim.control.pid import SpeedPI
from emasim.control.slot import CONTROLLER_SIG, Compiled, PlantFacts
from emasim.interface import O_RATE, O_VALUE
from emasim.plant import actuator as A
from emasim.plant.parameters import PlantParams
from emasim.plant.presets import sea805, sea805_stand
from emasim.signals import ZERO, Step, encode
from emasim.sim.core import new_workspace
from emasim.sim.engine import plant_step
from emasim.sim.setup import Setup, plant_facts

facts_of = plant_facts  # what a controller design may know of a plant

RPM = math.pi / 30.0  # rad/s per rpm
# Not a speed check: the one bound on a child process or a cluster's start that stops a hang,
# far beyond any run here (a cold numba compile on a loaded machine included); a slow machine
# never fails a test. Speed is measured in benchmarks/, as ratios and real-time factors.
HANG_GUARD_S = 1800


def frictionless_sea805(**packed_overrides) -> tuple[PlantParams, np.ndarray]:
    """The sea805 preset with friction model "none"; returns (params, packed SI array).

    ``packed_overrides`` maps parameter index constants' names without the ``P_`` prefix
    (e.g. ``B=0.0``, ``ETA=1.0``) to values written into the packed array.
    """
    plant = sea805()
    plant.friction.model = "none"
    p = plant.pack()
    for name, value in packed_overrides.items():
        p[getattr(A, f"P_{name}")] = value
    return plant, p


@nb.njit(CONTROLLER_SIG)
def zero_current_command(state, params, meas, ref, ts, out):
    """A speed "controller" that always asks for iq* = 0 (an electrically inert motor)."""
    out[O_VALUE] = 0.0
    out[O_RATE] = 0.0


def inert_speed_controller() -> Compiled:
    """:func:`zero_current_command` ready for the engine."""
    return Compiled(zero_current_command, np.zeros(1), np.zeros(1))


def speed_setup(
    p: np.ndarray,
    facts: PlantFacts,
    *,
    ts: float,
    duration_s: float,
    substeps: int = 4,
    speed_rpm: float = 0.0,
    motor_load: np.ndarray = ZERO,
    rod_load: np.ndarray = ZERO,
    speed: Compiled | None = None,
    current_facts: PlantFacts | None = None,
    x0: np.ndarray | None = None,
    record_every: int = 1,
) -> Setup:
    """A speed-loop run: step to ``speed_rpm`` at t = 0, SpeedPI unless ``speed`` is given.

    ``current_facts`` (default ``facts``) is what the current loop is designed from, so a test
    can give the controller a different idea of the plant than the plant itself.
    """
    return Setup(
        plant=p,
        sample_period_s=ts,
        substeps=substeps,
        duration_s=duration_s,
        reference=encode([Step(time_s=0.0, final=speed_rpm)], RPM),
        motor_load=motor_load,
        rod_load=rod_load,
        speed=speed if speed is not None else SpeedPI().build(facts, ts),
        current=CurrentPI().build(current_facts or facts, ts),
        record_every=record_every,
        x0=np.zeros(A.N_STATE) if x0 is None else x0,
    )


def step_signal(time_s: float, value: float) -> np.ndarray:
    """Encoded step from 0 to ``value`` (SI) at ``time_s``."""
    return encode([Step(time_s=time_s, final=value)])


def integrate_plant(plant, x0, duration_s, h, rudder_load=ZERO):
    """The plant (a PlantParams) from state x0 under plant_step, zero voltages and loads but
    ``rudder_load``, in steps of h; returns (t, states), the states row by row."""
    p = plant.pack()
    x = x0.copy()
    work = new_workspace()
    n = round(duration_s / h)
    states = np.empty((n + 1, A.N_STATE))
    states[0] = x
    for j in range(n):
        plant_step(j * h, x, 0.0, 0.0, p, ZERO, ZERO, rudder_load, h, work)
        states[j + 1] = x
    return h * np.arange(n + 1), states


def relative_error(simulated, expected):
    """Largest deviation over the largest expected magnitude."""
    return np.max(np.abs(simulated - expected)) / np.max(np.abs(expected))


def module_at(relative: str):
    """The Python file at ``relative`` (to the repository root) as a module: ``benchmarks/``
    and ``docs/`` are not packages."""
    path = Path(__file__).parents[1] / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def conservative_stand(width_mm: float, gap_stiffness_N_per_m: float) -> PlantParams:
    """sea805-stand with nothing that dissipates: no friction, no motor or load damping, a
    lossless screw, an undamped gap of ``width_mm`` and the given stiffness."""
    plant = sea805_stand()
    plant.friction.model = "none"
    plant.motor.viscous_Nms_per_rad = 0.0
    plant.drivetrain.gear_efficiency = plant.drivetrain.screw_efficiency = 1.0
    plant.backlash.width_mm = width_mm
    plant.backlash.stiffness_N_per_m = gap_stiffness_N_per_m
    plant.backlash.damping_ratio = 0.0
    plant.load.viscous_Ns_per_m = 0.0
    return plant


def refused_in_one_line(args: list[str], match: str) -> None:
    """``emasim ARGS`` exits with code 2 and prints one line holding ``match``, no traceback."""
    from typer.testing import CliRunner

    from emasim.cli import app

    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    assert match in lines[0], lines[0]
