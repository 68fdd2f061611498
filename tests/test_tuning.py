"""Fair tuning: one cost, one search, one budget for every controller set; every trial a run
of a job store, so a tuning run again resumes."""

import json
import shutil
import tomllib

import numpy as np
import optuna
import pytest
from typer.testing import CliRunner

from emasim import tuning
from emasim.analysis.report import CHATTER_WEIGHT, CHECK_TOLERANCE, tuning_cost
from emasim.cli import app
from emasim.control.pid import GAIN_SPAN, PositionPID, SpeedPI
from emasim.experiments import batch
from emasim.experiments.batch import dask_client, map_runs
from emasim.experiments.runs import run_scenario
from emasim.experiments.store import read_table
from emasim.scenarios.loader import (
    load_scenario,
    read_scenario_file,
    read_scenario_text,
    validate_scenario,
)
from emasim.search_rules import WIDEN_FACTOR, Budget
from emasim.sim.engine import simulate
from emasim.sim.setup import plant_facts
from emasim.tuning import (
    TUNED_HEADER,
    _controllers_with,
    search_space,
    tune_scenario,
    tune_variant,
    tuned_toml,
    tuning_store,
    with_explicit_gains,
)

SHORT = ["duration_s=0.05", "load.motor_torque_Nm=[]"]


@pytest.fixture
def simulated(monkeypatch):
    """The trials simulated from here on (each trial's run, counted as it starts)."""
    runs = []

    def counted(scenario, *args, **kwargs):
        runs.append(scenario)
        return run_scenario(scenario, *args, **kwargs)

    monkeypatch.setattr(tuning, "run_scenario", counted)
    return runs


def trials_of(result) -> list:
    """A search's trials as (number, params, value, user attributes), to compare searches."""
    return [(t.number, t.params, t.value, t.user_attrs) for t in result.study.trials]


def test_cost_is_tracking_error_plus_a_price_on_chattering():
    """J = IAE(e) / (T R) + RMS_s(e) / R + A_s(e) / R + w TV(iq*) / I_max, e the speed command
    minus the speed reading, the steady window the last 20 % of the run before its end (no
    load step here; the end's row left out, as the step metrics' window), computed here from
    the trace with numpy alone."""
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    result = run_scenario(scenario)
    t = result.t
    error = result["speed_ref_rad_s"] - result["measured_speed_rad_s"]
    scale = 1000 * np.pi / 30
    steady = (t >= t[-1] - 0.2 * (t[-1] - t[0])) & (t < t[-1])
    rms = np.sqrt(np.trapezoid(error[steady] ** 2, t[steady]) / (t[steady][-1] - t[steady][0]))
    tracking = (
        np.trapezoid(np.abs(error), t) / ((t[-1] - t[0]) * scale)
        + rms / scale
        + 0.5 * np.ptp(error[steady]) / scale
    )
    iq = result.data[:, result.columns.index("iq_ref_A")]
    iq[:] = 5.0  # a steady command: no chattering price
    assert tuning_cost(result, 58.0) == pytest.approx(tracking, rel=1e-9)
    iq += np.where(np.arange(len(iq)) % 2 == 0, 1.0, -1.0)  # +-1 A every sample
    jumps = 2.0 * (len(iq) - 1) / (t[-1] - t[0])
    assert tuning_cost(result, 58.0) == pytest.approx(
        tracking + CHATTER_WEIGHT * jumps / 58.0, rel=1e-9
    )


def test_a_pid_cascade_is_tuned_as_five_independent_gains_from_its_bandwidth_design():
    """The PID cascade's knobs are position Kp, Ki, Kd and speed Kp, Ki, each searched over
    GAIN_SPAN either way of the gains the bandwidth rule gives (its starting point)."""
    tuned = load_scenario("bench-step", label="PID")
    designed = tuned.controllers.model_copy(  # a cascade designed by its bandwidths alone
        update={"speed": SpeedPI(bandwidth_Hz=15.0), "position": PositionPID(bandwidth_Hz=1.5)}
    )
    scenario = tuned.model_copy(update={"controllers": designed})
    explicit = with_explicit_gains(scenario.controllers, scenario)
    space = search_space(explicit)
    assert sorted(space) == [
        "position.kd",
        "position.ki_per_s2",
        "position.kp_per_s",
        "speed.ki_A_per_rad",
        "speed.kp_A_s_per_rad",
    ]
    facts = plant_facts(scenario.plant)
    speed, position = scenario.controllers.speed, scenario.controllers.position
    alpha_s = 2 * np.pi * speed.bandwidth_Hz
    j_over_kt = facts.inertia_kgm2 / facts.torque_constant_Nm_per_A
    kd = 0.05  # the PID's default derivative gain
    alpha_p = 2 * np.pi * position.bandwidth_Hz
    starts = {
        "speed.kp_A_s_per_rad": 2 * alpha_s * j_over_kt,
        "speed.ki_A_per_rad": alpha_s**2 * j_over_kt,
        "position.kp_per_s": 2 * alpha_p * (1 + kd),
        "position.ki_per_s2": alpha_p**2 * (1 + kd),
        "position.kd": kd,
    }
    for key, start in starts.items():
        low, high = space[key]
        assert low == pytest.approx(start / GAIN_SPAN) and high == pytest.approx(start * GAIN_SPAN)
    # the same law: the explicit gains run the trace the bandwidth design runs
    before = simulate(scenario.model_copy(update={"duration_s": 0.05}).setup())
    after = simulate(
        scenario.model_copy(update={"duration_s": 0.05, "controllers": explicit}).setup()
    )
    assert np.allclose(before.data, after.data, rtol=1e-12, atol=0, equal_nan=True)


