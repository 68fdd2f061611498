"""The ablation (emasim.experiments.ablation): the bench's elements added one at a time.

Each stage must hold exactly the elements of its own and the stages before it, the last stage
must be the shipped bench scenario itself, and the rows written for the report must carry the
runs' own metrics with the paper's bench values beside them.
"""

import json
import re

import pytest

from emasim.analysis.paper_report import ablation_rows, paper_results, write_report
from emasim.experiments.ablation import STAGES, ablation, stage_scenarios
from emasim.jsonio import json_text
from emasim.plant.presets import bench_digital_sensors, bench_sensors
from emasim.scenarios.loader import load_scenario

OPTIONAL = ("compliance", "anchorage", "rudder_shaft", "load_motor", "ratings")


def present(scenario) -> set[str]:
    plant = scenario.plant
    found = {name for name in OPTIONAL if getattr(plant, name) is not None}
    if plant.linkage is not None:
        found.add("linkage")
    if scenario.loop.position_feedback == "rudder":
        found.add("rudder feedback")
    if scenario.loop.computation_delay_s > 0:
        found.add("delay")
    return found


def test_each_stage_adds_its_elements_to_the_one_before():
    bench = load_scenario("bench-step")
    stages = dict(stage_scenarios(bench))
    assert list(stages) == [name for name, _ in STAGES]
    assert stages["load motor"] == bench  # the last stage is the scenario itself
    adds = {
        "lumped": set(),
        "linkage": {"linkage"},
        "rudder feedback": {"rudder feedback"},
        "compliance": {"compliance", "anchorage", "rudder_shaft"},
        "digital drive": {"delay", "ratings"},
        "load motor": {"load_motor"},
    }
    have = set()
    for name, scenario in stages.items():
        have |= adds[name]
        assert present(scenario) == have, name
    assert stages["compliance"].sensors == bench_sensors()
    assert stages["digital drive"].sensors == bench_digital_sensors()
    assert stages["lumped"].plant.end_stops is not None  # every stage keeps its stroke
    # the inertia disk goes back onto the rudder when the shaft's torsion is taken out
    rudder = stages["rudder feedback"].plant.rudder_inertia_kgm2
    shaft = stages["compliance"].plant
    assert rudder == pytest.approx(shaft.rudder_inertia_kgm2 + shaft.rudder_shaft.disk_inertia_kgm2)
    assert stages["lumped"].compare == bench.compare  # the same gains throughout


def test_only_the_sets_asked_for_run_and_are_kept():
    short = {"bench-step": load_scenario("bench-step", settings=["duration_s=0.2"])}
    known = {"bench-step": {"PID": {"x": 1.0}, "hybrid": {"x": 2.0}}}
    result = ablation(short, known, labels=("hybrid",))
    assert all(set(by_label) == {"hybrid"} for by_label in result["bench-step"].values())
    assert result["bench-step"][STAGES[-1][0]] == {"hybrid": {"x": 2.0}}


def test_the_rows_carry_each_stages_own_metrics_and_the_papers(tmp_path):
    short = {"bench-step": load_scenario("bench-step", settings=["duration_s=2.5"])}
    result = ablation(short)
    assert set(result["bench-step"]) == {name for name, _ in STAGES}
    rows = ablation_rows(result)
    paper = paper_results()["bench_step"]
    for stage, by_label in result["bench-step"].items():
        (row,) = [r for r in rows if r["stage"] == stage and r["metric"] == "steady_error_rms_deg"]
        assert row["ours_pid"] == by_label["PID"]["steady_error_rms_deg"]
        assert row["ours_hybrid"] == by_label["hybrid"]["steady_error_rms_deg"]
        assert row["paper_pid"] == paper["PID"]["steady_error_rms_deg"]
    lumped = result["bench-step"]["lumped"]["PID"]
    linkage = result["bench-step"]["linkage"]["PID"]
    assert lumped != linkage  # the stages differ: the linkage changes the run
    write_report(tmp_path, {"ablation": rows}, {}, {}, "", stages=STAGES)
    text = (tmp_path / "report.md").read_text()
    assert "## Ablation" in text and all(f"| {name} |" in text for name, _ in STAGES)
    assert re.search(r"bench_step \w+, PID: most moved by", text)
    assert json.loads((tmp_path / "tables.json").read_text())["ablation"] == json.loads(
        json_text(rows)
    )
