"""Studies (emasim.experiments.study, .variation): what a KEY=SPEC means, the samples it
draws, runs that equal the same scenario run alone, resuming, and refusing what is not ours."""

import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from emasim.errors import InputError
from emasim.experiments.batch import dask_client
from emasim.experiments.runs import run_scenario
from emasim.experiments.store import (
    METRICS_FILE,
    RUNS_FOLDER,
    finished_rows,
    read_table,
    run_and_write,
    run_id_of,
)
from emasim.experiments.study import (
    Plan,
    StudySpec,
    grouping_keys,
    plan_study,
    run_study,
    summarize_by,
    varied,
)
from emasim.experiments.variation import parse_variation, samples
from emasim.output import OutputError, foreign_files
from emasim.scenarios.loader import load_scenario

SHORT = ("duration_s=0.04",)


@pytest.fixture(scope="module")
def client():
    """Two worker threads in this process: no processes to start for each study."""
    with dask_client(workers=2, processes=False) as c:
        yield c


# --- what a SPEC means ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "grid"),
    [
        ("a.b=0.1", (0.1,)),
        ("a.b=0.05,0.1,0.2", (0.05, 0.1, 0.2)),
        ("a.b=[1, 2]", (1, 2)),
        ("a.b=linspace(0, 1, 5)", (0.0, 0.25, 0.5, 0.75, 1.0)),
        ("a.b=geomspace(1, 100, 3)", (1.0, 10.0, 100.0)),
        ("plant.preset=sea805,sea805-linkage", ("sea805", "sea805-linkage")),
    ],
)
def test_grids(text, grid):
    variation = parse_variation(text)
    assert variation.distribution is None
    assert variation.grid == pytest.approx(grid) if not isinstance(grid[0], str) else grid


def test_a_list_of_arrays_gives_each_key_its_own_value():
    variation = parse_variation("a.x,a.y=*[[1, 1], [1.5, 3]]")
    assert variation.grid == ([1, 1], [1.5, 3]) and variation.relative
    assert variation.value_of([1.5, 3], 1) == 3 and variation.column([1.5, 3]) == 1
    with pytest.raises(InputError, match="one value per key"):
        parse_variation("a.x,a.y=[[1, 2], [3]]")


def test_several_keys_share_one_value_and_a_star_scales():
    variation = parse_variation("a.x,a.y=*uniform(0.5, 1.5)")
    assert variation.keys == ("a.x", "a.y") and variation.relative
    assert variation.distribution == ("uniform", (0.5, 1.5))


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("a.b", "expected KEY=SPEC"),
        ("a..b=1", "expected KEY=SPEC"),
        ("a.b=beta(1, 2)", "unknown 'beta(...)'"),
        ("a.b=uniform(1)", "uniform takes 2 numbers, got 1"),
        ("a.b=uniform(2, 1)", "needs a < b"),
        ("a.b=normal(0, 0)", "needs std > 0"),
        ("a.b=loguniform(0, 1)", "needs a > 0"),
        ("a.b=integers(0.5, 3)", "whole numbers"),
        ("a.b=linspace(0, 1, 2.5)", "whole number"),
        ("a.b=geomspace(0, 1, 3)", "needs a > 0 and b > 0"),
        ("a.b=uniform(0, nan)", "finite"),
        ("a.b=*fast", "a '*' factor must be a number"),
        ("a.b=1,,2", "an empty item"),
    ],
)
def test_bad_specs_are_one_line_naming_the_key(text, says):
    with pytest.raises(InputError, match=r"--vary") as err:
        parse_variation(text)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_the_samples_are_the_product_of_the_grids_times_the_runs():
    grid_a, grid_b = parse_variation("a=1,2,3"), parse_variation("b=10,20")
    draw = parse_variation("c=uniform(0, 1)")
    points = samples([grid_a, grid_b, draw], runs=4, seed=7)
    assert len(points) == 3 * 2 * 4
    assert [(p.values["a"], p.values["b"]) for p in points[::4]] == [
        (a, b) for a in (1, 2, 3) for b in (10, 20)
    ]
    assert [p.index for p in points] == list(range(24))


