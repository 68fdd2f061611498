"""Run a scenario end to end: compile, simulate, attach scenario, metadata and metrics."""

import dataclasses
import datetime
import platform
from importlib.metadata import version

from .. import __version__
from ..analysis.report import ANALYSIS_COLUMNS, run_metrics, run_warnings, undefined_metrics
from ..sim.cosim import check_fmu_trust, cosimulate
from ..sim.engine import simulate
from ..sim.result import Result


def meta_of(scenario, wall_s: float) -> dict:
    """What a saved result needs to be regenerated and judged: versions, seed, timings."""
    return {
        "emasim_version": __version__,
        "seed": scenario.seed,
        "scenario": scenario.name,
        "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "numba": version("numba"),
        "simulation_wall_s": wall_s,
        "real_time_factor": wall_s / scenario.duration_s,
    }


def run_scenario(scenario, progress=None, trust_fmu: bool = False, label=None) -> Result:
    """Simulate a validated :class:`~emasim.scenarios.schema.Scenario` on the compiled engine.

    The Result carries the fully resolved scenario (so the run can be repeated exactly), the
    metadata (package version, seed, wall time of the simulation alone, the label, and why any
    metric is undefined) and the metrics. ``trust_fmu`` allows a scenario's
    ``solver.mechanism_fmu`` to be loaded (its code runs in this process).
    """
    check_fmu_trust(scenario, trust_fmu)
    if scenario.solver.communication_step_s is not None:
        result = cosimulate(scenario, scenario.solver.communication_step_s, trust_fmu)
    else:
        setup = scenario.setup()
        if setup.record_signals is not None:  # and what the metrics and plots read
            setup = setup.with_(record_signals=(*setup.record_signals, *ANALYSIS_COLUMNS))
        result = simulate(setup, progress=progress)
    result.scenario = scenario.model_dump(mode="json", exclude_none=True)
    result.meta = meta_of(scenario, result.meta["simulation_wall_s"])
    result.meta["label"] = label or scenario.controllers_label()
    c = scenario.controllers
    names = {  # the controllers' configured names, not their compiled laws'
        "position": c.position.name if c.position is not None else None,
        "speed": c.speed.name,
        "current": "pi",  # CurrentPI, the library's current law
    }
    loops = {slot: names[slot] for slot in result.description.loops}
    result.description = dataclasses.replace(result.description, loops=loops)
    result.metrics = run_metrics(result)
    undefined = undefined_metrics(result.metrics)
    if undefined:
        result.meta["undefined_metrics"] = undefined
    warnings = run_warnings(result.metrics)
    if warnings:
        result.meta["warnings"] = warnings
    return result