def test_the_neighbourhood_check_records_the_best_neighbour_and_resumes(tmp_path, simulated):
    """After the search, NEIGHBOURS points of a Latin hypercube within x1.5 of each knob about
    the optimum (again about a better one found, at most CHECK_ROUNDS times): the record
    names the last check's best point and its cost over that check's optimum; the points are
    runs of the store, so a second call runs none again and finds the same search."""
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    budget = Budget(trials=3, patience_per_knob=None, widenings=0, neighbours=6)
    store = tuning_store(tmp_path, scenario, seed=0)
    result = tune_variant(scenario, "PI", scenario.controllers, budget, store)
    assert len(simulated) == len(result.study.trials)
    check = result.record()["neighbourhood"]
    assert check["points"] == 6
    checks = result.study.user_attrs["checks"]
    assert 1 <= len(checks) <= tuning.CHECK_ROUNDS
    last = checks[-1]
    neighbours = [
        t for t in result.study.trials if t.user_attrs.get(tuning.NEIGHBOUR, -1) >= last["first"]
    ]
    assert len(neighbours) == 6
    for trial in neighbours:
        for key, value in trial.params.items():
            assert last["centre"][key] / 1.5 <= value <= last["centre"][key] * 1.5
    best = min(neighbours, key=lambda t: t.value)
    assert check["best_cost_ratio"] == pytest.approx(best.value / last["cost"])
    assert result.best == min(last["cost"], best.value)
    converged = check["best_cost_ratio"] >= 1 - CHECK_TOLERANCE
    assert converged or len(checks) == tuning.CHECK_ROUNDS  # checked again until it holds
    simulated.clear()
    again = tune_variant(
        scenario, "PI", scenario.controllers, budget, tuning_store(tmp_path, scenario, seed=0)
    )
    assert simulated == [] and trials_of(again) == trials_of(result)  # nothing ran twice
    assert again.trials == 3  # the search's own trials: the check's are not counted


def test_search_space_covers_both_loops_of_a_cascade():
    scenario = load_scenario("position-step", controllers=["hybrid"])
    space = search_space(scenario.controllers)
    assert "position.adaptation_gain" in space and "speed.observer_bandwidth_Hz" in space
    assert all(lo < hi for lo, hi in space.values())