def test_a_samples_draws_depend_only_on_its_place_and_the_seed():
    draw = parse_variation("c=normal(0, 1)")
    short, long = samples([draw], 3, seed=1), samples([draw], 50, seed=1)
    assert [p.values for p in short] == [p.values for p in long[:3]]
    other = samples([draw], 3, seed=2)
    assert [p.values for p in other] != [p.values for p in short]


@pytest.mark.parametrize(
    ("spec", "mean", "std"),
    [
        ("uniform(2, 4)", 3.0, 2 / math.sqrt(12)),
        ("normal(5, 0.5)", 5.0, 0.5),
        # log-uniform on [1, e^2]: log x is uniform on [0, 2]
        ("loguniform(1, 7.38905609893065)", (math.exp(2) - 1) / 2, None),
    ],
)
def test_the_draws_follow_their_distribution(spec, mean, std):
    n = 4000
    x = np.array([p.values["c"] for p in samples([parse_variation(f"c={spec}")], n, seed=3)])
    sigma = x.std()
    assert abs(x.mean() - mean) < 4 * sigma / math.sqrt(n)  # a 4-sigma bound on the mean
    if std is not None:
        assert sigma == pytest.approx(std, rel=0.06)


def test_integers_include_both_ends():
    x = {p.values["s"] for p in samples([parse_variation("s=integers(3, 5)")], 200, seed=0)}
    assert x == {3, 4, 5}


def test_repeating_identical_runs_is_refused():
    with pytest.raises(InputError, match="--runs"):
        samples([parse_variation("a=1,2")], runs=3, seed=0)
    with pytest.raises(InputError, match="varied twice"):
        samples([parse_variation("a,b=1"), parse_variation("b=2")], runs=1, seed=0)


# --- what a study runs ---------------------------------------------------------------------


def test_a_star_scales_every_key_by_the_same_factor_of_its_own_value():
    spec = StudySpec(
        "speed-step",
        vary=("plant.friction.coulomb_Nm,plant.friction.static_Nm=*0.5,2",),
        labels=("PI",),
    )
    plan = plan_study(spec)
    nominal = load_scenario("speed-step", controllers=["speed=pi"]).plant.friction
    for job in plan.jobs:
        factor = job.tags["plant.friction.coulomb_Nm,plant.friction.static_Nm"]
        friction = job.scenario.plant.friction
        assert friction.coulomb_Nm == pytest.approx(factor * nominal.coulomb_Nm)
        assert friction.static_Nm == pytest.approx(factor * nominal.static_Nm)


def test_zipped_values_scale_each_key_by_its_own_factor():
    spec = StudySpec(
        "speed-step",
        vary=("plant.backlash.width_mm,plant.friction.coulomb_Nm=*[[1, 1], [2, 1.5]]",),
        labels=("PI",),
    )
    nominal = load_scenario("speed-step", controllers=["speed=pi"]).plant
    first, second = plan_study(spec).jobs
    assert first.scenario.plant == nominal
    assert second.scenario.plant.backlash.width_mm == pytest.approx(2 * nominal.backlash.width_mm)
    assert second.scenario.plant.friction.coulomb_Nm == pytest.approx(
        1.5 * nominal.friction.coulomb_Nm
    )
    assert [varied(job) for job in (first, second)] == [
        {"plant.backlash.width_mm,plant.friction.coulomb_Nm": 0},
        {"plant.backlash.width_mm,plant.friction.coulomb_Nm": 1},
    ]


def test_a_number_for_a_list_sets_every_element():
    spec = StudySpec("bench-step", vary=("plant.linkage.hinge_clearance_mm=0.02",))
    for job in plan_study(spec).jobs:  # one per controller set
        assert list(job.scenario.plant.linkage.hinge_clearance_mm) == [0.02] * 4


