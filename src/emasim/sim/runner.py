"""Run a scenario end to end: compile, simulate, attach scenario, metadata and metrics."""

import datetime
import platform

import numba

from .. import __version__
from ..analysis.report import run_metrics
from .engine import simulate
from .result import Result


def run_scenario(scenario, progress=None) -> Result:
    """Simulate a validated :class:`~emasim.scenarios.schema.Scenario` on the compiled engine.

    The Result carries the fully resolved scenario (so the run can be repeated exactly), the
    metadata (package version, seed, wall time of the simulation alone) and the metrics.
    """
    result = simulate(scenario.setup(), progress=progress)
    result.scenario = scenario.model_dump(mode="json", exclude_none=True)
    result.meta.update(
        {
            "emasim_version": __version__,
            "seed": scenario.seed,
            "scenario": scenario.name,
            "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "python": platform.python_version(),
            "numba": numba.__version__,
            "real_time_factor": result.meta["simulation_wall_s"] / scenario.duration_s,
        }
    )
    result.metrics = run_metrics(result)
    return result
