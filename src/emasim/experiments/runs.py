"""Run a scenario end to end: compile, simulate, attach scenario, metadata and metrics."""

import dataclasses
import datetime
import functools
import logging
import platform
import shlex
import subprocess
import sys
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING

from ..analysis.report import (
    ANALYSIS_COLUMNS,
    limit_warnings,
    limits_crossed,
    run_metrics,
    run_warnings,
    undefined_metrics,
)
from ..numba_cache import source_hash
from ..sim.cosim import check_fmu_trust, cosimulate
from ..sim.engine import simulate
from ..sim.result import Result
from ..version import __version__

if TYPE_CHECKING:
    from ..scenarios.schema import Scenario
    from ..sim.setup import Setup

log = logging.getLogger("emasim")  # each run's timing, at debug level (emasim --verbose)


def meta_of(scenario, wall_s: float) -> dict:
    """What a saved result needs to be regenerated and judged: versions (emasim, the digest of
    its source for any install, its git commit when it runs from a git checkout, Python,
    numpy, scipy, numba), the platform, the command line, the seed and the timings."""
    return {
        "emasim_version": __version__,
        "emasim_source_sha256": source_digest(),
        **source_commit(),
        "seed": scenario.seed,
        "scenario": scenario.name,
        "created_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        **_platform(),
        "command_line": shlex.join(sys.argv),
        "simulation_wall_s": wall_s,
        "real_time_factor": wall_s / scenario.duration_s,
    }


@functools.cache
def _platform() -> dict:
    """The versions of Python, numpy, scipy and numba, and the platform (they do not change
    while this process runs)."""
    return {
        "python": platform.python_version(),
        "numpy": version("numpy"),
        "scipy": version("scipy"),
        "numba": version("numba"),
        "platform": platform.platform(),
    }


@functools.cache
def source_digest() -> str:
    """The digest of the package's source (emasim.numba_cache.source_hash) when this process
    first asks: it names the code that runs, for any install, with or without git."""
    return source_hash()


@functools.cache
def source_commit() -> dict:
    """``git_commit`` (and ``git_dirty``: uncommitted changes to the package) of the checkout
    emasim's source is tracked in, when this process first asks (three git commands: 10 ms,
    once, not at every run); {} for an installed copy (not tracked by any git tree, even one
    it lies inside), or without git."""
    package = Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(package), *args],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout

    try:
        git("ls-files", "--error-unmatch", "__init__.py")  # the package itself is tracked
        commit = git("rev-parse", "HEAD").strip()
        dirty = bool(git("status", "--porcelain", "--", ".").strip())
    except (OSError, subprocess.SubprocessError):
        return {}
    return {"git_commit": commit, "git_dirty": dirty}


def simulate_scenario(
    scenario: "Scenario", trust_fmu: bool = False, setup: "Setup | None" = None, progress=None
) -> Result:
    """The bare simulation of a scenario, every solver setting honoured: a co-simulation where
    ``solver.communication_step_s`` is set (unless ``setup`` replaces the scenario's own
    Setup), else the compiled engine, recording ``solver.record_signals`` and what the metrics
    read (ANALYSIS_COLUMNS). Both :func:`run_scenario` and the tuning's trials run this. The
    Result's description holds the scenario's experiment (what its metrics and figures read)."""
    check_fmu_trust(scenario, trust_fmu)
    if scenario.solver.communication_step_s is not None and setup is None:
        result = cosimulate(scenario, scenario.solver.communication_step_s, trust_fmu)
    else:
        run = scenario.setup() if setup is None else setup
        if run.record_signals is not None:  # and what the metrics and plots read
            run = run.with_(record_signals=(*run.record_signals, *ANALYSIS_COLUMNS))
        result = simulate(run, progress=progress)
    experiment = scenario.experiment()
    result.description = dataclasses.replace(result.description, experiment=experiment)
    return result


def run_scenario(
    scenario: "Scenario",
    progress: Callable[[float], None] | None = None,
    trust_fmu: bool = False,
    label: str | None = None,
    setup: "Setup | None" = None,
) -> Result:
    """Simulate a validated :class:`~emasim.scenarios.schema.Scenario` on the compiled engine.

    The Result carries the fully resolved scenario (so the run can be repeated exactly), the
    metadata (package version, seed, wall time of the simulation alone, the label, and why any
    metric is undefined) and the metrics. ``trust_fmu`` allows a scenario's
    ``solver.mechanism_fmu`` to be loaded (its code runs in this process). ``setup`` runs that
    :class:`~emasim.sim.setup.Setup` instead of the scenario's own: the scenario's with a slot
    replaced by a law of your own (``scenario.setup().with_(speed=Compiled(...))``). Its
    metadata then names the replaced slots' laws (``custom_laws``), which the saved
    scenario.toml cannot hold.
    """
    given = setup is not None
    result = simulate_scenario(scenario, trust_fmu, setup, progress)
    # the run that was made: a comparison's other sets are not part of it
    result.scenario = scenario.model_dump(mode="json", exclude_none=True, exclude={"compare"})
    compile_s = result.meta.get("compile_s", 0.0)  # the co-simulation's has none
    result.meta = meta_of(scenario, result.meta["simulation_wall_s"])
    result.meta["compile_s"] = compile_s
    log.debug(
        f"{scenario.name} ({label or scenario.controllers_label()}): {scenario.duration_s:g} s "
        f"simulated in {result.meta['simulation_wall_s']:.3f} s (real-time factor "
        f"{result.meta['real_time_factor']:.4f}), engine loaded in {compile_s:.3f} s"
    )
    result.meta["label"] = (
        label or scenario.tuning.get("controller_set") or scenario.controllers_label()
    )
    if "gains_from" in scenario.tuning:  # a controller set's gains, chosen by the loader
        result.meta["gains_from"] = scenario.tuning["gains_from"]
    c = scenario.controllers
    names = {  # the controllers' configured names, not their compiled laws'
        "position": c.position.name if c.position is not None else None,
        "speed": c.speed.name,
        "current": "pi",  # CurrentPI, the library's current law
    }
    laws = result.description.loops
    own = scenario.setup().loop_laws() if given else laws
    custom = {slot: law for slot, law in laws.items() if own.get(slot) != law}
    if custom:
        result.meta["custom_laws"] = custom
    loops = {slot: custom.get(slot) or names[slot] for slot in laws}
    result.description = dataclasses.replace(result.description, loops=loops)
    result.metrics = run_metrics(result)
    undefined = undefined_metrics(result.metrics)
    if undefined:
        result.meta["undefined_metrics"] = undefined
    limits = limits_crossed(result)
    if limits:
        result.meta["limits"] = limits
    warnings = run_warnings(result.metrics) + limit_warnings(limits)
    if warnings:
        result.meta["warnings"] = warnings
    return result
