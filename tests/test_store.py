"""The job store: a job list's runs in one resumable folder, with one tidy table."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from subprocess import DEVNULL

import numpy as np
import pandas as pd
import pytest

from emasim.errors import OutputError
from emasim.experiments import runs
from emasim.experiments.batch import Job, dask_client
from emasim.experiments.reproduction import RUNS_TABLE, job_store, reproduce
from emasim.experiments.store import (
    LOG_FILE,
    METRICS_FILE,
    RUN_ID,
    RUNS_FOLDER,
    Store,
    digest,
    read_table,
)
from emasim.scenarios.loader import load_scenario

SHORT = ["duration_s=0.04"]


def jobs_of(seeds, trace_first=True):
    """speed-step with PI at each seed, tagged with it; the first keeps its trace."""
    jobs = []
    for i, seed in enumerate(seeds):
        scenario = load_scenario("speed-step", label="PI", settings=[*SHORT, f"seed={seed}"])
        tags = {RUN_ID: f"pi-{seed}", "seed": seed}
        jobs.append(Job(scenario, "PI", tags, trace=trace_first and i == 0))
    return jobs


def counting(monkeypatch) -> list:
    """Count the runs simulated from now on (run_and_write reads runs.run_scenario)."""
    ran, real = [], runs.run_scenario

    def run_scenario(scenario, **kwargs):
        ran.append(scenario.seed)
        return real(scenario, **kwargs)

    monkeypatch.setattr(runs, "run_scenario", run_scenario)
    return ran


def test_the_table_has_a_row_per_run_with_its_tags_status_and_metrics(tmp_path):
    jobs = jobs_of([1, 2, 3])
    store = Store(tmp_path / "s", jobs, {"what": "three seeds"})
    rows = store.run()
    table = read_table(tmp_path / "s")
    assert list(table.columns[:4]) == ["run_id", "label", "status", "seed"]
    assert list(table["run_id"]) == ["pi-1", "pi-2", "pi-3"] and (table["status"] == "ok").all()
    for job in jobs:  # every metric is the run's own, alone
        alone = runs.run_scenario(job.scenario, label="PI").metrics
        assert store.metrics_of(rows[job.tags[RUN_ID]]) == pytest.approx(alone, nan_ok=True)
    assert table.equals(store.frame(rows))


def test_a_kept_trace_reads_back_as_the_run_and_the_others_keep_none(tmp_path):
    jobs = jobs_of([1, 2])
    store = Store(tmp_path / "s", jobs, {"what": "two seeds"})
    store.run()
    alone = runs.run_scenario(jobs[0].scenario, label="PI")
    kept = store.result(jobs[0])
    assert kept.columns == alone.columns and np.array_equal(kept.data, alone.data, equal_nan=True)
    assert kept.metrics == pytest.approx(alone.metrics, nan_ok=True)
    assert not (tmp_path / "s" / RUNS_FOLDER / "pi-2" / "result.parquet").exists()


def test_a_run_folder_that_lost_a_file_is_run_again(tmp_path, monkeypatch):
    jobs = jobs_of([1, 2])
    store = Store(tmp_path / "s", jobs, {"what": "two seeds"})
    store.run()
    (tmp_path / "s" / RUNS_FOLDER / "pi-1" / "result.parquet").unlink()  # the kept trace
    edited = tmp_path / "s" / RUNS_FOLDER / "pi-2" / "metrics.json"
    edited.write_text("{}")  # a file changed since emasim wrote it: never replaced
    ran = counting(monkeypatch)
    rows = store.run()
    assert sorted(ran) == [1, 2] and store.result(jobs[0]).data.shape[0] > 0
    assert rows["pi-1"]["status"] == "ok" and edited.read_text() == "{}"
    assert rows["pi-2"]["status"].startswith("failed: ") and "emasim" in rows["pi-2"]["status"]


def test_a_killed_job_list_resumes_with_only_the_runs_it_lacks(tmp_path, monkeypatch):
    jobs = jobs_of([1, 2, 3, 4])
    full = Store(tmp_path / "full", jobs, {"what": "four seeds"})
    whole = full.frame(full.run())
    # the folder as a kill leaves it: two runs finished, the table behind, and the temporary
    # of a run killed as it was published, its records written: not a finished run
    shutil.copytree(tmp_path / "full", tmp_path / "cut", symlinks=True)
    runs_folder = tmp_path / "cut" / RUNS_FOLDER
    dead = runs_folder / ".pi-2.tmp-999999-0123abcd"
    (runs_folder / "pi-2").rename(dead)
    shutil.rmtree(runs_folder / "pi-4")
    (tmp_path / "cut" / METRICS_FILE).unlink()
    ran = counting(monkeypatch)
    told = []
    cut = Store(tmp_path / "cut", jobs, {"what": "four seeds"})
    resumed = cut.frame(cut.run(progress=lambda done, total: told.append((done, total))))
    assert sorted(ran) == [2, 4] and told[0] == (2, 4) and told[-1] == (4, 4)
    assert resumed.equals(whole) and read_table(tmp_path / "cut").equals(whole)
    assert not dead.exists() and (runs_folder / "pi-2" / "metrics.json").is_file()


def test_a_folder_holding_other_runs_is_refused_and_left_as_it_was(tmp_path):
    Store(tmp_path / "s", jobs_of([1]), {"what": "seed 1"}).run()
    before = sorted(p.name for p in (tmp_path / "s").rglob("*"))
    with pytest.raises(OutputError, match="holds other runs"):
        Store(tmp_path / "s", jobs_of([1]), {"what": "seed 1, again"}).run()
    assert sorted(p.name for p in (tmp_path / "s").rglob("*")) == before
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match="emasim did not write"):
        Store(mine, jobs_of([1]), {}).run()
    assert os.listdir(mine) == ["notes.txt"]


def test_two_jobs_sharing_a_run_id_are_refused():
    job = jobs_of([1])[0]
    with pytest.raises(ValueError, match="share a run id"):
        Store("unused", [job, job], {})


def test_the_digest_follows_every_scenario():
    assert digest(jobs_of([1, 2])) == digest(jobs_of([1, 2]))
    assert digest(jobs_of([1, 2])) != digest(jobs_of([1, 3]))


def test_a_killed_reproduction_resumes_from_its_store(tmp_path, monkeypatch):
    """A reproduction's runs go through its store: run again after a kill, it simulates only
    what the store lacks, and its report (tables and the tidy runs.parquet) is the same."""
    monkeypatch.chdir(tmp_path)  # the store lives under runs/reproduce/
    first = reproduce(tmp_path / "first", only=["speed-step"], with_ablation=False)
    store, _ = job_store({"speed-step": load_scenario("speed-step")}, with_ablation=False)
    assert store.folder.is_dir() and len(store.jobs) >= 2
    table = read_table(store.folder)
    assert pd.read_parquet(first / RUNS_TABLE).equals(table) and (table["status"] == "ok").all()
    lost = sorted((store.folder / RUNS_FOLDER).iterdir())[0]
    shutil.rmtree(lost)  # a run the kill left unfinished
    ran = counting(monkeypatch)
    again = reproduce(tmp_path / "again", only=["speed-step"], with_ablation=False)
    assert len(ran) == 1
    tables = [json.loads((f / "tables.json").read_text()) for f in (first, again)]
    assert tables[0] == tables[1]
    assert pd.read_parquet(again / RUNS_TABLE).equals(table)


def test_a_reproduction_killed_by_sigkill_resumes_without_running_its_finished_runs_again(
    tmp_path,
):
    """A real kill, in a process of its own, as soon as the store holds a finished run: the
    same command then finishes, each run that was finished before is kept as it was (its
    meta.json unchanged), and the report's table has every run, ok."""
    command = [sys.executable, "-m", "emasim", "reproduce", "--only", "bench-step"]
    command += ["--no-ablation", "--out", "report"]
    runs = tmp_path / "runs" / "reproduce"
    finished = lambda: sorted(  # noqa: E731
        meta for meta in runs.glob("jobs-*/runs/*/meta.json") if meta.parent.name[0] != "."
    )
    process = subprocess.Popen(command, cwd=tmp_path, stdout=DEVNULL, stderr=DEVNULL)
    while not finished() and process.poll() is None:  # the run ends by itself: a bounded wait
        time.sleep(0.005)
    process.send_signal(signal.SIGKILL)
    process.wait()
    before = {path: path.read_bytes() for path in finished()}
    assert before and not (tmp_path / "report").exists()
    again = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert {path: path.read_bytes() for path in before} == before
    table = pd.read_parquet(tmp_path / "report" / RUNS_TABLE)
    assert len(table) > len(before) and (table["status"] == "ok").all()


