"""Physical limits a run crosses (emasim.analysis.report.limits_crossed): the motor's speed
above the drive's limit, the current above the limit in force, the rod past its stroke on a
plant without end stops; each a warning line and a ``limits`` entry in meta.json."""

import dataclasses
import json
import math

import numpy as np
import pytest
from test_report_metrics import FakeResult, step_scenario
from typer.testing import CliRunner

from emasim.analysis.report import LIMIT_TOLERANCE, limit_warnings, limits_crossed
from emasim.cli import app
from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario
from emasim.sim.result import Result

# a motor stand's: its speed limit and stroke, no end stops
PLANT = dataclasses.replace(
    step_scenario("speed_rpm", 1000.0), max_speed_rpm=3000.0, stroke_mm=250.0
)
RPM = math.pi / 30.0


def fake(experiment, **columns) -> FakeResult:
    t = np.linspace(0.0, 1.0, 11)
    return FakeResult(t, experiment, **columns)


def test_each_limit_crossed_is_found_with_its_peak_and_when():
    speed = np.array([0, 1000, 3500, 2000, 3100, 0, 0, 0, 0, 0, 0]) * RPM
    iq = np.array([0, 10, 20, 30, 62, 70, 40, 0, 0, 0, 0])
    limit = np.full(11, 58.0)
    rod = np.array([0, 50, 100, 120, 126, 130, 110, 0, 0, 0, 0]) * 1e-3
    columns = dict(motor_speed_rad_s=speed, iq_A=iq, current_limit_A=limit)
    out = limits_crossed(fake(PLANT, actuator_position_m=rod, **columns))
    assert out["motor_speed"] == {
        "peak": pytest.approx(3500.0),
        "peak_s": pytest.approx(0.2),
        "limit": 3000.0,
        "unit": "rpm",
        "first_s": pytest.approx(0.2),
        "what": "the motor's speed",
    }
    assert (out["current"]["peak"], out["current"]["first_s"]) == (70.0, pytest.approx(0.4))
    assert out["rod_stroke"]["peak"] == pytest.approx(130.0)
    assert out["rod_stroke"]["limit"] == 125.0
    lines = limit_warnings(out)
    assert len(lines) == 3
    assert lines[0].startswith("the motor's speed reached 3500 rpm at 0.2 s, beyond its 3000 rpm")


def test_a_plant_with_end_stops_reports_their_contact_not_the_stroke():
    rod = np.full(11, 0.130)
    with_stops = dataclasses.replace(PLANT, stroke_mm=None)  # end stops hold the rod
    assert limits_crossed(fake(with_stops, actuator_position_m=rod)) == {}
    assert "rod_stroke" in limits_crossed(fake(PLANT, actuator_position_m=rod))


def test_a_run_at_its_limit_crosses_nothing():
    """The drive holds its commands at the limit: a value on it (and float rounding) is no
    crossing; beyond it by more than LIMIT_TOLERANCE is."""
    at = np.full(11, 3000.0 * RPM) * (1.0 + 0.5 * LIMIT_TOLERANCE)
    assert limits_crossed(fake(PLANT, motor_speed_rad_s=at)) == {}
    beyond = np.full(11, 3000.0 * RPM) * (1.0 + 2 * LIMIT_TOLERANCE)
    assert set(limits_crossed(fake(PLANT, motor_speed_rad_s=beyond))) == {"motor_speed"}


def test_the_motor_stand_warns_when_the_rod_passes_its_stroke():
    """The issue's case: the stand has no end stops, and a 10 s speed step drives the rod far
    past its +-125 mm stroke."""
    scenario = load_scenario("speed-step", label="PI", settings=["duration_s=10.0"])
    result = run_scenario(scenario)
    limits = result.meta["limits"]
    assert limits["rod_stroke"]["peak"] > 1000.0 and limits["rod_stroke"]["limit"] == 125.0
    assert "motor_speed" not in limits and "current" not in limits
    assert any("rod's travel from mid stroke" in line for line in result.meta["warnings"])


def test_emasim_run_gives_each_warning_line_as_a_python_warning():
    """From Python, emasim.run issues each line of meta.json's warnings as an
    emasim.PhysicalLimitWarning (a notebook shows it; a user filters or escalates it), the
    controller set's label before it."""
    import warnings

    import emasim

    with pytest.warns(emasim.PhysicalLimitWarning) as caught:
        result = emasim.run("speed-step", label="PI", settings=["duration_s=10.0"])
    assert [str(w.message) for w in caught] == [f"PI: {line}" for line in result.meta["warnings"]]
    assert caught[0].filename == __file__  # it points at the caller's line
    with warnings.catch_warnings():
        warnings.simplefilter("error", emasim.EmasimWarning)
        with pytest.raises(emasim.PhysicalLimitWarning, match="rod's travel from mid stroke"):
            emasim.run("speed-step", label="PI", settings=["duration_s=10.0"])


def test_a_back_driven_overspeed_and_overcurrent_are_warned_and_recorded(tmp_path):
    """A -200 N m load on the motor's shaft, far beyond what the drive's 58 A hold: the drive
    keeps its commands within its limits, the load drives the motor past them; run prints a
    line for each and meta.json records them. The inverter holds the current at its 58 A until
    the back-driven motor's back-EMF reaches what the bus can oppose (Udc/sqrt(3)): only then
    does the current pass it (before the inverter's current limit it passed at 1973 rpm, with
    99 V of back-EMF against 323 V). Until then the chopping, checked once a sub-step, holds it
    within LIMIT_TOLERANCE (0.10 % over at the shipped three sub-steps)."""
    out = tmp_path / "run"
    load = 'load.motor_torque_Nm=[{type="step", time_s=3.0, final=-200.0}]'
    result = CliRunner().invoke(
        app, ["run", "position-step", "--label", "PI", "--set", load, "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert text.count("PI: the motor's speed reached") == 1  # a line, not also a Python warning
    assert "beyond its 3000 rpm limit" in text
    assert "PI: the q-axis current reached" in text and "beyond its 58 A limit" in text
    meta = json.loads((out / "meta.json").read_text())
    assert meta["limits"]["motor_speed"]["peak"] > 3000.0
    assert meta["limits"]["current"]["peak"] > 58.0
    assert len(meta["warnings"]) == 3  # the end stops, the speed and the current
    run = Result.load(out)
    motor = run.scenario["plant"]["motor"]
    current = np.hypot(run["id_A"], run["iq_A"])
    first = np.flatnonzero(current > motor["max_current_A"] * (1.0 + LIMIT_TOLERANCE))[0]
    back_emf = motor["pole_pairs"] * motor["flux_linkage_Wb"] * abs(run["motor_speed_rad_s"][first])
    assert back_emf > 0.99 * motor["dc_bus_V"] / math.sqrt(3.0)
