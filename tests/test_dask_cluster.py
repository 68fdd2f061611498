"""A study on a real Dask cluster (issue 30, item 6): a scheduler and two workers started as
separate processes with Dask's own command line (``dask scheduler``, ``dask worker``), on the
loopback address, and ``emasim study --scheduler`` run on them. Its metrics.parquet equals a
local run's row by row: the runs are deterministic, wherever they execute. Every process is
bounded in time and ended when the test ends."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from emasim.experiments.study import read_table

STUDY = ["study", "speed-step", "--label", "PI", "--set", "duration_s=0.02"]
STUDY += ["--vary", "plant.backlash.width_mm=0.05,0.1,0.2"]
START_S = 90.0  # the scheduler's file and both workers, at most


def dask(*args: str, log: Path) -> subprocess.Popen:
    """``python -m dask ARGS`` in the background, its output to ``log``."""
    with log.open("w") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "dask", *args], stdout=out, stderr=subprocess.STDOUT
        )


def wait_for_workers(scheduler_file: Path, n: int) -> str:
    """The scheduler's address once ``n`` workers have joined it (START_S at most)."""
    from distributed import Client

    deadline = time.monotonic() + START_S
    while not scheduler_file.exists():
        assert time.monotonic() < deadline, "the scheduler wrote no scheduler file"
        time.sleep(0.2)
    address = json.loads(scheduler_file.read_text())["address"]
    with Client(address, timeout=START_S) as client:
        client.wait_for_workers(n, timeout=max(1.0, deadline - time.monotonic()))
    return address


@pytest.fixture
def cluster(tmp_path):
    """A scheduler on 127.0.0.1 and two single-threaded worker processes; its address."""
    scheduler_file = tmp_path / "scheduler.json"
    common = ["--no-dashboard"]
    processes = [
        dask(
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--scheduler-file",
            str(scheduler_file),
            *common,
            log=tmp_path / "scheduler.log",
        )
    ]
    try:
        for k in range(2):
            processes.append(
                dask(
                    "worker",
                    "--scheduler-file",
                    str(scheduler_file),
                    "--host",
                    "127.0.0.1",
                    "--nworkers",
                    "1",
                    "--nthreads",
                    "1",
                    *common,
                    log=tmp_path / f"worker-{k}.log",
                )
            )
        yield wait_for_workers(scheduler_file, 2)
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def executed(address: str) -> dict[str, int]:
    """worker -> how many tasks it has run."""
    from distributed import Client

    with Client(address, timeout=START_S) as client:
        return client.run(lambda dask_worker: dask_worker.state.executed_count)


def emasim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "emasim", *args], capture_output=True, text=True, timeout=600
    )


def test_a_study_on_a_dask_cluster_equals_the_local_run(cluster, tmp_path):
    remote, local = tmp_path / "on-the-cluster", tmp_path / "local"
    done = emasim(*STUDY, "--scheduler", cluster, "--out", str(remote))
    assert done.returncode == 0, done.stderr
    assert sum(executed(cluster).values()) >= 1  # the runs ran on the cluster's workers
    done = emasim(*STUDY, "--workers", "1", "--out", str(local))
    assert done.returncode == 0, done.stderr
    a, b = read_table(remote), read_table(local)
    assert len(a) == 3 and list(a.columns) == list(b.columns)
    assert list(a["status"]) == ["ok"] * 3
    for column in a.columns:
        if a[column].dtype.kind in "fiu":
            np.testing.assert_array_equal(a[column].to_numpy(), b[column].to_numpy(), column)
        else:
            assert list(a[column]) == list(b[column]), column