def test_a_store_and_its_table_are_pruned_whole_and_a_changed_table_keeps_it(tmp_path):
    """metrics.parquet, written after the store's folder was published, is in its manifest,
    and so is workers.log as the workers left it: `emasim runs prune` removes a finished
    store whole, and keeps one whose table changed."""
    from typer.testing import CliRunner

    from emasim.cli import app

    for name in ("a", "b"):
        Store(tmp_path / "runs" / name, jobs_of([1]), {"what": name}).run()
    (tmp_path / "runs" / "a" / LOG_FILE).write_text("a worker's warning\n")
    Store(tmp_path / "runs" / "a", jobs_of([1]), {"what": "a"}).run()  # its log listed again
    with open(tmp_path / "runs" / "b" / METRICS_FILE, "ab") as table:
        table.write(b"an edit")
    done = CliRunner().invoke(
        app, ["runs", "prune", str(tmp_path / "runs"), "--keep", "0", "--yes"]
    )
    assert done.exit_code == 0, done.output
    assert not (tmp_path / "runs" / "a").exists() and (tmp_path / "runs" / "b").is_dir()
    assert f"kept, it holds files emasim did not write ({METRICS_FILE})" in " ".join(
        done.output.split()
    )


def test_a_study_of_other_code_is_never_resumed(tmp_path, monkeypatch):
    """A study's record and the robustness studies' folder key name the source digest: the
    same study run by changed code is refused in its folder, and gets a folder of its own."""
    from emasim.experiments import robustness
    from emasim.experiments import runs as runs_module
    from emasim.experiments.study import StudySpec, run_study

    spec = StudySpec("speed-step", vary=("seed=1",), labels=("PI",), settings=tuple(SHORT))
    with dask_client(processes=False) as client:
        run_study(spec, tmp_path / "s", client=client)
        before = robustness.study_folder("bench-step", 3, tmp_path)
        monkeypatch.setattr(runs_module, "source_digest", lambda: "another source")
        with pytest.raises(OutputError, match="version or source differ"):
            run_study(spec, tmp_path / "s", client=client)
    assert robustness.study_folder("bench-step", 3, tmp_path) != before
