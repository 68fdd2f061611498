"""The position loop closes on the rod sensor, the rudder encoder or the motor encoder
(loop.position_feedback).

With rudder feedback the position controller sees the rod position that the rigid kinematics
give for the encoder's angle (emasim.scenarios.schema.rudder_rod_grid, the same map the rudder
reference goes through), so the hinge clearances sit inside the loop. Checks:

* on the lumped stage the rudder angle is x_L / arm exactly, so both feedbacks give the same
  run to round-off;
* on the linkage, with ideal sensors, the loop's position reading is the map of the true
  rudder angle, and it differs from the rod's own position by the play of the clearances;
* with motor feedback (the semi-closed loop) the loop reads K theta_m, the nut's travel, and the
  backlash sits outside the loop: at rest after the step the nut holds the command and the rod
  stands off it, within the half gap;
* rudder and motor feedback without a position loop are refused.
"""

import numpy as np
import pytest

from emasim.errors import InputError
from emasim.scenarios.loader import load_scenario
from emasim.scenarios.schema import rudder_rod_grid
from emasim.signals import MAX_TABLE_POINTS, encode, signal_values
from emasim.sim.engine import simulate

RUDDER = "loop.position_feedback='rudder'"


def run(name: str, *settings: str):
    scenario = load_scenario(name, controllers=["position=pid"], settings=list(settings))
    return scenario, simulate(scenario.setup())


def test_on_the_lumped_stage_rudder_feedback_is_rod_feedback():
    _, rod = run("position-step", "duration_s=0.3")
    _, rudder = run("position-step", "duration_s=0.3", RUDDER)
    for column in ("actuator_position_m", "iq_ref_A", "measured_position_m"):
        scale = np.max(np.abs(rod[column]))
        assert np.max(np.abs(rudder[column] - rod[column])) <= 1e-9 * scale, column


def test_on_the_linkage_the_loop_reads_the_rudder_through_the_kinematics():
    scenario, result = run("bench-step", "duration_s=0.3", "sensors='ideal'", RUDDER)
    angles, rods = rudder_rod_grid(scenario.plant)
    expected = np.interp(result["rudder_angle_rad"], angles, rods)
    assert np.max(np.abs(result["measured_position_m"] - expected)) < 1e-12
    play = np.abs(result["measured_position_m"] - result["actuator_position_m"])
    assert play.max() > 1e-7  # the clearances (0.01 mm at four hinges) are inside the loop


def test_a_rudder_command_longer_than_a_scenario_table_sets_up():
    """The linkage's rod command is the rudder command through the kinematics, a point every
    millisecond: 1001 s of it is more points than a scenario file's table may hold
    (signals.MAX_TABLE_POINTS), and emasim builds it all the same (it failed with an internal
    error). It is the kinematics' grid interpolated at the command, to the chord between its
    points."""
    scenario = load_scenario("bench-sine", settings=["duration_s=1001"]).variants()[0][1]
    setup = scenario.setup()
    assert setup.reference[2] / 2 == 1_001_001 > MAX_TABLE_POINTS
    angles, rods = rudder_rod_grid(scenario.plant)
    t = np.array([0.0, 0.0005, 3.21, 500.0, 1000.9995, 1001.0])
    angle = signal_values(encode(scenario.reference.rudder_deg, np.radians(1.0)), t)
    rod = signal_values(setup.reference, t)
    expected = np.interp(angle, angles, rods)  # a sine's chord over 1 ms: 1e-8 of its swing
    assert np.all(np.abs(rod - expected) < 1e-6 * np.ptp(rods))


def test_motor_feedback_reads_the_encoder_as_the_nut_travel():
    ideal = ["duration_s=2.5", "sensors='ideal'", "plant.backlash.width_mm=0.4"]
    scenario, motor = run("position-step", *ideal, "loop.position_feedback='motor'")
    k = scenario.plant.ratio_m_per_rad
    assert np.max(np.abs(motor["measured_position_m"] - k * motor["motor_angle_rad"])) < 1e-15
    target = motor["position_ref_m"][-1]
    half_gap = 0.2e-3
    # at rest the nut holds the command; the rod is where the gap left it, within it
    assert abs(k * motor["motor_angle_rad"][-1] - target) < 1e-6
    assert 1e-5 < abs(motor["actuator_position_m"][-1] - target) <= 1.01 * half_gap


@pytest.mark.parametrize("feedback", ["rudder", "motor"])
def test_encoder_feedback_needs_a_position_loop(feedback):
    with pytest.raises(InputError, match="position_feedback"):
        load_scenario("speed-step", settings=[f"loop.position_feedback='{feedback}'"])
