"""The hybrid part by part (emasim.experiments.components, emasim.analysis.components): the
runs change exactly one thing of the tuned hybrid, and the lines say what the numbers say."""

from emasim.analysis.components import (
    COMPONENTS,
    HYBRID_OVER_PID,
    PID_OVER_HYBRID,
    TUNED,
    component_lines,
)
from emasim.experiments.components import component_jobs
from emasim.scenarios.loader import load_scenario


def test_each_component_run_is_the_tuned_hybrid_with_one_thing_changed():
    chosen = {name: load_scenario(name) for name in ("bench-step", "bench-sine", "speed-step")}
    jobs = component_jobs(chosen)
    assert [(j.tags["experiment"], j.tags["component"]) for j in jobs] == [
        (n, c) for n in ("bench-step", "bench-sine") for c in COMPONENTS
    ]  # the bench experiments only, every component
    assert all(j.label == j.tags["component"] for j in jobs)  # its Result says which
    for name in ("bench-step", "bench-sine"):
        sets = dict(chosen[name].variants())
        hybrid, pid = sets["hybrid"].controllers, sets["PID"].controllers
        by = {
            j.tags["component"]: j.scenario.controllers
            for j in jobs
            if j.tags["experiment"] == name
        }
        assert by[TUNED] == hybrid
        assert by["RBF off"].position.adaptation_gain == 0.0
        assert by["RBF off"].speed == hybrid.speed
        assert by["SMC switching off"].position.switching_gain_m_s2 == 0.0
        assert by["GPIO off"].speed.name == "st-improved"
        assert by["GPIO off"].position == hybrid.position
        off = by["all three off"]
        assert (off.position.adaptation_gain, off.position.switching_gain_m_s2) == (0.0, 0.0)
        assert off.speed.name == "st-improved"
        assert by[HYBRID_OVER_PID].position == hybrid.position
        assert by[HYBRID_OVER_PID].speed == pid.speed
        assert by[PID_OVER_HYBRID].position == pid.position
        assert by[PID_OVER_HYBRID].speed == hybrid.speed


def rows(**changed):
    """A bench-sine table: the tuned hybrid at 1.0 on both figures, PID at 2.0, the crossed
    cascades at 1.5 and 2.0, every part off at 1.0 unless ``changed``."""
    figures = ("tracking_error_deg", "velocity_fluctuation_deg_s")
    values = {c: 1.0 for c in COMPONENTS} | {"PID": 2.0, HYBRID_OVER_PID: 1.5, PID_OVER_HYBRID: 2.0}
    values |= changed
    return [{"component": c, **dict.fromkeys(figures, v)} for c, v in values.items()]


def test_parts_that_move_no_figure_by_5_percent_are_called_inert():
    lines = component_lines("bench_sine", rows(**{"RBF off": 1.04}))
    assert lines[0].startswith("The tuned hybrid's own parts are inert here")
    assert "at most 4%" in lines[0]
    # half of the lead (2.0 -> 1.0) is kept by its position law over the PID's speed loop
    assert lines[1] == (
        "tracking_error_deg: of the hybrid's lead over PID, its position law over the PID's "
        "speed loop keeps 50%, the PID's position law over its speed loop 0%."
    )


def test_a_part_that_moves_a_figure_is_named_with_how_far():
    (first, *_) = component_lines("bench_sine", rows(**{"GPIO off": 1.3}))
    assert (
        first.startswith("Of the hybrid's parts,") and "GPIO off moves them by up to 30%" in first
    )


def test_no_lead_is_said_so():
    lines = component_lines("bench_sine", rows(PID=0.5))
    assert lines[1] == "tracking_error_deg: the hybrid has no lead over PID to share out."
