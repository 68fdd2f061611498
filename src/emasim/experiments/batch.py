"""Many independent runs at once, the one facility for sweeps, and a scenario's comparison of
its controller sets.

Runs are Dask delayed tasks. The default threaded scheduler uses every core of this machine,
because the compiled loop releases the GIL (``nogil``) while it integrates, and numba's noise
generator is per thread and seeded at the start of each run, so results do not depend on the
schedule. Pass ``scheduler`` (any of Dask's: "threads", "processes", "synchronous", or a
distributed Client's) to run elsewhere.
"""

from ..sim.cosim import check_fmu_trust
from ..sim.result import Comparison
from .runs import meta_of, run_scenario


def run_all(scenarios, scheduler="threads", trust_fmu: bool = False, labels=None) -> list:
    """Simulate scenarios (single runs) in parallel; return their Results in order.

    ``labels`` name the runs (one per scenario); ``trust_fmu`` as in ``run_scenario``.
    """
    import dask  # here: a single run needs none of it (0.17 s of start-up)

    scenarios = list(scenarios)
    labels = list(labels) if labels is not None else [None] * len(scenarios)
    tasks = [
        dask.delayed(run_scenario)(scenario, trust_fmu=trust_fmu, label=label)
        for scenario, label in zip(scenarios, labels, strict=True)
    ]
    return list(dask.compute(*tasks, scheduler=scheduler))


def run_comparison(scenario, progress=None, trust_fmu: bool = False) -> Comparison:
    """Run every controller set of ``scenario.compare`` (or its one set) on the experiment,
    in parallel (run_all); ``progress`` is told 0 at the start and 1 at the end."""
    check_fmu_trust(scenario, trust_fmu)
    variants = scenario.variants()
    if progress is not None:
        progress(0.0)
    runs = run_all(
        (v for _, v in variants), trust_fmu=trust_fmu, labels=[label for label, _ in variants]
    )
    results = dict(zip((label for label, _ in variants), runs, strict=True))
    if progress is not None:
        progress(1.0)
    wall = sum(r.meta["simulation_wall_s"] for r in results.values())
    meta = meta_of(scenario, wall)
    meta["real_time_factor"] = wall / (scenario.duration_s * len(variants))
    return Comparison(
        results, scenario=scenario.model_dump(mode="json", exclude_none=True), meta=meta
    )
