"""Every controller closes its loop on the paper's experiments and reaches the reference.

Sliding-mode laws are compared by metrics, not samples. All run through the one compiled loop,
which must not recompile whatever the controller.
"""

import numpy as np
import pytest

from emasim.control.registry import CONTROLLERS
from emasim.errors import InputError
from emasim.scenarios.loader import load_scenario
from emasim.sim import engine
from emasim.sim.engine import simulate

RPM = np.pi / 30


def value_at(result, column, t):
    return result[column][np.searchsorted(result.t, t) - 1]


@pytest.mark.parametrize("name", list(CONTROLLERS["speed"]))
def test_speed_controllers_reach_the_reference_and_reject_the_load(name):
    scenario = load_scenario(
        "speed-step",
        controllers=[f"speed={name}"],
        settings=["duration_s=0.4", 'load.motor_torque_Nm=[{type="step", time_s=0.2, final=10}]'],
    )
    result = simulate(scenario.setup())
    target = 1000 * RPM
    for t in (0.19, 0.399):  # before the load step, and after it
        assert abs(value_at(result, "motor_speed_rad_s", t) - target) < 0.01 * target, t


@pytest.mark.parametrize("name", list(CONTROLLERS["position"]))
def test_position_controllers_reach_the_reference_and_reject_the_load(name):
    scenario = load_scenario(
        "position-step",
        controllers=[f"position={name}"],
        settings=["duration_s=1.2", 'load.motor_torque_Nm=[{type="step", time_s=0.8, final=10}]'],
    )
    result = simulate(scenario.setup())
    for t in (0.79, 1.199):
        assert abs(value_at(result, "actuator_position_m", t) - 0.120) < 3e-4, t  # 0.3 mm


@pytest.mark.parametrize("output", ["cascade", "current"])
def test_rbf_smc_closes_the_loop_with_either_output(output):
    scenario = load_scenario(
        "position-step",
        controllers=["hybrid"],
        settings=["duration_s=1.0", f'controllers.position.output="{output}"'],
    )
    assert scenario.controllers.position.name == "rbf-smc"
    assert scenario.controllers.speed.name == "st-gpio"
    result = simulate(scenario.setup())
    assert abs(result["actuator_position_m"][-1] - 0.120) < 3e-4
    speed_ref = result["speed_ref_rad_s"]
    assert np.isnan(speed_ref).all() if output == "current" else np.isfinite(speed_ref).all()


def test_no_controller_recompiled_the_loop():
    simulate(load_scenario("speed-step", settings=["duration_s=0.01"]).setup())
    assert len(engine.run_ticks.overloads) == 1


def test_cascades_fill_only_the_loops_a_scenario_closes():
    speed = load_scenario("speed-step", controllers=["hybrid"])
    assert speed.controllers.speed.name == "st-gpio" and speed.controllers.position is None
    pid = load_scenario("position-step", controllers=["pid"])
    assert (pid.controllers.position.name, pid.controllers.speed.name) == ("pid", "pi")


@pytest.mark.parametrize(
    "choice,words",
    [
        ("position=st-gpio", "'st-gpio' is a speed-loop controller"),
        ("speed=rbf-smc", "'rbf-smc' is a position-loop controller"),
        ("hybridd", "expected LOOP=NAME or a cascade"),
    ],
)
def test_a_controller_in_the_wrong_loop_is_refused(choice, words):
    with pytest.raises(InputError, match=words):
        load_scenario("position-step", controllers=[choice])