def test_tuning_starts_from_the_given_gains_never_ends_worse_and_resumes(tmp_path, simulated):
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    store = tuning_store(tmp_path, scenario, seed=1)
    result = tune_variant(scenario, "PI", scenario.controllers, 4, store, seed=1)
    tuned, best, given, study = result.controllers, result.best, result.given, result.study
    # the gains given: those of the comparison's PI set, which the choice starts from, as
    # the independent gains they stand for
    given_gains = scenario.controllers.speed.with_explicit_gains(plant_facts(scenario.plant))
    assert (
        scenario.controllers.speed
        == validate_scenario(read_scenario_file("speed-step")[0]).compare[0].controllers.speed
    )
    assert study.trials[0].params == {
        "speed.kp_A_s_per_rad": given_gains.kp_A_s_per_rad,
        "speed.ki_A_per_rad": given_gains.ki_A_per_rad,
    }
    assert given == study.trials[0].value and best <= given
    assert tuned.speed.kp_A_s_per_rad == pytest.approx(study.best_params["speed.kp_A_s_per_rad"])
    simulated.clear()
    again = tune_variant(
        scenario, "PI", scenario.controllers, 6, tuning_store(tmp_path, scenario, seed=1), seed=1
    )
    complete = [t for t in again.study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(complete) == 6 and len(simulated) == 2  # resumed: two more, not six more
    assert trials_of(again)[:4] == trials_of(result)  # the same four trials, read back


def test_every_controller_set_gets_the_same_budget_and_the_file_records_it(tmp_path):
    """Every set gets the same budget; the store's table holds one row per trial, with its
    set, its gains and every metric of its run, the cost among them."""
    raw, _ = read_scenario_file("speed-step")
    raw["duration_s"] = 0.05
    raw["load"] = {}
    scenario = validate_scenario(raw)
    store = tuning_store(tmp_path, scenario, seed=0)
    tuned_raw, results = tune_scenario(raw, scenario, 3, store)
    assert list(results) == ["PI", "SMC", "ST-SMC", "ST-SMC+GPIO"]
    table = read_table(store.folder)
    assert list(table["set"]) == [label for label in results for _ in range(3)]
    assert set(table["status"]) == {"ok"} and "settling_time_s" in table
    for label, result in results.items():
        rows = table[table["set"] == label]
        costs = [t.value for t in result.study.trials]
        assert list(rows["tuning_cost"]) == costs  # the cost told is the run's own metric
        knobs = list(result.study.best_params)
        assert rows[knobs].to_dict("records") == [t.params for t in result.study.trials]
        assert results[label].best <= results[label].given
    tuned = validate_scenario(tuned_raw)
    assert tuned.tuning["budget"] == "3 trials per controller set"
    assert tuned.tuning["batch"] == 1  # no Dask client: one trial at a time
    assert {label: record.trials for label, record in tuned.tuning["sets"].items()} == {
        label: 3 for label in results
    }
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
            "--save",
            str(save),
        ],
    )
    assert result.exit_code == 0, result.output
    tuned = validate_scenario(tomllib.loads(save.read_text()))
    assert tuned.controllers.speed.name == "adrc"
    record = tuned.tuning["sets"]["speed=adrc"]  # a single run: its controllers label
    assert record.knobs == 2 and record.trials >= 2
    assert tuned.tuning["budget"].startswith("2 trials per controller set")
    (store,) = tuning.STORE_ROOT.glob("jobs-*")  # its trials' runs, in the store
    assert set(read_table(store)["set"]) == {"speed=adrc"}


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
    assert "computation_delay_s = 0.0001  # one sample" in written  # an unchanged value's comment
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
        tuning_store(tmp_path, scenario, seed=0),
        progress=lambda done, total: seen.append((done, total)),
    )
    assert seen == [(0, 3), (1, 3), (2, 3), (3, 3)]


def test_an_optimum_on_a_bound_widens_the_range_and_the_search_goes_on(
    tmp_path, monkeypatch, simulated
):
    """A range far below the speed loop's useful bandwidth (5-6 Hz): it is first stretched to
    the gains given (a 70 Hz design, the first trial), where the optimum sits, on the upper
    bound; that bound moves out by WIDEN_FACTOR, and the next round searches the wider
    range with as many trials; run again, it finds the same search without new trials."""
    monkeypatch.setattr(SpeedPI, "tunable_ranges", lambda self: {"bandwidth_Hz": (5.0, 6.0)})
    monkeypatch.setattr(SpeedPI, "with_explicit_gains", lambda self, plant: self)  # its own knob
    scenario = load_scenario(
        "speed-step",
        controllers=["speed=pi"],
        settings=[*SHORT, "controllers.speed={name = 'pi', bandwidth_Hz = 70}"],
    )
    budget = Budget(trials=3, patience_per_knob=None, widenings=2, neighbours=0)
    result = tune_variant(
        scenario, "PI", scenario.controllers, budget, tuning_store(tmp_path, scenario, 0)
    )
    given = scenario.controllers.speed.bandwidth_Hz
    rounds = result.study.user_attrs["widenings"]
    low, high = result.widened["speed.bandwidth_Hz"]
    assert rounds >= 1 and low == 5.0 and high == pytest.approx(given * WIDEN_FACTOR**rounds)
    assert result.trials == 3 * (rounds + 1) and result.stopped == "budget"
    highs = [t.distributions["speed.bandwidth_Hz"].high for t in result.study.trials]
    assert highs[:3] == [given] * 3 and highs[3] == pytest.approx(given * WIDEN_FACTOR)
    assert result.on_bound == {} or rounds == budget.widenings  # flagged only when out of rounds
    simulated.clear()
    again = tune_variant(
        scenario, "PI", scenario.controllers, budget, tuning_store(tmp_path, scenario, 0)
    )
    assert again.trials == result.trials and again.widened == result.widened
    assert simulated == [] and trials_of(again) == trials_of(result)