def test_controller_keys_vary_each_controller_set():
    spec = StudySpec("bench-step", vary=("controllers.position.kp_per_s=*0.5,1",), labels=("PID",))
    plan = plan_study(spec)
    tuned = dict(load_scenario("bench-step").variants())["PID"].controllers.position
    gains = [job.scenario.controllers.position.kp_per_s for job in plan.jobs]
    assert gains == pytest.approx([0.5 * tuned.kp_per_s, tuned.kp_per_s])


@pytest.mark.parametrize(
    ("spec", "says"),
    [
        (StudySpec("speed-step", labels=("PID",)), "--label: 'PID' is no controller set"),
        (
            StudySpec("speed-step", vary=("plant.backlash.width_mm=-1,0.1",)),
            "the sample plant.backlash.width_mm=-1 is not a valid scenario",
        ),
        (StudySpec("speed-step", vary=("plant.nothing=*2",)), "no number there to scale"),
        (
            StudySpec("speed-step", vary=("seed=1,2",), seeds=2),
            "the seed is varied by --vary already",
        ),
    ],
)
def test_a_bad_study_is_refused_before_any_run(spec, says):
    with pytest.raises(InputError) as err:
        plan_study(spec)
    assert says in str(err.value)


def test_every_run_equals_its_scenario_run_alone(tmp_path, client):
    spec = StudySpec(
        "speed-step",
        vary=("plant.backlash.width_mm=0.05,0.2", "load.motor_torque_Nm.0.final=uniform(2, 8)"),
        runs=2,
        labels=("PI", "SMC"),
        settings=(*SHORT, "load.motor_torque_Nm.0.time_s=0.02"),
    )
    study = run_study(spec, tmp_path / "s", client=client)
    table = read_table(tmp_path / "s")
    assert len(table) == 8 and study.complete
    assert list(table.columns[:6]) == [
        "run_id",
        "label",
        "sample",
        "status",
        "plant.backlash.width_mm",
        "load.motor_torque_Nm.0.final",
    ]
    assert (table["status"] == "ok").all()
    # paired: each sample is the same plant for both controller sets
    by_label = {label: group.set_index("sample") for label, group in table.groupby("label")}
    values = ["plant.backlash.width_mm", "load.motor_torque_Nm.0.final"]
    assert by_label["PI"][values].equals(by_label["SMC"][values])
    for job in plan_study(spec).jobs[::3]:
        alone = run_scenario(job.scenario, label=job.label).metrics
        row = table[table["run_id"] == run_id_of(job)].iloc[0]
        assert {k: row[k] for k in alone} == pytest.approx(alone, nan_ok=True)
        again = load_scenario(str(tmp_path / "s" / RUNS_FOLDER / run_id_of(job) / "scenario.toml"))
        assert again.plant.backlash.width_mm == job.tags["plant.backlash.width_mm"]
    summary = json.loads((tmp_path / "s" / "summary" / "summary.json").read_text())
    rise = table[table["label"] == "SMC"]["rise_time_s"]
    assert summary["metrics"]["SMC"]["rise_time_s"]["p50"] == pytest.approx(rise.median())
    assert (tmp_path / "s" / "summary" / "distributions.png").stat().st_size > 0
    assert foreign_files(tmp_path / "s" / "summary") == []
    assert foreign_files(tmp_path / "s" / RUNS_FOLDER / run_id_of(plan_study(spec).jobs[0])) == []


