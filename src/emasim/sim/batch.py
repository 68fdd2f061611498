"""Many independent runs at once: the one facility for comparisons and sweeps.

Runs are Dask delayed tasks. The default threaded scheduler uses every core of this machine,
because the compiled loop releases the GIL (``nogil``) while it integrates, and numba's noise
generator is per thread and seeded at the start of each run, so results do not depend on the
schedule. Pass ``scheduler`` (any of Dask's: "threads", "processes", "synchronous", or a
distributed Client's) to run elsewhere.
"""

import dask


def run_all(scenarios, scheduler="threads", trust_fmu: bool = False, labels=None) -> list:
    """Simulate scenarios (single runs) in parallel; return their Results in order.

    ``labels`` name the runs (one per scenario); ``trust_fmu`` as in ``run_scenario``.
    """
    from .runner import run_scenario

    scenarios = list(scenarios)
    labels = list(labels) if labels is not None else [None] * len(scenarios)
    tasks = [
        dask.delayed(run_scenario)(scenario, trust_fmu=trust_fmu, label=label)
        for scenario, label in zip(scenarios, labels, strict=True)
    ]
    return list(dask.compute(*tasks, scheduler=scheduler))
