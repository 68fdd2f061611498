"""Runs in parallel (emasim.experiments.batch) give exactly what they give one by one."""

import warnings

import numpy as np
import pytest

from emasim.experiments.batch import (
    GROUP_MAX,
    TASKS_PER_SLOT,
    dask_client,
    map_runs,
    run_all,
    task_groups,
)
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
    # the seeds differ, so the noisy current readings, and with them the runs, differ
    assert not np.array_equal(parallel[0].data, parallel[2].data, equal_nan=True)


class RecordingClient:
    """A Dask client that notes the tasks it is sent: how many, and the jobs of each."""

    def __init__(self, client):
        self.client, self.sent = client, []

    def submit(self, run_group, function, jobs, **kwargs):
        self.sent.append(jobs)
        return self.client.submit(run_group, function, jobs, **kwargs)

    def scheduler_info(self):
        return self.client.scheduler_info()

    def cancel(self, futures):
        self.client.cancel(futures)


def test_runs_start_longest_first_and_come_back_in_the_order_given():
    durations = (0.01, 0.04, 0.02, 0.03)
    scenarios = [load_scenario("speed-step", settings=[f"duration_s={d}"]) for d in durations]
    with dask_client(processes=False) as client:
        recording = RecordingClient(client)
        results = run_all(scenarios, labels=[str(d) for d in durations], client=recording)
    sent = [scenario.duration_s for task in recording.sent for scenario, *_ in task]
    assert sent == sorted(durations, reverse=True)
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


@pytest.mark.parametrize("jobs", [1, 7, 64, 200, 1000])
@pytest.mark.parametrize("slots", [1, 2, 16])
def test_task_groups_hold_every_job_once_in_shrinking_tasks(jobs, slots):
    """Guided self-scheduling: every job once, in order; each task ceil(left / (4 slots)) jobs,
    at most GROUP_MAX, so one job each once no more are left than 4 per slot."""
    groups = task_groups(range(jobs), slots)
    assert [i for group in groups for i in group] == list(range(jobs))
    sizes = [len(group) for group in groups]
    left = jobs
    for size in sizes:
        assert size == min(-(-left // (TASKS_PER_SLOT * slots)), GROUP_MAX)
        left -= size
    assert sizes == sorted(sizes, reverse=True) and sizes[-1] == 1


def test_grouped_jobs_come_back_in_order_and_each_is_told():
    """Grouped tasks: the values of all jobs in the order given; on_done hears of each job
    once, with its own value, and fewer tasks are sent than there are jobs."""
    jobs = [(k, k + 1) for k in range(40)]
    told = {}
    with dask_client(workers=2, processes=False) as client:
        recording = RecordingClient(client)
        values = map_runs(pow, jobs, recording, on_done=told.__setitem__, grouped=True)
    assert values == [pow(*job) for job in jobs]
    assert told == dict(enumerate(values))
    assert len(recording.sent) == len(task_groups(range(40), 2)) < 40
