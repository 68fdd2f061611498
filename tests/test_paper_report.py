"""The report's tables and page (emasim.analysis.paper_report), on known inputs: numbers in
fixed point with three significant figures, text left and numbers right, controller tables
transposed with their units, flags as yes/no on both sides, formulas kept literal, the page
from its template with the title escaped."""

import pytest

from emasim.analysis import paper_report as pr
from emasim.analysis.tables import number_cell


def test_numbers_have_three_significant_figures_in_fixed_point():
    assert [number_cell(v) for v in (1110.3, 0.0123, 4.8049, 12.0, 0.0)] == [
        "1110",
        "0.0123",
        "4.80",
        "12.0",
        "0",
    ]
    assert number_cell(2.5e-5) == "2.5e-05" and number_cell(3.2e7) == "3.2e+07"
    assert number_cell(None) == "-" and number_cell(True) == "yes"


def test_tables_align_text_left_and_numbers_right():
    table = pr.markdown_table(["metric", "unit", "PID"], [["rise_time_s", "s", 0.0123]])
    assert table.splitlines()[1] == "|:---|:---|---:|"


def test_a_controller_table_is_transposed_with_units():
    rows = [
        {"controller": "PI", "rise_time_s": 0.01, "load_dip_rpm": 1110.3},
        {"controller": "SMC", "rise_time_s": 0.02, "load_dip_rpm": 900.0},
    ]
    lines = pr._dict_rows_markdown(rows).splitlines()
    assert lines[0] == "| metric | unit | PI | SMC |"
    assert lines[2] == "| rise_time_s | s | 0.0100 | 0.0200 |"
    assert lines[3] == "| load_dip_rpm | rpm | 1110 | 900 |"


def test_a_flag_reads_yes_or_no_on_both_sides():
    paper = {pr.PID_LABEL: {"flag": True}, pr.HYBRID_LABEL: {"flag": False}}
    ours = {pr.PID_LABEL: {"flag": 1.0}, pr.HYBRID_LABEL: {"flag": 0.0}}
    (row,) = pr.bench_table(paper, ours, {"flag": ("flag", "yes/no")})
    assert row["ours_pid"] is True and row["ours_hybrid"] is False
    assert row["ours_reduction"] is None


def test_a_further_pid_variant_gets_its_value_and_the_hybrids_reduction_against_it():
    paper = {pr.PID_LABEL: {"lag": 1.3}, pr.HYBRID_LABEL: {"lag": 0.3}}
    ours = {
        pr.PID_LABEL: {"lag": 0.2},
        pr.HYBRID_LABEL: {"lag": 0.05},
        "industrial PID": {"lag": 0.04},
    }
    (row,) = pr.bench_table(paper, ours, {"lag": ("lag", "deg")})
    assert row["ours_reduction"] == pytest.approx(0.75)
    variant = row["variants"]["industrial PID"]
    assert variant["value"] == 0.04
    # (|0.04| - |0.05|) / |0.04|: the hybrid loses to this variant
    assert variant["hybrid_reduction"] == pytest.approx(-0.25)
    header, _, line = pr._bench_markdown([row]).splitlines()
    assert header.endswith("| ours industrial PID | reduction vs industrial PID |")
    assert line.endswith("| 0.0400 | -25 % |")


def test_without_further_sets_the_bench_table_has_the_papers_columns_only():
    sides = {pr.PID_LABEL: {"lag": 1.0}, pr.HYBRID_LABEL: {"lag": 0.5}}
    (row,) = pr.bench_table(sides, sides, {"lag": ("lag", "deg")})
    assert row["variants"] == {}
    assert pr._bench_markdown([row]).splitlines()[0].endswith("| ours reduction |")


def test_the_page_keeps_formulas_literal_and_escapes_the_title():
    html = pr.report_html("cost `IAE/(T*max|ref|) + 2e-3 * TV(iq*)/I_max`", "a <b> & c")
    assert "<code>IAE/(T*max|ref|) + 2e-3 * TV(iq*)/I_max</code>" in html
    assert "<em>" not in html
    assert "<title>a &lt;b&gt; &amp; c</title>" in html


def test_the_gains_sentence_states_each_sets_search():
    record = {
        "method": "optuna TPE",
        "budget": "at most 40 trials per knob",
        "seed": 3,
        "batch": 2,
        "cost": "J",
        "sets": {
            "PID": {"trials": 57, "knobs": 3, "stopped": "converged"},
            "hybrid": {
                "trials": 320,
                "knobs": 8,
                "stopped": "budget",
                "widened": {"speed.bandwidth_Hz": [1.25, 300.0]},
                "on_bound": {"position.adaptation_gain": "upper"},
            },
        },
    }
    text = pr.tuning_sentence(record)
    assert "at most 40 trials per knob; 2 trials at a time; seed 3;" in text
    assert "PID 57 trials for 3 knobs (converged)" in text
    assert (
        "hybrid 320 trials for 8 knobs (budget; speed.bandwidth_Hz widened to [1.25, 300]" in text
    )
    assert "**optimum on the upper bound of position.adaptation_gain**" in text
    old = {"method": "optuna TPE", "trials_per_controller_set": 60, "cost": "J"}
    assert "60 trials per controller set" in pr.tuning_sentence(old)
    assert pr.tuning_sentence({}) == "the scenario's defaults (not tuned)."
    at_limit = {"hybrid": {"position.adaptation_gain": "why it stops there"}}
    named = pr.tuning_sentence(record, at_limit)
    assert "adaptation_gain**, the law's own limit (why it stops there)" in named


def test_an_optimum_on_its_laws_own_limit_is_found_and_named_with_its_reason():
    """speed-step's ST-SMC ends with mu on the super-twisting's 0 < mu < 1 (the paper's rule),
    a bound no widening can move; a bound the search could still widen is not such a limit."""
    from emasim.experiments.reproduction import bounds_at_limit
    from emasim.scenarios.loader import load_scenario

    found = bounds_at_limit(load_scenario("speed-step"))
    assert list(found) == ["ST-SMC"]
    assert "0 < mu < 1" in found["ST-SMC"]["speed.boundary_layer_rad_s"]
    # the same optimum on the unwidened search range (0.05, 0.95): widenable, not a limit
    scenario = load_scenario("speed-step")
    record = scenario.tuning["sets"]["ST-SMC"]
    record.widened.clear()
    assert bounds_at_limit(scenario) == {}
    assert all(bounds_at_limit(load_scenario(name)) == {} for name in ("bench-step", "bench-sine"))
