"""Fault identification on the bench: the features against readings built to known values,
one worn plant recovered from its sensors' readings through the command line, bad traces
refused in one line, and the docs' score kept equal to what the benchmark measured.

The worn plant's readings are simulated with a noise seed of their own; the fit's simulations
use the scenario's (0), so the sensors' noise differs between the two as between a bench and
its model. ``benchmarks/bench_fault_identification.py`` runs twenty such plants.
"""

import json
import math
import tomllib

import numpy as np
import pandas as pd
import pytest
from helpers import module_at, refused_in_one_line
from typer.testing import CliRunner

from emasim.cli import app
from emasim.identification.bench_features import Constants, features
from emasim.page_blocks import block_of

bench = module_at("benchmarks/bench_fault_identification.py")
KNOWN = Constants(
    lead_per_rad_m=0.008 / (2 * math.pi), torque_constant_Nm_per_A=0.7, stribeck_speed_rad_s=1.0
)


def test_the_features_read_back_the_values_readings_were_built_from():
    """Readings made from chosen friction torques, half-gaps and rudder lost motion (with a
    speed-dependent lag and a cubic kinematics on top, which the features' fits hold apart):
    each feature equals its value."""
    t = np.arange(0.0, 8.0, 1e-3)
    speed = 8.0 * np.sin(2 * np.pi * t / 3.0)  # rad/s, both ways
    angle = 8.0 * 3.0 / (2 * np.pi) * (1.0 - np.cos(2 * np.pi * t / 3.0))
    load = np.where(np.sin(2 * np.pi * t / 1.3) >= 0.0, 60.0, -60.0)
    forward, backward, half_gap, rudder_jump = 0.31, 0.27, 42e-6, 3.1e-4
    force = 4.0 * load + 7.0  # N
    friction = np.where(speed > 0.0, forward, -backward)
    iq = (friction + KNOWN.lead_per_rad_m * force) / KNOWN.torque_constant_Nm_per_A
    rod = KNOWN.lead_per_rad_m * angle - half_gap * np.sign(load) - 3e-7 * speed
    centred = rod / 0.01
    rudder = 0.2 * centred + 0.01 * centred**3 + rudder_jump * np.sign(load) + 1e-5 * speed
    readings = {
        "angle_rad": angle,
        "rod_position_m": rod,
        "iq_A": iq,
        "force_N": force,
        "rudder_rad": rudder,
    }
    found = features(t, readings, load, KNOWN)
    assert found == pytest.approx([forward, backward, half_gap, rudder_jump], rel=1e-5)


def test_features_refuse_a_trace_without_a_load_reversal():
    t = np.arange(0.0, 4.0, 1e-3)
    readings = {name: np.sin(t) for name in ("angle_rad", "rod_position_m", "iq_A", "force_N")}
    readings["rudder_rad"] = np.sin(t)
    with pytest.raises(ValueError, match="load of both signs"):
        features(t, readings, np.full(t.size, 60.0), KNOWN)


@pytest.fixture(scope="module")
def worn(tmp_path_factory):
    """The readings of a worn plant and its true values."""
    folder = tmp_path_factory.mktemp("worn")
    truth = {bench.FRICTION: 1.6, bench.BACKLASH: 0.22, bench.CLEARANCE: 0.035}
    return bench.readings_file(truth, noise_seed=11, folder=folder), truth


