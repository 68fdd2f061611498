"""emasim reproduce: every experiment, the paper's numbers beside ours, consistent files."""

import json
import tomllib
from pathlib import Path

import pytest
from helpers import module_at
from typer.testing import CliRunner

from emasim.analysis.paper_report import EXPERIMENTS, HEADLINE, paper_results, reduction
from emasim.cli import app

SHARED_RESULTS = Path(__file__).parents[2] / "shared" / "paper" / "results.toml"
ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce") / "report"
    # the ablation re-runs the bench experiments six times: tests/test_ablation.py checks it
    result = CliRunner().invoke(app, ["reproduce", "--no-ablation", "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out


def test_every_file_is_written(report):
    for name in ("report.md", "report.html", "tables.json"):
        assert (report / name).is_file()
    for exp in EXPERIMENTS:
        assert (report / "figures" / f"{exp.scenario}.png").is_file()
        assert (report / "runs" / exp.scenario / "metrics.json").is_file()
    html = (report / "report.html").read_text()
    assert "<table>" in html and "figures/bench-step.png" in html


def test_headline_has_the_five_figures_with_both_sides(report):
    tables = json.loads((report / "tables.json").read_text())
    assert set(tables["headline"]) == set(HEADLINE)
    for item in tables["headline"].values():
        for key in ("paper_pid", "paper_hybrid", "ours_pid", "ours_hybrid", "unit", "definition"):
            assert key in item
        assert isinstance(item["ours_pid"], float) and isinstance(item["ours_hybrid"], float)


def test_the_readmes_headline_is_the_one_this_reproduction_measures(report):
    """The README's table is docs/headline.json rendered, and a fresh reproduction measures
    those numbers (runs are deterministic: tests/test_fingerprints.py)."""
    module = module_at("docs/readme_headline.py")
    stored = json.loads(module.STORE.read_text())
    readme = (ROOT / "README.md").read_text()
    block = readme[readme.index(module.BEGIN) + len(module.BEGIN) : readme.index(module.END)]
    assert block.strip() == module.render(stored)
    measured = json.loads((report / "tables.json").read_text())["headline"]
    for key, item in stored.items():
        for side in ("ours_pid", "ours_hybrid", "paper_pid", "paper_hybrid"):
            assert measured[key][side] == pytest.approx(item[side], rel=1e-9), (key, side)
    # the README's verdict: on the realistic bench the hybrid beats PID on all five figures
    assert all(item["hybrid_better"] for item in measured.values())
    assert "the hybrid beats PID on all five figures" in " ".join(readme.split())


def test_tables_agree_with_the_runs_and_the_paper(report):
    tables = json.loads((report / "tables.json").read_text())
    bench = json.loads((report / "runs" / "bench-step" / "metrics.json").read_text())
    (row,) = [r for r in tables["bench_step"] if r["metric"] == "chatter_amplitude_deg"]
    assert row["ours_pid"] == bench["PID"]["chatter_amplitude_deg"]
    assert row["ours_hybrid"] == bench["hybrid"]["chatter_amplitude_deg"]
    assert row["paper_pid"] == 0.2 and row["paper_hybrid"] == 0.05
    assert row["paper_reduction"] == pytest.approx(0.75)
    fig8 = {r["controller"]: r for r in tables["position_step"]}
    assert fig8["RBF+SMC"]["paper_settling_s"] == 1.45


@pytest.mark.skipif(not SHARED_RESULTS.is_file(), reason="no shared/ beside the checkout")
def test_the_packaged_paper_numbers_are_the_shared_transcription():
    assert paper_results() == tomllib.loads(SHARED_RESULTS.read_text())


def test_reduction_is_relative_to_the_baseline_magnitude():
    assert reduction(0.2, 0.05) == pytest.approx(0.75)
    assert reduction(-4.0, 1.0) == pytest.approx(0.75)
    assert reduction(1.0, 2.0) == pytest.approx(-1.0)
    assert reduction(0.0, 1.0) is None


def test_unknown_experiment_is_refused(tmp_path):
    result = CliRunner().invoke(app, ["reproduce", "--only", "fig-99", "--out", str(tmp_path)])
    assert result.exit_code == 2 and "choose from" in result.output