def test_the_search_stops_once_converged(tmp_path):
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    # a tolerance of 100 %: converged as soon as the window (2 trials a knob, Kp and Ki) has
    # passed
    budget = Budget(trials=50, patience_per_knob=2, tolerance=1.0, widenings=0, neighbours=0)
    result = tune_variant(
        scenario, "PI", scenario.controllers, budget, tuning_store(tmp_path, scenario, 0)
    )
    assert result.trials == 5 and result.stopped == "converged"
    record = result.record()
    assert {k: record[k] for k in ("trials", "knobs", "stopped")} == {
        "trials": 5,
        "knobs": 2,
        "stopped": "converged",
    }
    # the front: the trials' (chattering, tracking), none beaten on both by another
    points = [(t.user_attrs["chatter"], t.user_attrs["tracking"]) for t in result.study.trials]
    front = record["front"]
    assert front and all(
        list(p) in front or any(q[0] <= p[0] and q[1] <= p[1] for q in front) for p in points
    )
    assert record["tuned_point"] in front
    best = result.study.best_trial
    assert best.value == best.user_attrs["tracking"] + CHATTER_WEIGHT * best.user_attrs["chatter"]


def test_trials_run_in_batches_on_the_study_facility_and_the_search_is_reproducible(
    tmp_path, monkeypatch
):
    """Two workers evaluate two trials at once through map_runs; told in trial order, the
    same seed gives the same trials, and the costs equal a run of each in this process."""
    scenario = load_scenario("position-step", controllers=["pid"], settings=SHORT)
    batches = []

    def recording_map_runs(function, jobs, client, *args, **kwargs):
        batches.append(len(jobs))
        return map_runs(function, jobs, client, *args, **kwargs)

    monkeypatch.setattr(batch, "map_runs", recording_map_runs)
    searches = []
    with dask_client(workers=2, processes=False) as client:
        for k in range(2):
            store = tuning_store(tmp_path / str(k), scenario, 3, client)
            result = tune_variant(scenario, "PID", scenario.controllers, 4, store, 3, None, client)
            searches.append([(t.params, t.value) for t in result.study.trials])
    assert searches[0] == searches[1] and len(searches[0]) == 4
    assert batches == [2, 2, 2, 2]  # each search: two pairs handed to the facility
    params, value = searches[0][-1]
    candidate = scenario.model_copy(
        update={"controllers": _controllers_with(scenario.controllers, params)}
    )
    assert tuning_cost(run_scenario(candidate), scenario.plant.motor.max_current_A) == value


def test_a_killed_tuning_runs_only_the_trials_it_lacks(tmp_path, simulated):
    """A tuning killed while a trial ran (its run folder never published: here, one taken
    away): the same tuning again runs that trial alone, and its search is the one an
    uninterrupted tuning makes."""
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    whole = tune_variant(
        scenario, "PI", scenario.controllers, 4, tuning_store(tmp_path / "a", scenario, 0)
    )
    store = tuning_store(tmp_path / "b", scenario, 0)
    tune_variant(scenario, "PI", scenario.controllers, 4, store)
    lost = sorted((store.folder / "runs").iterdir())[2]
    shutil.rmtree(lost)
    simulated.clear()
    again = tune_variant(
        scenario, "PI", scenario.controllers, 4, tuning_store(tmp_path / "b", scenario, 0)
    )
    assert len(simulated) == 1 and (lost / "metrics.json").is_file()
    assert trials_of(again) == trials_of(whole)
    assert (
        read_table(store.folder)
        .drop(columns="run_id")
        .equals(read_table(tmp_path / "a" / store.folder.name).drop(columns="run_id"))
    )


def test_a_better_neighbour_is_checked_again_about_itself():
    """A check whose best point beats the optimum by more than CHECK_TOLERANCE makes that
    point the optimum, and the next check is centred on it (a cost whose minimum lies 30 %
    above the first optimum's knobs, evaluated without simulating)."""
    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=SHORT)
    controllers = with_explicit_gains(scenario.controllers, scenario)
    start = {
        "speed.kp_A_s_per_rad": controllers.speed.kp_A_s_per_rad,
        "speed.ki_A_per_rad": controllers.speed.ki_A_per_rad,
    }
    target = {key: 1.3 * value for key, value in start.items()}

    def cost(params):
        return 1.0 + sum(np.log(params[k] / target[k]) ** 2 for k in params)

    def evaluate_params(points, numbers):
        return [(cost(p), cost(p), 0.0) for p in points]

    study = optuna.create_study()
    study.add_trial(
        optuna.trial.create_trial(
            params=start,
            distributions={
                k: optuna.distributions.FloatDistribution(v / 10, v * 10, log=True)
                for k, v in start.items()
            },
            value=cost(start),
        )
    )
    first = tuning.check_neighbourhood(study, controllers, 8, 0, 4, evaluate_params)
    assert first["best_cost_ratio"] < 1 - CHECK_TOLERANCE and study.best_value < cost(start)
    second = tuning.check_neighbourhood(study, controllers, 8, 0, 4, evaluate_params)
    checks = study.user_attrs["checks"]
    assert len(checks) == 2 and checks[1]["centre"] == first["best_point"]
    assert second["points"] == 8  # its own points, not the first check's
    assert study.best_value <= checks[1]["cost"]
