"""The robustness of the headline verdicts (emasim.experiments.robustness): the uncertainty it
samples, and its statistics on tables with known answers."""

import numpy as np
import pandas as pd
import pytest
from helpers import refused_in_one_line
from scipy.stats import beta

from emasim.analysis.paper_report import robustness_lines
from emasim.errors import InputError
from emasim.experiments.robustness import (
    COST,
    improvement_pct,
    median_interval,
    paired,
    spec_for,
    verdict,
    verdicts,
)
from emasim.experiments.study import plan_study
from emasim.scenarios.loader import load_scenario


def test_the_uncertainty_spans_the_stated_ranges_around_the_nominal_plant():
    jobs = plan_study(spec_for("bench-step", 40)).jobs
    nominal = load_scenario("bench-step").plant
    assert {job.label for job in jobs} == {"PID", "industrial PID", "hybrid"}
    for job in jobs:
        p = job.scenario.plant
        assert 0.5 <= p.friction.coulomb_Nm / nominal.friction.coulomb_Nm <= 1.5
        assert p.friction.static_Nm / p.friction.coulomb_Nm == pytest.approx(
            nominal.friction.static_Nm / nominal.friction.coulomb_Nm
        )
        assert 0.05 <= p.backlash.width_mm <= 0.2
        assert len(set(p.linkage.hinge_clearance_mm)) == 1
        assert 0.0 <= p.linkage.hinge_clearance_mm[0] <= 0.05
        factor = p.rudder_shaft.disk_inertia_kgm2 / nominal.rudder_shaft.disk_inertia_kgm2
        assert 0.8 <= factor <= 1.2
        assert p.linkage.rudder_inertia_kgm2 == pytest.approx(
            factor * nominal.linkage.rudder_inertia_kgm2
        )
        assert 0.0 <= p.load_motor.preload_Nm <= 94.5  # the loader's rating
    # the gains stay at their nominal tuning
    tuned = dict(load_scenario("bench-step").variants())
    for job in jobs:
        assert job.scenario.controllers == tuned[job.label].controllers
    # paired: sample k is the same plant for both sets
    by_sample = {}
    for job in jobs:
        by_sample.setdefault(job.tags["sample"], []).append(job.scenario.plant)
    assert all(all(p == plants[0] for p in plants) for plants in by_sample.values())


def test_the_median_interval_of_ten_is_the_second_and_ninth_values():
    # binomial(10, 1/2): P(B <= 1) = 11/1024 <= 0.025 < P(B <= 2) = 56/1024
    x = np.array([7.0, 3.0, 9.0, 1.0, 5.0, 2.0, 8.0, 4.0, 10.0, 6.0])
    assert median_interval(x) == (2.0, 9.0)
    assert median_interval(np.arange(5.0)) == (-np.inf, np.inf)  # too few for 95 %


def test_the_median_interval_covers_the_true_median_at_least_95_percent():
    rng = np.random.default_rng(0)
    trials = 2000
    covered = sum(
        low <= 0.0 <= high
        for low, high in (median_interval(rng.standard_cauchy(51)) for _ in range(trials))
    )
    assert covered / trials >= 0.95 - 3 * np.sqrt(0.95 * 0.05 / trials)


def test_a_verdict_counts_wins_and_takes_the_median_gain():
    pid = np.linspace(1.0, 2.0, 200)
    hybrid = np.where(np.arange(200) < 150, 0.5 * pid, 2.0 * pid)  # 150 wins of 200
    v = verdict(pid, hybrid)
    assert v["runs"] == 200 and v["win_rate"] == 0.75
    assert v["median_improvement_pct"] == pytest.approx(50.0)
    assert v["ci95_pct"] == pytest.approx([50.0, 50.0])
    # Clopper-Pearson from the beta distribution
    assert v["win_rate_ci95"] == pytest.approx(
        [beta.ppf(0.025, 150, 51), beta.ppf(0.975, 151, 50)], rel=1e-9
    )


def test_a_diverged_run_loses_and_both_diverged_is_no_sample():
    pid = np.array([1.0, np.inf, 1.0, np.inf])
    hybrid = np.array([np.inf, 1.0, 0.5, np.inf])
    assert list(improvement_pct(pid, hybrid)[:3]) == [-np.inf, 100.0, 50.0]
    v = verdict(pid, hybrid)
    assert v["runs"] == 3 and v["win_rate"] == pytest.approx(2 / 3)


def study_table(pid: list, hybrid: list, statuses=None) -> pd.DataFrame:
    """A study table of a cost column, the rows shuffled (pairing goes by sample)."""
    n = len(pid)
    rows = [
        {"run_id": f"{lb}-{k}", "label": lb, "sample": k, "status": "ok", COST: value}
        for lb, values in (("PID", pid), ("hybrid", hybrid))
        for k, value in enumerate(values)
    ]
    for k, status in (statuses or {}).items():
        rows[n + k]["status"] = status
    return pd.DataFrame(rows).sample(frac=1.0, random_state=1)


def test_pairs_are_taken_by_sample_and_a_diverged_run_is_infinite():
    table = study_table([1.0, 2.0, 3.0], [-0.5, 4.0, 1.0], {2: "diverged: t = 1 s"})
    pid, hybrid = paired(table, COST)
    assert list(pid) == [1.0, 2.0, 3.0]
    assert list(hybrid) == [0.5, 4.0, np.inf]  # magnitudes; the diverged run is inf


