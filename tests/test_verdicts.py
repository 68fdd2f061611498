"""Verdicts that measure what they judge: the tuning cost ranks controller sets as the bench's
headline figures do, and the bench stays within its loader's rating.

The cost (emasim.analysis.report.tuning_cost) sees the loop's own reading and the steady
window the headline figures judge. On bench-step, with no preload and with 5 N m (the region
where the old rod-IAE cost ranked a set first that lost every step figure by 3x to 17x), a set
that loses all three step figures by 2x or more to another never has the lower cost.
"""

import itertools

import pytest

from emasim.control.pid import PositionPID, SpeedPI
from emasim.errors import InputError
from emasim.experiments.batch import run_all
from emasim.scenarios.loader import load_scenario

STEP_FIGURES = ("steady_error_rms_deg", "chatter_amplitude_deg", "velocity_fluctuation_deg_s")
HAND_PICKED = {  # label -> (speed, position bandwidth, Hz): the issue's, a hunting one, the old
    "PID 15 Hz / 1.5 Hz": (15.0, 1.5),
    "PID 3 Hz / 3 Hz": (3.0, 3.0),
    "PID 2.3 Hz / 1.8 Hz": (2.284, 1.769),  # the PID tuned for the old cost: 33 % overshoot
}


def candidates(preload: float) -> dict[str, object]:
    """label -> single-set bench-step scenario at ``preload`` N m: the tuned sets, and PID
    cascades designed by bandwidth alone (emasim.control.pid)."""
    load = f"plant.load_motor.preload_Nm={preload}"
    short = "duration_s=6"  # 4 s of steady window: the figures and the cost judge the same runs
    sets = {
        label: load_scenario("bench-step", label=label, settings=[load, short])
        for label in ("PID", "hybrid")
    }
    for label, (speed, position) in HAND_PICKED.items():
        controllers = sets["PID"].controllers.model_copy(
            update={
                "speed": SpeedPI(bandwidth_Hz=speed),
                "position": PositionPID(bandwidth_Hz=position, velocity_feedforward=False),
            }
        )
        sets[label] = sets["PID"].model_copy(update={"controllers": controllers})
    return sets


@pytest.fixture(scope="module")
def runs():
    """(preload, label) -> metrics, every candidate at 0 and 5 N m."""
    jobs = {
        (preload, label): sc for preload in (0.0, 5.0) for label, sc in candidates(preload).items()
    }
    results = run_all(list(jobs.values()), labels=[label for _, label in jobs])
    return {key: result.metrics for key, result in zip(jobs, results, strict=True)}


@pytest.mark.parametrize("preload", [0.0, 5.0])
def test_a_set_that_loses_every_step_figure_by_2x_never_wins_the_cost(runs, preload):
    sets = {label: m for (p, label), m in runs.items() if p == preload}
    dominated = 0
    for (a, ma), (b, mb) in itertools.permutations(sets.items(), 2):
        if all(abs(ma[k]) >= 2.0 * abs(mb[k]) for k in STEP_FIGURES):
            dominated += 1
            assert ma["tuning_cost"] > mb["tuning_cost"], (preload, a, b)
    assert dominated, "no pair where one set loses every step figure by 2x: the test is moot"


def test_the_nominal_bench_carries_no_preload_and_the_loader_keeps_its_rating():
    for name in ("bench-step", "bench-sine", "cosim-step"):
        scenario = load_scenario(name)
        assert scenario.plant.load_motor.preload_Nm == 0.0
        assert scenario.plant.load_motor.max_torque_Nm == 94.5  # LAFERT B132I, paper section 3
    with pytest.raises(InputError, match="preload_Nm .* within the load motor's rating"):
        load_scenario("bench-step", settings=["plant.load_motor.preload_Nm=200"])