def test_a_study_resumes_with_only_the_runs_it_lacks(tmp_path, client):
    spec = StudySpec(
        "speed-step", vary=("seed=integers(0, 9999)",), runs=6, labels=("PI",), settings=SHORT
    )
    full = run_study(spec, tmp_path / "full", client=client).table
    # an interrupted study: the folder as a kill leaves it, some runs finished, the table
    # behind, a dead process's temporary beside them
    shutil.copytree(tmp_path / "full", tmp_path / "cut", symlinks=True)
    runs = tmp_path / "cut" / RUNS_FOLDER
    for run in sorted(runs.iterdir())[2:]:
        shutil.rmtree(run)
    shutil.rmtree(tmp_path / "cut" / "summary")
    (tmp_path / "cut" / METRICS_FILE).unlink()
    dead = runs / ".pi-00003.tmp-999999-0123abcd"
    dead.mkdir()
    (dead / ".emasim-result").write_text('{"kind": "run", "files": []}')
    told = []
    resumed = run_study(
        spec, tmp_path / "cut", client=client, progress=lambda d, t: told.append((d, t))
    )
    assert told[0] == (2, 6) and told[-1] == (6, 6)
    columns = list(full.columns)
    assert resumed.table[columns].equals(full[columns])
    assert not dead.exists()


def test_a_task_run_again_reads_the_runs_it_finished_before(tmp_path, client, monkeypatch):
    """Dask runs a task again when its worker is lost; the runs of it that wrote their folder
    are read from it, not simulated again (their folder cannot be written twice)."""
    from emasim.experiments import runs

    spec = StudySpec("speed-step", vary=("seed=1,2",), labels=("PI",), settings=SHORT)
    study = run_study(spec, tmp_path / "s", client=client)
    job = plan_study(spec).jobs[0]
    folder = tmp_path / "s" / RUNS_FOLDER / run_id_of(job)

    def no_run(*args, **kwargs):
        raise AssertionError("a finished run was simulated again")

    monkeypatch.setattr(runs, "run_scenario", no_run)
    row = run_and_write(job, folder)
    assert row == finished_rows(tmp_path / "s")[run_id_of(job)]
    assert row["steady_error_rms_rpm"] == study.table.iloc[0]["steady_error_rms_rpm"]


def test_another_study_in_the_folder_is_refused_and_left_as_it_was(tmp_path, client):
    spec = StudySpec("speed-step", vary=("seed=1,2",), labels=("PI",), settings=SHORT)
    run_study(spec, tmp_path / "s", client=client)
    before = sorted(p.name for p in (tmp_path / "s" / RUNS_FOLDER).iterdir())
    other = StudySpec("speed-step", vary=("seed=1,3",), labels=("PI",), settings=SHORT)
    with pytest.raises(OutputError, match="holds another study"):
        run_study(other, tmp_path / "s", client=client)
    assert sorted(p.name for p in (tmp_path / "s" / RUNS_FOLDER).iterdir()) == before
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match="emasim did not write"):
        run_study(spec, mine, client=client)
    assert os.listdir(mine) == ["notes.txt"]


def test_a_diverging_run_is_a_row_that_says_so(tmp_path, client):
    spec = StudySpec(
        "speed-step",
        vary=("plant.backlash.stiffness_N_per_m=1e8,1e12",),
        labels=("PI",),
        settings=("duration_s=0.02", "solver.step_s=1e-4"),
    )
    table = run_study(spec, tmp_path / "s", client=client).table
    assert table["status"].iloc[0] == "ok"
    assert table["status"].iloc[1].startswith("diverged: ")
    assert "too large for the backlash contact stiffness" in table["status"].iloc[1]
    meta = json.loads((tmp_path / "s" / RUNS_FOLDER / "pi-00001" / "meta.json").read_text())
    assert meta["status"].startswith("diverged")


