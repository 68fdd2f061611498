"""The tuning search's rules (emasim.search_rules) on inputs with known answers."""

import math

import pytest

from emasim.config import hard_limits
from emasim.control.pid import PositionPID, SpeedPI
from emasim.search_rules import (
    BOUND_MARGIN,
    WIDEN_FACTOR,
    Budget,
    bound_side,
    converged,
    widened,
)


def test_converged_compares_the_last_trials_best_with_the_best_before_them():
    # best before the last 3 is 1.0; the last 3 reach 0.995: 0.5 % better, under 1 %
    assert converged([2.0, 1.0, 1.2, 0.995, 1.1], patience=3, tolerance=0.01)
    # ... 0.98 is 2 % better: not converged
    assert not converged([2.0, 1.0, 1.2, 0.98, 1.1], patience=3, tolerance=0.01)
    # no trial before the window: not yet
    assert not converged([1.0, 1.0, 1.0], patience=3, tolerance=0.01)
    assert not converged([1.0, 1.0, 1.0, 1.0], patience=0, tolerance=0.01)
    assert converged([1.0, 1.0, 1.0, 1.0], patience=3, tolerance=0.0)  # no gain at all


def test_an_optimum_within_the_margin_of_the_log_range_is_on_that_bound():
    low, high = 1.0, 100.0  # log width ln 100
    inside = math.exp(0.5 * BOUND_MARGIN * math.log(100.0))
    assert bound_side(inside, low, high) == "lower"
    assert bound_side(high / inside, low, high) == "upper"
    assert bound_side(10.0, low, high) is None
    assert bound_side(math.exp(2.0 * BOUND_MARGIN * math.log(100.0)), low, high) is None


def test_a_range_widens_on_its_side_inside_the_configs_own_limits():
    assert widened(5.0, 300.0, "lower", (0.0, 1e4)) == (5.0 / WIDEN_FACTOR, 300.0)
    assert widened(5.0, 300.0, "upper", (0.0, 1e4)) == (5.0, 300.0 * WIDEN_FACTOR)
    assert widened(5.0, 5000.0, "upper", (0.0, 1e4)) == (5.0, 1e4)  # SpeedPI's le=1e4
    low, _ = widened(1e-3, 1.0, "lower", (1e-3, 100.0))  # at an inclusive limit already
    assert low == pytest.approx(1e-3, rel=1e-8) and low >= 1e-3


def test_the_limits_are_those_the_field_validates():
    assert hard_limits(SpeedPI(), "bandwidth_Hz") == (0.0, 1e4)  # gt=0, le=1e4
    assert hard_limits(PositionPID(), "kd") == (0.0, 100.0)  # ge=0, le=100


def test_the_budget_scales_with_the_knobs_unless_one_count_is_given():
    assert Budget(trials_per_knob=30).cap(8) == 240
    assert Budget(trials=60).cap(8) == 60
    budget = Budget(trials_per_knob=30, patience_per_knob=10, tolerance=0.01, widenings=2)
    assert budget.window(3) == 30 and budget.window(8) == 80
    text = budget.describe()
    assert "30 trials per knob" in text and "1%" in text and "last 10 trials per knob" in text
    assert "at most 2 times" in text
    fixed = Budget(trials=5, patience_per_knob=None, widenings=0)
    assert fixed.describe() == "5 trials per controller set" and fixed.window(3) is None
