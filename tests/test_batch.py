"""Runs in parallel (emasim.experiments.batch) give exactly what they give one by one."""

import warnings

import numpy as np
import pytest

from emasim.experiments.batch import dask_client, run_all
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


class RecordingClient:
    """A Dask client that notes the simulated time of each run in the order it is sent."""

    def __init__(self, client):
        self.client, self.sent = client, []

    def submit(self, function, scenario, *args, **kwargs):
        self.sent.append(scenario.duration_s)
        return self.client.submit(function, scenario, *args, **kwargs)

    def cancel(self, futures):
        self.client.cancel(futures)


def test_runs_start_longest_first_and_come_back_in_the_order_given():
    durations = (0.01, 0.04, 0.02, 0.03)
    scenarios = [load_scenario("speed-step", settings=[f"duration_s={d}"]) for d in durations]
    with dask_client(processes=False) as client:
        recording = RecordingClient(client)
        results = run_all(scenarios, labels=[str(d) for d in durations], client=recording)
    assert recording.sent == sorted(durations, reverse=True)
    assert [r.meta["label"] for r in results] == [str(d) for d in durations]
    assert [r["t_s"][-1] for r in results] == pytest.approx([d - 1e-4 for d in durations])


def test_a_warning_in_a_worker_process_is_one_line(capfd):
    """emasim's own worker processes show a Python warning as the command line does: one
    ``warning:`` line, not Python's two lines with the source path (the worker's stderr is
    this process's, which capfd reads)."""
    with dask_client(workers=1) as client:
        client.submit(warnings.warn, "eq. 37 does not hold", UserWarning, pure=False).result()
    lines = [line for line in capfd.readouterr().err.splitlines() if "eq. 37" in line]
    assert lines == ["warning: eq. 37 does not hold"]
