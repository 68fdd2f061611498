"""The integration-step check of the headline verdicts: its runs (every bench controller set at
half and twice the shipped step), its table and what its lines say. The figures a reproduction
measures are checked against docs/integration_step.json in tests/test_reproduce.py."""

import math

import pytest

from emasim.analysis.integration_step import (
    HOLDS,
    TURNS,
    margins,
    markdown,
    spread,
    step_line,
    step_lines,
    verdict,
)
from emasim.experiments.batch import Job
from emasim.experiments.integration_step import STEP_FACTORS, step_jobs, step_table
from emasim.scenarios.loader import load_scenario

STEPS = [5e-6, 1e-5, 2e-5]


def entry(**values) -> dict:
    return {
        "experiment": "bench-sine",
        "metric": "tracking_error_deg",
        "unit": "deg",
        "step_s": STEPS,
        "shipped_step_s": 1e-5,
        "values": {label.replace("_", " "): v for label, v in values.items()},
    }


def test_a_verdict_holds_only_when_its_sign_is_the_same_at_every_step():
    steady = entry(PID=[1.0, 1.0, 1.0], hybrid=[0.5, 0.9, 0.2])
    assert margins(steady, "PID") == pytest.approx([50.0, 10.0, 80.0])
    assert verdict(steady, "PID") == HOLDS
    losing = entry(PID=[1.0, 1.0, 1.0], hybrid=[1.5, 1.1, 2.0])
    assert verdict(losing, "PID") == HOLDS
    assert "the hybrid loses at every step" in step_line("x_reduction", losing, "PID")
    turning = entry(PID=[1.0, 1.0, 1.0], hybrid=[0.99, 0.97, 1.05])
    assert verdict(turning, "PID") == TURNS
    line = step_line("sine_displacement_lag_reduction", turning, "PID")
    assert line.startswith("sine displacement lag against PID: the hybrid wins at 5e-06 s, ")
    assert "1e-05 s (shipped) and loses at 2e-05 s (margin +1 % at 5e-06 s" in line
    assert line.endswith("the verdict turns with the integration step, so the simulation "
                         "does not settle it.")  # fmt: skip
    tie = entry(PID=[1.0, 1.0, 1.0], hybrid=[0.9, 1.0, 0.9])  # a tie is no win
    assert verdict(tie, "PID") == TURNS


def test_a_diverged_run_or_a_baseline_at_zero_is_a_loss_for_the_hybrid():
    """tables.json writes a diverged run's figure as null: the margin of the verdict map
    (emasim.analysis.verdict_map.margin) reads it as infinite."""
    diverged = entry(PID=[1.0, None, 1.0], hybrid=[0.5, 0.5, None])
    assert margins(diverged, "PID") == [50.0, 100.0, -math.inf]
    assert verdict(diverged, "PID") == TURNS
    still = entry(PID=[0.0, 0.0, 0.0], hybrid=[0.04, 0.04, 0.05])
    assert margins(still, "PID") == [-math.inf] * 3
    assert "(margin -inf at 5e-06 s" in step_line("x_reduction", still, "PID")
    assert spread(still, "PID") == 0.0 and spread(still, "hybrid") == pytest.approx(0.25)
    assert spread(entry(PID=[0.0, 0.0, 0.1], hybrid=[1, 1, 1]), "PID") is None
    assert spread(diverged, "hybrid") is None


def test_the_lines_and_the_report_section_cover_every_figure_and_baseline():
    table = {
        "sine_displacement_lag_reduction": entry(
            PID=[0.21, 0.14, 0.16], industrial_PID=[0.08, 0.08, 0.08], hybrid=[0.08, 0.07, 0.09]
        )
    }
    lines = step_lines(table)
    assert len(lines) == 2 + 1  # two baselines, then how far the figure moves
    assert lines[0].endswith("it holds.") and "turns with the integration step" in lines[1]
    assert lines[2].endswith("PID 50 %, industrial PID 0 %, hybrid 29 %.")
    section = "\n\n".join(markdown(table))
    assert "| figure | controller set | 5e-06 s | 1e-05 s (shipped) | 2e-05 s |" in section
    assert (
        "| bench-sine: tracking_error_deg (deg) | industrial PID | 0.0800 | 0.0800 | 0.0800 |"
        in section
    )


def test_every_bench_controller_set_runs_at_half_and_twice_its_step():
    """The jobs of the shipped bench experiments: each set at 5e-6 and 2e-5 s, the control
    period and the computation delay whole numbers of the new step, nothing else changed."""
    chosen = {name: load_scenario(name) for name in ("bench-step", "bench-sine", "speed-step")}
    jobs = step_jobs(chosen)
    assert {job.tags["experiment"] for job in jobs} == {"bench-step", "bench-sine"}
    for name in ("bench-step", "bench-sine"):
        shipped = chosen[name]
        labels = [label for label, _ in shipped.variants()]
        ran = [job for job in jobs if job.tags["experiment"] == name]
        assert [(job.tags["step_s"], job.label) for job in ran] == [
            (factor * shipped.solver.step_s, label) for factor in STEP_FACTORS for label in labels
        ]
        for job in ran:
            solver = job.scenario.solver
            assert solver.step_s == job.tags["step_s"]
            assert solver.substeps * solver.step_s == pytest.approx(solver.sample_period_s)
            delay = job.scenario.loop.computation_delay_s / solver.step_s
            assert delay == pytest.approx(round(delay))
            single = dict(shipped.variants())[job.label]
            assert job.scenario.model_copy(update={"solver": single.solver}) == single


def test_the_table_puts_the_shipped_runs_between_the_others():
    chosen = {"bench-sine": load_scenario("bench-sine")}
    jobs = [
        Job(None, label, {"experiment": "bench-sine", "step_s": step})
        for step in (5e-6, 2e-5)
        for label in ("PID", "hybrid")
    ]
    measured = [
        {"tracking_error_deg": v, "velocity_fluctuation_deg_s": 10 * v} for v in (1, 2, 3, 4)
    ]
    shipped = {
        "bench-sine": {"PID": measured[0] | {"tracking_error_deg": 5.0}, "hybrid": measured[1]}
    }
    table = step_table(chosen, jobs, measured, shipped)
    assert set(table) == {"sine_displacement_lag_reduction", "sine_speed_fluctuation_reduction"}
    lag = table["sine_displacement_lag_reduction"]
    assert lag["step_s"] == STEPS and lag["shipped_step_s"] == 1e-5
    assert lag["values"] == {"PID": [1, 5.0, 3], "hybrid": [2, 2, 4]}
    assert table["sine_speed_fluctuation_reduction"]["values"]["hybrid"] == [20, 20, 40]
