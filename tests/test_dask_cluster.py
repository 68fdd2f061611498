"""A study on a real Dask cluster (issue 30, item 6): a scheduler and two workers started as
separate processes with Dask's own command line (``dask scheduler``, ``dask worker``), on the
loopback address, and ``emasim study --scheduler`` run on them. Its metrics.parquet equals a
local run's row by row: the runs are deterministic, wherever they execute. Every process is
bounded in time and ended when the test ends."""

import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import HANG_GUARD_S

from emasim.experiments.store import read_table

STUDY = ["study", "speed-step", "--label", "PI", "--set", "duration_s=0.02"]
STUDY += ["--vary", "plant.backlash.width_mm=0.05,0.1,0.2"]


def dask(*args: str, log: Path) -> subprocess.Popen:
    """``python -m dask ARGS`` in the background, its output to ``log``."""
    with log.open("w") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "dask", *args], stdout=out, stderr=subprocess.STDOUT
        )


def free_port() -> int:
    """A loopback port nothing listens on now (the scheduler takes it next)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def cluster(tmp_path):
    """A scheduler on 127.0.0.1 and two single-threaded worker processes; its address, once
    both workers have joined (Dask's connect and wait_for_workers, each bounded by HANG_GUARD_S,
    raise rather than hang)."""
    from distributed import Client

    address = f"tcp://127.0.0.1:{free_port()}"
    port = address.rsplit(":", 1)[1]
    processes = [
        dask(
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            port,
            "--no-dashboard",
            log=tmp_path / "scheduler.log",
        )
    ]
    try:
        for k in range(2):
            processes.append(
                dask(
                    "worker",
                    address,
                    "--host",
                    "127.0.0.1",
                    "--nworkers",
                    "1",
                    "--nthreads",
                    "1",
                    "--no-dashboard",
                    log=tmp_path / f"worker-{k}.log",
                )
            )
        with Client(address, timeout=HANG_GUARD_S) as client:
            client.wait_for_workers(2, timeout=HANG_GUARD_S)
        yield address
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

    with Client(address, timeout=HANG_GUARD_S) as client:
        return client.run(lambda dask_worker: dask_worker.state.executed_count)


def emasim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "emasim", *args],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
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
