"""Where each verdict flips (emasim.experiments.verdict_map, emasim.analysis.verdict_map): the
grid is the bench's own at its nominal cell, the lines say what the margins say, and the stored
map (docs/verdict_map.json, docs/paper.md's) is what the code measures off the nominal bench."""

import json
import math

import pandas as pd
import pytest
from helpers import module_at

from emasim.analysis.plots import plot_verdict_map
from emasim.analysis.verdict_map import cell_at, flip_line, flips, margin, markdown
from emasim.experiments.batch import run_all
from emasim.experiments.robustness import BASELINES, figures
from emasim.experiments.store import OK
from emasim.experiments.study import plan_study
from emasim.experiments.verdict_map import (
    AXES,
    ENCODERS,
    LABELS,
    NOMINAL,
    cells,
    latest,
    spec_for,
    verdict_map,
)
from emasim.jsonio import finite_or_none
from emasim.page_blocks import block_of
from emasim.plant.presets import ttl_rudder_encoder
from emasim.scenarios.loader import load_scenario

HEADLINE_MODULE = "docs/readme_headline.py"


def test_the_nominal_cell_is_the_shipped_bench():
    """Its figures are the headline's: preload, encoder and clearance as the bench has them."""
    for name in ("bench-step", "bench-sine"):
        scenario = load_scenario(name)
        assert scenario.plant.load_motor.preload_Nm == NOMINAL["preload_Nm"]
        assert scenario.sensors.rudder == ENCODERS[NOMINAL["encoder"]] == ttl_rudder_encoder()
        assert set(scenario.plant.linkage.hinge_clearance_mm) == {NOMINAL["hinge_clearance_mm"]}
        for axis, (_, values) in AXES.items():
            assert NOMINAL[axis] in values


def test_the_grid_runs_every_cell_with_each_set_and_sets_what_it_names():
    plan = plan_study(spec_for("bench-step"))
    assert cells() == 4 * 2 * 3
    assert len(plan.jobs) == len(LABELS) * cells()
    preloads = {job.scenario.plant.load_motor.preload_Nm for job in plan.jobs}
    assert preloads == {0.0, 31.5, 63.0, 94.5}  # the loader's rating in thirds
    rudders = [
        (job.scenario.sensors.rudder.resolution, job.scenario.sensors.rudder.accuracy_error)
        for job in plan.jobs
    ]
    for channel in ENCODERS.values():
        read = (channel.resolution, channel.accuracy_error)
        assert rudders.count(read) == len(plan.jobs) // len(ENCODERS)
    absolute = ENCODERS["20-bit absolute"]
    assert absolute.resolution == pytest.approx(2 * math.pi / 2**20)
    assert absolute.accuracy_error == 0.0 and absolute.noise_std == 0.0
    clearances = {job.scenario.plant.linkage.hinge_clearance_mm for job in plan.jobs}
    assert clearances == {(c,) * 4 for c in (0.0, 0.01, 0.05)}


def test_the_margin_is_the_hybrids_relative_lead():
    assert margin(2.0, 1.0) == 50.0
    assert margin(1.0, 2.0) == -100.0
    assert margin(math.inf, 1.0) == 100.0  # the baseline alone diverged
    assert margin(1.0, math.inf) == -math.inf
    assert margin(0.0, 0.5) == -math.inf  # the baseline's reading still, the hybrid's not
    assert margin(0.0, 0.0) == 0.0  # a tie is no win


def synthetic(margin_of_cell) -> list[dict]:
    return [
        {"preload_Nm": p, "encoder": e, "hinge_clearance_mm": c, "baseline": 1.0}
        | {"hybrid": None if m is None else 1.0 - m / 100, "margin_pct": m}
        for p in AXES["preload_Nm"][1]
        for e in AXES["encoder"][1]
        for c in AXES["hinge_clearance_mm"][1]
        for m in [margin_of_cell(p, e, c)]
    ]


def test_the_lines_name_the_values_between_which_a_verdict_flips():
    # the hybrid wins from 63 N m of preload on, and with the absolute encoder at any preload
    map_ = synthetic(lambda p, e, c: 30.0 if p >= 63 or e != "TTL" else -20.0)
    assert flips(map_, NOMINAL, "preload_Nm") == [(31.5, 63.0)]
    assert flips(map_, NOMINAL, "encoder") == [("TTL", "20-bit absolute")]
    assert flips(map_, NOMINAL, "hinge_clearance_mm") == []
    line = flip_line("step_x_reduction", "steady_error_rms_deg", "PID", map_, NOMINAL)
    assert line.startswith("step x against PID: on the nominal bench the hybrid loses (1 against")
    assert "1.2 deg, margin -20 %); it wins in 18 of 24 cells." in line  # 2 x 3 + 2 x 2 x 3
    assert "along the preload it flips between 31.5 N·m and 63 N·m;" in line
    assert "along the encoder it flips between TTL and 20-bit absolute;" in line
    assert "along the hinge clearance it holds (0 mm to 0.05 mm)." in line
    # over the whole map: at 0 and 31.5 N m only the absolute encoder's 3 cells win
    assert "preload 0 N·m, 31.5 N·m, 63 N·m, 94.5 N·m: 3, 3, 6, 6 of 6;" in line
    assert "encoder TTL, 20-bit absolute: 6, 12 of 12;" in line
    assert "hinge clearance 0 mm, 0.01 mm, 0.05 mm: 6, 6, 6 of 8." in line


def test_a_verdict_that_never_flips_holds_over_the_whole_map():
    line = flip_line("x", "x_deg", "PID", synthetic(lambda p, e, c: 5.0), NOMINAL)
    assert line.endswith("it wins in 24 of 24 cells: the verdict holds over the whole map.")


