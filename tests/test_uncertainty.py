"""The Monte Carlo's uncertainty table (emasim.experiments.uncertainty): every range validates
on the bench experiments, docs/paper.md's table is the code's, the verdicts' sensitivity to each
parameter's thirds, and the draws' --seed."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from emasim.experiments import robustness, study
from emasim.experiments.study import plan_study, resolved_value
from emasim.experiments.uncertainty import (
    ROWS,
    SEED,
    TABLE_BLOCK,
    UNCERTAINTY,
    markdown,
)
from emasim.experiments.variation import parse_variation
from emasim.page_blocks import block_of
from emasim.scenarios.loader import load_scenario

PAPER = Path(__file__).resolve().parents[1] / "docs" / "paper.md"


def test_the_docs_hold_the_codes_table():
    text = PAPER.read_text(encoding="utf-8")
    assert block_of(text, TABLE_BLOCK) == markdown(), "docs/paper.md's table differs from ROWS"


def test_every_row_has_a_name_and_a_reason_and_the_issues_parameters_are_sampled():
    assert UNCERTAINTY == robustness.UNCERTAINTY
    assert len({row.name for row in ROWS}) == len(ROWS)
    assert all(len(row.reason) > 20 for row in ROWS)
    keys = {k for row in ROWS for k in parse_variation(row.spec).keys}
    for key in (
        "plant.compliance.stiffness_N_per_m",
        "plant.compliance.damping_Ns_per_m",
        "plant.anchorage.stiffness_N_per_m",
        "plant.anchorage.damping_Ns_per_m",
        "plant.rudder_shaft.stiffness_Nm_per_rad",
        "plant.rudder_shaft.damping_Nms_per_rad",
        "plant.linkage.contact.stiffness_N_per_mm_e",
        "plant.load_motor.bandwidth_Hz",
        "plant.load_motor.preload_Nm",
        "loop.computation_delay_s",
        "sensors.speed.filter_time_constant_s",
        "plant.motor.flux_linkage_Wb",
        "plant.motor.inertia_kgm2",
        "plant.motor.resistance_ohm",
        "plant.motor.inductance_q_H",
        "sensors.rudder.accuracy_error",
        "plant.backlash.width_mm",
        "plant.linkage.hinge_clearance_mm",
        SEED,
    ):
        assert key in keys


def _extremes(spec: str) -> str:
    """``spec`` with its distribution replaced by the grid of its two ends."""
    v = parse_variation(spec)
    a, b = v.distribution[1][:2]
    return f"{v.name}={'*' if v.relative else ''}[{a!r}, {b!r}]"


@pytest.mark.parametrize("scenario", robustness.SCENARIOS)
def test_each_range_validates_at_both_ends_on_its_own_keys(scenario):
    nominal = load_scenario(scenario).model_dump(mode="json")
    for row in ROWS:
        v = parse_variation(row.spec)
        if row.name == SEED:
            continue
        jobs = plan_study(
            robustness.StudySpec(scenario, vary=(_extremes(row.spec),), labels=("PID",))
        ).jobs
        ends = v.distribution[1][:2]
        assert len(jobs) == 2, row.name
        for job, end in zip(jobs, ends, strict=True):
            got = job.scenario.model_dump(mode="json")
            for key in v.keys:
                base = resolved_value(nominal, key)
                want = np.multiply(base, end) if v.relative else end
                assert np.all(np.isclose(resolved_value(got, key), want, rtol=1e-9)), (
                    row.name,
                    key,
                )


def test_the_delay_is_drawn_in_whole_solver_steps_and_the_encoder_error_within_its_class():
    jobs = plan_study(
        robustness.StudySpec("bench-step", vary=UNCERTAINTY, runs=30, labels=("PID",))
    )
    jobs = jobs.jobs
    solver = load_scenario("bench-step").solver
    delays = {round(job.scenario.loop.computation_delay_s / solver.step_s, 6) for job in jobs}
    half_to_one_period = {float(n) for n in range(solver.substeps // 2, solver.substeps + 1)}
    assert delays == half_to_one_period
    arcsec = np.pi / (180 * 3600)
    assert all(0 <= job.scenario.sensors.rudder.accuracy_error <= 60 * arcsec for job in jobs)


def thirds_table() -> pd.DataFrame:
    """Nine plants (PID 1.0 on each; the hybrid wins on plants 0, 1 and 3) and a tenth on
    which both diverged; backlash 1..9, preload a shuffle with a win in each third, the delay
    the same on all."""
    backlash = [1, 2, 3, 4, 5, 6, 7, 8, 9, 5]
    preload = [10, 40, 80, 70, 20, 30, 50, 60, 90, 50]
    hybrid = [0.5, 0.5, 2.0, 0.5, 2.0, 2.0, 2.0, 2.0, 2.0, 0.0]
    rows = []
    for label, values in (("PID", [1.0] * 10), ("hybrid", hybrid)):
        for k, value in enumerate(values):
            rows.append(
                {"run_id": f"{label}-{k}", "label": label, "sample": k}
                | {"status": "diverged: t = 1 s" if k == 9 else "ok"}
                | {
                    "plant.backlash.width_mm": backlash[k],
                    "plant.load_motor.preload_Nm": preload[k],
                }
                | {"loop.computation_delay_s": 1.0, SEED: k, robustness.COST: value}
            )
    return pd.DataFrame(rows)


def test_the_win_rate_in_each_parameters_thirds_and_what_moves_it_most():
    out = robustness.thirds(thirds_table(), robustness.COST)
    rates = out["sensitivity_thirds"]
    # backlash thirds {1,2,3} {4,5,6} {7,8,9}: wins 2, 1, 0 of 3 (plant 9 diverged on both)
    assert rates["backlash"] == pytest.approx([2 / 3, 1 / 3, 0.0])
    # preload thirds {10,20,30} {40,50,60} {70,80,90}: plants {0,4,5} {1,6,7} {3,2,8}
    assert rates["preload"] == pytest.approx([1 / 3, 1 / 3, 1 / 3])
    assert rates["computation delay"] == [pytest.approx(1 / 3), None, None]  # all on one value
    assert "seed" not in rates
    assert out["moves_most"] == {"parameter": "backlash", "spread": pytest.approx(2 / 3)}


def test_the_verdicts_carry_the_sensitivity_and_the_report_a_line_for_it():
    from emasim.analysis.paper_report import robustness_lines

    out = robustness.verdicts({"bench-step": thirds_table()})
    cost = out["bench_step_tuning_cost"]
    pid = cost["against"]["PID"]
    assert pid["moves_most"]["parameter"] == "backlash"
    assert cost["sensitivity_thirds"]["backlash"] == pytest.approx([2 / 3, 1 / 3, 0.0])
    lines = [ln for ln in robustness_lines(out) if "moves the win rate most" in ln]
    assert lines == [
        "bench step tuning cost, what moves the win rate most (the win rate in its lower / "
        "middle / upper third): against PID backlash (67 / 33 / 0 %)."
    ]


def test_the_seed_draws_other_plants_into_another_folder(monkeypatch, tmp_path):
    default = robustness.spec_for("bench-step", 3)
    other = robustness.spec_for("bench-step", 3, seed=7)
    assert default.seed == robustness.DEFAULT_SEED == 0 and other.seed == 7
    a, b = (plan_study(s).jobs[0].tags for s in (default, other))
    assert a["plant.backlash.width_mm"] != b["plant.backlash.width_mm"]
    assert robustness.study_folder("bench-step", 3, tmp_path) != robustness.study_folder(
        "bench-step", 3, tmp_path, seed=7
    )
    seen = []

    class Done:
        table = thirds_table()

    def fake_study(spec, folder, **_):
        seen.append((spec.seed, folder))
        return Done()

    monkeypatch.setattr(study, "run_study", fake_study)  # what run_studies calls
    robustness.run_robustness(3, root=tmp_path, seed=7)
    assert seen == [
        (7, robustness.study_folder(name, 3, tmp_path, seed=7)) for name in robustness.SCENARIOS
    ]


def test_reproduce_passes_its_seed_to_the_monte_carlo(monkeypatch, tmp_path):
    from typer.testing import CliRunner

    from emasim.cli import app
    from emasim.experiments import reproduction

    seen = {}

    def fake(out, **kwargs):
        seen.update(kwargs)
        return tmp_path

    monkeypatch.setattr(reproduction, "reproduce", fake)
    result = CliRunner().invoke(app, ["reproduce", "--robustness", "--seed", "7", "--runs", "10"])
    assert result.exit_code == 0, result.output
    assert seen["robustness_seed"] == 7 and seen["robustness_runs"] == 10
    CliRunner().invoke(app, ["reproduce"])
    assert seen["robustness_seed"] == robustness.DEFAULT_SEED and seen["robustness_runs"] is None


def test_a_discrete_draw_is_one_of_its_evenly_spaced_values():
    from emasim.errors import InputError

    v = parse_variation("a.b=*discrete(0.5, 1, 6)")
    rng = np.random.default_rng(0)
    drawn = {v.draw(rng) for _ in range(200)}
    assert drawn == {0.5, 0.6, 0.7, 0.8, 0.9, 1.0}
    for bad in ("a.b=discrete(1, 0.5, 6)", "a.b=discrete(0, 1, 1)", "a.b=discrete(0, 1, 2.5)"):
        with pytest.raises(InputError, match="discrete"):
            parse_variation(bad)