def test_the_command_line_refuses_a_bad_spec_in_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "s"
    done = subprocess.run(
        [sys.executable, "-m", "emasim", "study", "speed-step", "--vary", "a.b=beta(1,2)"]
        + ["--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2
    assert done.stderr.strip().startswith("error: --vary a.b: unknown 'beta(...)'")
    assert len(done.stderr.strip().splitlines()) == 1 and not out.exists()


def test_a_study_runs_on_the_scheduler_it_is_given(tmp_path, client):
    spec = StudySpec("speed-step", vary=("seed=1,2",), labels=("PI",), settings=SHORT)
    address = client.scheduler.address
    study = run_study(spec, tmp_path / "s", scheduler=address)
    assert list(study.table["status"]) == ["ok", "ok"]


@pytest.mark.parametrize("address", ["127.0.0.1:8786", "tcp://127.0.0.1:1", "nonsense://x"])
def test_a_scheduler_that_cannot_be_reached_is_one_line(tmp_path, address):
    spec = StudySpec("speed-step", vary=("seed=1,2",), labels=("PI",), settings=SHORT)
    with pytest.raises(InputError, match=f"--scheduler {address}: ") as err:
        run_study(spec, tmp_path / "s", scheduler=address)
    assert "\n" not in str(err.value)


def test_a_summary_is_grouped_by_each_varied_key_that_takes_a_few_values():
    """A grid's key (3 values) and a discrete draw's (2 values) group the summary, each value's
    distribution over its own runs (the other keys pooled: medians checked against numpy);
    a continuous draw (a value a run) and the scenario seed (replicates) do not."""
    variations = [
        parse_variation("plant.backlash.width_mm=0.05,0.1,0.2"),
        parse_variation("plant.friction.scale=discrete(0.5,1.5,2)"),
        parse_variation("plant.load.rudder_inertia_kgm2=uniform(0.9,1.1)"),
        parse_variation("seed=1,2"),
    ]
    rng = np.random.default_rng(0)
    n = 24
    table = pd.DataFrame(
        {
            "run_id": [f"pi-{k:05d}" for k in range(n)],
            "label": ["PI"] * n,
            "sample": range(n),
            "status": ["ok"] * n,
            "plant.backlash.width_mm": np.repeat([0.05, 0.1, 0.2], n // 3),
            "plant.friction.scale": np.tile([0.5, 1.5], n // 2),
            "plant.load.rudder_inertia_kgm2": rng.uniform(0.9, 1.1, n),
            "seed": np.tile([1, 2, 1, 2], n // 4),
            "overshoot_pct": rng.normal(5.0, 1.0, n),
        }
    )
    plan = Plan(None, variations, ["PI"], [])
    assert grouping_keys(table, plan) == ["plant.backlash.width_mm", "plant.friction.scale"]
    for key in grouping_keys(table, plan):
        groups = summarize_by(table, plan, key)
        assert list(groups) == sorted(set(table[key]))
        for value, summary in groups.items():
            chosen = table.loc[table[key] == value, "overshoot_pct"]
            d = summary["PI"]["overshoot_pct"]
            assert d["runs"] == len(chosen) and d["p50"] == pytest.approx(np.median(chosen))


def test_the_command_line_runs_a_study_on_worker_processes(tmp_path):
    out = tmp_path / "s"
    command = [sys.executable, "-m", "emasim", "study", "speed-step", "--label", "PI"]
    command += ["--vary", "plant.backlash.width_mm=0.05,0.1,0.2", "--set", "duration_s=0.02"]
    done = subprocess.run(
        [*command, "--workers", "2", "--out", str(out)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "3 runs in" in done.stderr and "Traceback" not in done.stderr  # an info line
    table = read_table(out)
    assert list(table["plant.backlash.width_mm"]) == [0.05, 0.1, 0.2]
    # the console summary: a block per width, each run's own figure (one run: its median)
    assert "at each plant.backlash.width_mm" in " ".join(done.stdout.split())
    assert done.stdout.count("rise time") == 3
    for width, rise in zip(table["plant.backlash.width_mm"], table["rise_time_s"], strict=True):
        assert f"{width:.4g}" in done.stdout and f"{rise:.4g}" in done.stdout
    again = subprocess.run(
        [*command, "--workers", "2", "--out", str(out)], capture_output=True, text=True
    )
    assert again.returncode == 0 and "3 runs in" in again.stderr  # complete: nothing to run