def test_a_null_margin_reads_as_a_loss():
    """tables.json holds -inf as null: the hybrid's figure above the baseline's 0."""
    map_ = synthetic(lambda p, e, c: None if p == 0 else 10.0)
    assert flips(map_, NOMINAL, "preload_Nm") == [(0.0, 31.5)]
    assert "the hybrid loses" in flip_line("x", "x_deg", "PID", map_, NOMINAL)


def test_without_its_studies_there_is_no_map(tmp_path):
    assert latest(tmp_path) is None


@pytest.fixture(scope="module")
def stored():
    return json.loads(module_at(HEADLINE_MODULE).VERDICT_MAP.read_text())


def test_the_docs_lines_are_the_stored_maps():
    module = module_at(HEADLINE_MODULE)
    page = module.PAPER.read_text()
    vmap = json.loads(module.VERDICT_MAP.read_text())
    assert block_of(page, "verdict-map") == module.render_verdict_map(vmap)


def test_the_stored_map_covers_every_headline_figure_against_both_baselines(stored):
    headline = {n for n in figures() if n.endswith("_reduction")}
    assert set(stored["figures"]) == headline
    for entry in stored["figures"].values():
        assert set(entry["against"]) == set(BASELINES)
        for found in entry["against"].values():
            assert len(found) == cells()


@pytest.mark.parametrize("scenario", ["bench-step", "bench-sine"])
def test_a_cell_off_the_nominal_bench_is_what_the_code_measures(stored, scenario):
    """The corner cell (loader at its rating, absolute encoder, 0.05 mm) re-run now gives the
    stored map's figures and margins (runs are deterministic: tests/test_fingerprints.py)."""
    corner = {"preload_Nm": 94.5, "encoder": "20-bit absolute", "hinge_clearance_mm": 0.05}
    encoder = ENCODERS[corner["encoder"]]
    settings = [
        f"plant.load_motor.preload_Nm={corner['preload_Nm']!r}",
        f"plant.linkage.hinge_clearance_mm=[{', '.join([repr(0.05)] * 4)}]",
        f"sensors.rudder.resolution={encoder.resolution!r}",
        f"sensors.rudder.accuracy_error={encoder.accuracy_error!r}",
    ]
    variants = dict(load_scenario(scenario, settings=settings).variants())
    results = run_all([variants[label] for label in LABELS], labels=list(LABELS))
    table = [
        {"label": label, "sample": 0, "status": OK, **result.metrics}
        | {column: corner[axis] for axis, (column, _) in AXES.items()}
        for label, result in zip(LABELS, results, strict=True)
    ]
    frame = pd.DataFrame(table)
    frame[AXES["encoder"][0]] = list(ENCODERS).index(corner["encoder"])
    fresh = finite_or_none(verdict_map({scenario: frame}))
    for name, entry in fresh["figures"].items():
        for baseline, (cell,) in entry["against"].items():
            kept = cell_at(stored["figures"][name]["against"][baseline], corner)
            for key in ("baseline", "hybrid", "margin_pct"):
                if kept[key] is None:
                    assert cell[key] is None, (name, baseline, key)
                else:
                    assert cell[key] == pytest.approx(kept[key], rel=1e-9), (name, baseline, key)


def test_the_report_section_and_its_figure_are_made_from_the_map(stored, tmp_path):
    text = "\n".join(markdown(stored, ("where each verdict flips", "figures/verdict-map.png")))
    assert "## Where each verdict flips" in text
    assert text.count("### ") == 5 * len(BASELINES)
    assert text.count("**") == 2 * 5 * len(BASELINES)  # the nominal cell, once a table
    assert "![where each verdict flips](figures/verdict-map.png)" in text
    figure = plot_verdict_map(stored)
    assert len([ax for ax in figure.axes if ax.get_title()]) == 5 * len(BASELINES)


def test_the_notes_read_the_stored_map(stored):
    """Each count the reproduction notes give for the verdict map, from docs/verdict_map.json."""
    from emasim.analysis.paper_report import notes
    from emasim.analysis.verdict_map import margin_of, wins_by_value

    text = " ".join(notes().split())

    def against(name: str, baseline: str = "PID") -> list[dict]:
        return stored["figures"][name]["against"][baseline]

    def wins(found: list[dict]) -> int:
        return sum(margin_of(c) > 0 for c in found)

    step = ("step_steady_error_reduction", "step_vibration_amplitude_reduction")
    for found in (against(name, b) for name in step for b in BASELINES):
        assert wins_by_value(found, "encoder") == {"TTL": (1, 12), "20-bit absolute": (9, 12)}
        absolute = [c for c in found if c["encoder"] == "20-bit absolute"]
        assert all((margin_of(c) > 0) == (c["preload_Nm"] > 0) for c in absolute)
    lag, rate = "sine_displacement_lag_reduction", "sine_speed_fluctuation_reduction"
    industrial = BASELINES[1]
    losses = [c for c in against(rate, industrial) if margin_of(c) <= 0]
    claims = {
        "in 1 of 12 cells against PID; read through the 20-bit encoder, in 9 of 12": True,
        "speed fluctuation goes to PID in all 24 cells": all(
            wins(against("step_speed_fluctuation_reduction", b)) == 0 for b in BASELINES
        ),
        "The sine lag goes to the hybrid in all 24 cells against PID and in 23 against the "
        "industrial PID": (wins(against(lag)), wins(against(lag, industrial))) == (24, 23),
        "beats PID's in all 24 and the industrial PID's in 17, with 6 of its 7 losses at no "
        "standing preload": (wins(against(rate)), wins(against(rate, industrial))) == (24, 17)
        and (sum(c["preload_Nm"] == 0 for c in losses), len(losses)) == (6, 7),
    }
    for words, holds in claims.items():
        assert words in text, words
        assert holds, words
