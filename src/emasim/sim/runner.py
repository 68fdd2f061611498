"""Run a scenario end to end: compile, simulate, attach scenario, metadata and metrics."""

import datetime
import platform

import numba

from .. import __version__
from ..analysis.report import run_metrics
from .cosim import cosimulate
from .engine import simulate
from .result import Comparison, Result


def _meta(scenario, wall_s: float) -> dict:
    """What a saved result needs to be regenerated and judged: versions, seed, timings."""
    return {
        "emasim_version": __version__,
        "seed": scenario.seed,
        "scenario": scenario.name,
        "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "simulation_wall_s": wall_s,
        "real_time_factor": wall_s / scenario.duration_s,
    }


def run_scenario(scenario, progress=None) -> Result:
    """Simulate a validated :class:`~emasim.scenarios.schema.Scenario` on the compiled engine.

    The Result carries the fully resolved scenario (so the run can be repeated exactly), the
    metadata (package version, seed, wall time of the simulation alone) and the metrics.
    """
    if scenario.solver.communication_step_s is not None:
        result = cosimulate(scenario, scenario.solver.communication_step_s)
    else:
        result = simulate(scenario.setup(), progress=progress)
    result.scenario = scenario.model_dump(mode="json", exclude_none=True)
    result.meta = _meta(scenario, result.meta["simulation_wall_s"])
    result.metrics = run_metrics(result)
    return result


def run_comparison(scenario, progress=None) -> Comparison:
    """Run every controller set of ``scenario.compare`` (or its one set) on the experiment,
    in parallel (emasim.sim.batch); ``progress`` is told 0 at the start and 1 at the end."""
    from .batch import run_all

    variants = scenario.variants()
    if progress is not None:
        progress(0.0)
    results = dict(
        zip((label for label, _ in variants), run_all(v for _, v in variants), strict=True)
    )
    if progress is not None:
        progress(1.0)
    wall = sum(r.meta["simulation_wall_s"] for r in results.values())
    meta = _meta(scenario, wall)
    meta["real_time_factor"] = wall / (scenario.duration_s * len(variants))
    return Comparison(
        results, scenario=scenario.model_dump(mode="json", exclude_none=True), meta=meta
    )
