"""Fair tuning: one cost, one search, one budget for every controller set; resumable."""

import json
import tomllib

import numpy as np
import optuna
import pytest
from typer.testing import CliRunner

from emasim.analysis.report import CHATTER_WEIGHT, tuning_cost
from emasim.cli import app
from emasim.scenarios.loader import (
    load_scenario,
    read_scenario_file,
    read_scenario_text,
    validate_scenario,
)
from emasim.sim.engine import simulate
from emasim.tuning import (
    TUNED_HEADER,
    search_space,
    study_key,
    tune_scenario,
    tune_variant,
    tuned_toml,
)

SHORT = ["duration_s=0.05", "load.motor_torque_Nm=[]"]


def test_cost_is_tracking_error_plus_a_price_on_chattering():
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    result = simulate(scenario.setup())
    t = result.t
    error = result["speed_ref_rad_s"] - result["motor_speed_rad_s"]
    tracking = np.trapezoid(np.abs(error), t) / ((t[-1] - t[0]) * 1000 * np.pi / 30)
    iq = result.data[:, result.columns.index("iq_ref_A")]
    iq[:] = 5.0  # a steady command: no chattering price
    assert tuning_cost(result, 58.0) == pytest.approx(tracking, rel=1e-12)
    iq += np.where(np.arange(len(iq)) % 2 == 0, 1.0, -1.0)  # +-1 A every sample
    jumps = 2.0 * (len(iq) - 1) / (t[-1] - t[0])
    assert tuning_cost(result, 58.0) == pytest.approx(
        tracking + CHATTER_WEIGHT * jumps / 58.0, rel=1e-12
    )


def test_search_space_covers_both_loops_of_a_cascade():
    scenario = load_scenario("position-step", controllers=["hybrid"])
    space = search_space(scenario.controllers)
    assert "position.adaptation_gain" in space and "speed.observer_bandwidth_Hz" in space
    assert all(lo < hi for lo, hi in space.values())


def test_tuning_starts_from_the_given_gains_never_ends_worse_and_resumes(tmp_path):
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    tuned, best, given, study = tune_variant(
        scenario, "PI", scenario.controllers, 4, storage, seed=1
    )
    # the gains given: those of the comparison's PI set, which the choice starts from
    given_gain = scenario.controllers.speed.bandwidth_Hz
    assert (
        given_gain
        == read_scenario_file("speed-step")[0]["compare"][0]["controllers"]["speed"]["bandwidth_Hz"]
    )
    assert study.trials[0].params == {"speed.bandwidth_Hz": given_gain}
    assert given == study.trials[0].value and best <= given
    assert tuned.speed.bandwidth_Hz == pytest.approx(study.best_params["speed.bandwidth_Hz"])
    *_, again = tune_variant(scenario, "PI", scenario.controllers, 6, storage, seed=1)
    complete = [t for t in again.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(complete) == 6  # resumed: two more, not six more


def test_every_controller_set_gets_the_same_budget_and_the_file_records_it(tmp_path):
    raw, _ = read_scenario_file("speed-step")
    raw["duration_s"] = 0.05
    raw["load"] = {}
    scenario = validate_scenario(raw)
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    tuned_raw, costs = tune_scenario(raw, scenario, 3, storage)
    assert list(costs) == ["PI", "SMC", "ST-SMC", "ST-SMC+GPIO"]
    for label, variant in scenario.variants():
        name = f"speed-step:{label}:{study_key(variant)}"
        study = optuna.load_study(study_name=name, storage=storage)
        assert len(study.trials) == 3
        assert costs[label][1] <= costs[label][0]
    tuned = validate_scenario(tuned_raw)
    assert tuned.tuning["trials_per_controller_set"] == 3
    assert [v.controllers.speed.name for v in tuned.compare] == [
        "pi",
        "smc",
        "st-improved",
        "st-gpio",
    ]


def test_tune_command_writes_a_valid_scenario(tmp_path):
    save = tmp_path / "tuned.toml"
    result = CliRunner().invoke(
        app,
        [
            "tune",
            "speed-step",
            "-c",
            "speed=adrc",
            *sum([["--set", s] for s in SHORT], []),
            "--trials",
            "2",
            "--storage",
            f"sqlite:///{tmp_path / 's.db'}",
            "--save",
            str(save),
        ],
    )
    assert result.exit_code == 0, result.output
    tuned = validate_scenario(tomllib.loads(save.read_text()))
    assert tuned.controllers.speed.name == "adrc" and tuned.tuning


def test_the_tuned_file_keeps_the_scenario_files_comments_and_layout():
    text, _ = read_scenario_text("bench-step")
    raw = tomllib.loads(text)
    tuned = json.loads(json.dumps(raw))
    tuned["compare"][0]["controllers"]["speed"]["bandwidth_Hz"] = 7.5
    tuned["tuning"]["seed"] = 3
    written = tuned_toml(tuned, "bench-step", text)
    assert written.startswith(TUNED_HEADER)
    assert tomllib.loads(written) == tuned
    comments = [line for line in text.splitlines() if line.lstrip().startswith("#")]
    assert comments and all(line in written.splitlines() for line in comments)
    assert "preload_Nm = 200.0  # ours" in written  # an inline comment of an unchanged value
    again = tuned_toml(tuned, "bench-step", written)  # re-tuning a tuned file: one header
    assert again == written


def test_tuning_reports_each_trial(tmp_path):
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    seen = []
    tune_variant(
        scenario,
        "PI",
        scenario.controllers,
        3,
        f"sqlite:///{tmp_path / 's.db'}",
        progress=lambda done, total: seen.append((done, total)),
    )
    assert seen == [(0, 3), (1, 3), (2, 3), (3, 3)]