def test_a_worn_plant_is_recovered_from_its_readings_through_the_command_line(tmp_path, worn):
    data, truth = worn
    out = tmp_path / "identified"
    result = CliRunner().invoke(
        app, ["identify", "bench-identify", "--data", str(data), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    found = json.loads((out / "identified.json").read_text())["parameters"]
    for key, value in truth.items():
        assert abs(found[key]["value"] - value) <= bench.tolerance(key, value), (key, found[key])
        assert found[key]["interval95"] > 0.0
    calibrated = tomllib.loads((out / "scenario.toml").read_text())
    backlash = calibrated["plant"]["backlash"]["width_mm"]
    assert backlash == pytest.approx(found[bench.BACKLASH]["value"])
    assert calibrated["plant"]["friction"]["coulomb_Nm"] == pytest.approx(
        0.3 * found[bench.FRICTION]["value"]
    )
    assert {"fit.png", "traces.parquet", "report.md"} <= {p.name for p in out.iterdir()}


def test_bad_traces_and_keys_are_refused_in_one_line(tmp_path, worn):
    data, _ = worn
    frame = pd.read_parquet(data)
    cases = {
        "short": (frame.iloc[:-10], "records 16000"),
        "slow": (frame.assign(t_s=2 * frame.t_s), "sampled every 0.002 s"),
        "no_force": (frame.drop(columns="measured_force_N"), "no column for force_N"),
    }
    for name, (bad, match) in cases.items():
        path = tmp_path / f"{name}.parquet"
        bad.to_parquet(path)
        refused_in_one_line(["identify", "bench-identify", "--data", str(path)], match)
    args = ["identify", "bench-identify", "--data", str(data)]
    refused_in_one_line([*args, "--method", "idim"], "not linear in its parameters")
    refused_in_one_line([*args, "--set", "load.rudder_torque_Nm=[]"], "load of both signs")
    refused_in_one_line([*args, "--fit", "plant.backlash.width_mm=0:20"], "width_mm")
    refused_in_one_line(
        [*args, "--fit", "plant.friction.nothing,plant.friction.coulomb_Nm=*1:2"], "nothing"
    )
    refused_in_one_line(["identify", "bench-step", "--data", str(data)], "choose the one")


def test_a_rod_reading_in_mm_is_refused_not_identified_on_its_bound(tmp_path, worn, monkeypatch):
    """With the rod sensor's column in mm the fit stopped 3.4e-7 mm under the backlash's
    range top (its tolerance is 1e-3) with an interval of ± 206 mm, and was reported as
    identified (99.9 % off the truth). That stopping point, given back by a stand-in for the
    optimiser (the real fit takes minutes), is refused in one line."""
    from emasim.identification import identify as module
    from emasim.identification.fit import Fit

    data, _ = worn
    frame = pd.read_parquet(data)
    mm = tmp_path / "rod-in-mm.parquet"
    frame.assign(measured_rod_position_m=1e3 * frame.measured_rod_position_m).to_parquet(mm)

    def stopped_on_the_bound(residuals, keys, start, **options):
        (key,) = keys
        value = {key.name: key.high - 3.4e-7}
        return Fit(tuple(keys), value, {key.name: 206.0}, np.eye(1), 0.5, 9, True, "xtol", 1.0)

    monkeypatch.setattr(module, "output_error", stopped_on_the_bound)
    args = ["identify", "bench-identify", "--data", str(mm), "--fit", bench.BACKLASH]
    args += ["--out", str(tmp_path / "out")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1, result.output
    assert "no value identified: the 95 % interval of plant.backlash" in result.output
    assert "(± 206) is wider than its range (0.01 to 0.6)" in result.output
    assert "misses rod_position_m by 99.9 %" in result.output


def test_the_docs_score_is_what_the_benchmark_measured():
    """docs/calibration.md's block is the benchmark's rendering of fault_identification.json,
    whose score follows from its rows (python benchmarks/bench_fault_identification.py
    --write rewrites both)."""
    results = json.loads(bench.RESULTS.read_text())
    rows = results["plants"]
    assert len(rows) == bench.PLANTS
    for row, truth in zip(rows, bench.draw(bench.PLANTS), strict=True):
        for key, value in truth.items():
            assert row[key]["truth"] == pytest.approx(value, rel=1e-12)
            error = abs(row[key]["identified"] - value)
            assert row[key]["recovered"] == (error <= bench.tolerance(key, value))
        assert row["recovered"] == all(row[key]["recovered"] for key in truth)
    assert {k: results[k] for k in ("recovered", "strictly", "by_key")} == bench.score(rows)
    text = bench.DOCS.read_text()
    assert block_of(text, bench.BLOCK) == bench.render(results)
