"""A Result says what its run was (RunDescription): elements, loops, sensors, column units.

Analysis reads this, never NaN columns; it survives a save and a load.
"""

import math

import pytest

from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario
from emasim.sim.result import Result


def test_a_position_run_describes_its_cascade_elements_sensors_and_units(tmp_path):
    scenario = load_scenario("bench-step", controllers=["hybrid"], settings=["duration_s=0.02"])
    result = run_scenario(scenario)
    run = result.description
    assert run.outer_loop == "position" and result.outer_loop == "position"
    assert run.loops == {"position": "rbf-smc", "speed": "st-gpio", "current": "pi"}
    assert {"linkage", "compliance", "anchorage", "rudder_shaft", "load_motor"} <= set(run.elements)
    assert run.sensors["rudder"]["resolution"] > 0 and run.sensors["rudder"]["accuracy_error"] > 0
    assert run.sensors["rudder"]["accuracy_period"] == pytest.approx(2 * math.pi / 1024)
    assert set(run.sensors) == {"rudder", "position", "force", "angle", "speed", "id", "iq"}
    assert run.sensors["speed"]["derived_from"] == "angle"  # the bench-digital sensors
    assert run.sensors["position"]["sample_period_s"] == 1e-3
    assert set(run.units) == set(result.columns)
    assert run.units["iq_A"] == "A" and run.units["hinge1_force_N"] == "N"
    again = Result.load(result.save(tmp_path / "run", plot=False))
    assert again.description == run


def test_a_speed_run_closes_two_loops_on_the_lumped_plant():
    result = run_scenario(
        load_scenario("speed-step", controllers=["speed=smc"], settings=["duration_s=0.01"])
    )
    run = result.description
    assert run.outer_loop == "speed" and run.loops == {"speed": "smc", "current": "pi"}
    assert "linkage" not in run.elements and run.sensors == {}
    assert "linkage_rod_force_N" not in run.units
