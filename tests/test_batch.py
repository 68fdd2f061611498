"""Runs in parallel (emasim.experiments.batch) give exactly what they give one by one."""

import numpy as np

from emasim.experiments.batch import run_all
from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario


def test_parallel_runs_match_sequential_runs_with_noise():
    scenarios = [
        load_scenario("bench-step", controllers=[cascade], settings=["duration_s=0.2", f"seed={s}"])
        for cascade, s in (("pid", 1), ("hybrid", 2), ("pid", 3))
    ]
    parallel = run_all(scenarios)
    for scenario, result in zip(scenarios, parallel, strict=True):
        alone = run_scenario(scenario)
        assert np.array_equal(result.data, alone.data, equal_nan=True)
    # the seeds differ, so the noisy measurements differ between runs of the same cascade
    first, third = parallel[0]["measured_position_m"], parallel[2]["measured_position_m"]
    assert not np.array_equal(first, third)