def test_the_verdicts_and_their_report_lines():
    table = study_table([2.0] * 20, [1.0] * 18 + [3.0] * 2)
    out = verdicts({"bench-step": table})
    cost = out["bench_step_tuning_cost"]
    assert cost["scenario"] == "bench-step" and cost["runs"] == 20
    assert cost["win_rate"] == 0.9 and cost["median_improvement_pct"] == 50.0
    assert "bench_sine_tuning_cost" not in out  # no table for it
    (line,) = [ln for ln in robustness_lines(out) if ln.startswith("bench step tuning cost")]
    assert "lower than PID's on 90 % of 20 plants" in line
    assert "lower with probability 90 %" in line


def test_wear_scales_each_key_by_its_level_and_reads_the_degradation():
    from emasim.experiments import wear

    jobs = plan_study(wear.spec_for("bench-sine")).jobs
    nominal = load_scenario("bench-sine").plant
    worn = [job for job in jobs if job.label == "hybrid"][-1].scenario.plant
    assert worn.backlash.width_mm == pytest.approx(3 * nominal.backlash.width_mm)
    assert worn.linkage.hinge_clearance_mm == pytest.approx(
        [5 * c for c in nominal.linkage.hinge_clearance_mm]
    )
    assert worn.friction.static_Nm == pytest.approx(2 * nominal.friction.static_Nm)
    rows = [
        {"run_id": f"{lb}-{k}", "label": lb, "sample": k, "status": "ok", wear.LEVEL: k}
        | {COST: (k + 1) * (2.0 if lb == "PID" else 1.0)}
        for lb in ("PID", "hybrid")
        for k in range(wear.LEVELS)
    ]
    out = wear.degradation({"bench-sine": pd.DataFrame(rows)})
    assert out["bench_sine_tuning_cost"]["PID"] == [2.0, 4.0, 6.0, 8.0, 10.0]
    assert out["bench_sine_tuning_cost"]["hybrid"] == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_the_command_lines_default_is_the_studys():
    from typer.main import get_command

    from emasim.cli import app
    from emasim.experiments.robustness import DEFAULT_RUNS

    (runs,) = [p for p in get_command(app).commands["reproduce"].params if p.name == "runs"]
    assert runs.default == DEFAULT_RUNS


def test_the_sensitivity_names_the_parameter_the_improvement_follows():
    from emasim.experiments.robustness import UNCERTAINTY, sensitivity

    backlash = "plant.backlash.width_mm"
    assert any(spec.startswith(backlash + "=") for spec in UNCERTAINTY)
    rng = np.random.default_rng(4)
    n = 50
    width = rng.uniform(0.05, 0.2, n)
    noise = rng.uniform(0.0, 1.0, n)  # another sampled column the gain does not follow
    hybrid = 1.0 - 4.0 * width  # better the wider the gap: the gain rises with the width
    rows = [
        {"run_id": f"{lb}-{k}", "label": lb, "sample": k, "status": "ok"}
        | {backlash: width[k], "plant.load_motor.preload_Nm": noise[k], COST: value}
        for lb, values in (("PID", np.ones(n)), ("hybrid", hybrid))
        for k, value in enumerate(values)
    ]
    found = sensitivity(pd.DataFrame(rows), COST)
    assert found["parameter"] == backlash and found["spearman"] == pytest.approx(1.0)


def series_values() -> dict:
    """What emasim identify --at found on two traces of a bench whose friction, backlash and
    clearance grew: each key's value at each date."""
    from emasim.experiments.variation import FACTOR

    friction = (
        "plant.friction.coulomb_Nm,plant.friction.static_Nm,plant.friction.viscous_Nms_per_rad"
    )
    return {
        friction + FACTOR: [1.0, 1.5],
        "plant.backlash.width_mm": [0.1, 0.2],
        "plant.linkage.hinge_clearance_mm": [0.01, 0.03],
    }


def test_the_wear_study_runs_the_bench_at_each_identified_row(tmp_path):
    """The identified values over an actuator's life are the wear study's input: each row's
    scenario holds them (a factor on the bench's own friction), and the degradation is read
    against the rows' dates or cycle counts."""
    from emasim.experiments import wear
    from emasim.experiments.batch import dask_client
    from emasim.experiments.study import StudySpec

    values = series_values()
    nominal = load_scenario("bench-sine").plant
    jobs = plan_study(
        StudySpec("bench-sine", vary=(wear.series_variation(values, "bench-sine"),))
    ).jobs
    worn = [job for job in jobs if job.label == "hybrid"][-1].scenario.plant
    assert worn.backlash.width_mm == pytest.approx(0.2)
    assert worn.linkage.hinge_clearance_mm == pytest.approx([0.03] * 4)
    assert worn.friction.coulomb_Nm == pytest.approx(1.5 * nominal.friction.coulomb_Nm)
    assert worn.friction.viscous_Nms_per_rad == pytest.approx(
        1.5 * nominal.friction.viscous_Nms_per_rad
    )
    with dask_client(processes=False, workers=1) as client:
        out = wear.run_wear_series(
            values,
            ["0", "5000"],
            root=tmp_path,
            client=client,
            scenarios=("bench-step",),
            settings=("duration_s=0.2",),
        )
    entry = out["bench_step_tuning_cost"]
    assert entry["at"] == ["0", "5000"] and entry["levels"] == [0, 1]
    assert all(np.isfinite(entry[label]).all() for label in ("PID", "hybrid"))
    with pytest.raises(InputError, match="no single non-zero number"):
        wear.series_variation({"plant.mass_kg": [80.0, 90.0]}, "bench-sine")


def test_runs_without_robustness_is_refused():
    """``reproduce --runs 20`` ran the reproduction and ignored the 20 (issue 50); --seed
    alone chooses whose stored studies the report reads, so it stays."""
    refused_in_one_line(["reproduce", "--runs", "20"], "--runs applies to --robustness")
