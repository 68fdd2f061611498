"""Tracking against chattering (emasim.analysis.pareto), on points with known fronts."""

import math

from emasim.analysis import paper_report as pr
from emasim.analysis.pareto import (
    best_tracking_within,
    equal_chatter_table,
    pareto_front,
    thinned,
)


def test_the_front_keeps_exactly_the_points_no_other_beats_on_both():
    points = [(1.0, 5.0), (2.0, 3.0), (2.5, 3.5), (3.0, 1.0), (4.0, 1.0), (0.5, 9.0)]
    points += [(math.nan, 0.1), (2.0, 3.0)]  # a diverged trial, a duplicate
    assert pareto_front(points) == [(0.5, 9.0), (1.0, 5.0), (2.0, 3.0), (3.0, 1.0)]
    assert pareto_front([]) == []


def test_a_thinned_front_keeps_both_ends_evenly():
    front = [(float(i), 100.0 - i) for i in range(100)]
    kept = thinned(front, 5)
    assert kept[0] == front[0] and kept[-1] == front[-1] and len(kept) == 5
    assert [c for c, _ in kept] == [0.0, 25.0, 50.0, 74.0, 99.0]  # round(i * 99 / 4)
    assert thinned(front[:3], 5) == front[:3]


def test_sets_compare_at_equal_chattering_not_at_one_weight():
    """A chatters less at its tuned point, B tracks better at its own; at A's chattering B's
    best is worse than A, at B's chattering A cannot go that far: a weight-free verdict that
    flips with the level."""
    a = [(1.0, 4.0), (2.0, 2.0)]
    b = [(1.5, 5.0), (3.0, 1.0)]
    assert best_tracking_within(b, 1.0) is None and best_tracking_within(b, 2.0) == 5.0
    rows = equal_chatter_table({"A": a, "B": b}, {"A": 2.0, "B": 3.0})
    assert rows == [
        {"at the chattering of": "A", "chatter": 2.0, "A": 2.0, "B": 5.0},
        {"at the chattering of": "B", "chatter": 3.0, "A": 2.0, "B": 1.0},
    ]


def test_the_report_shows_the_comparison_only_with_two_fronts():
    record = {
        "sets": {
            "PID": {"front": [[1.0, 4.0], [2.0, 2.0]], "tuned_point": [2.0, 2.0]},
            "hybrid": {"front": [[1.5, 5.0], [3.0, 1.0]], "tuned_point": [3.0, 1.0]},
        }
    }
    lines = pr.pareto_markdown(record)
    assert "Tracking at equal chattering" in lines[0]
    assert "| PID | 2.00 | 2.00 | 5.00 |" in lines[1].replace("  ", " ")
    assert pr.pareto_markdown({"sets": {"PID": record["sets"]["PID"]}}) == []
    assert pr.pareto_markdown({"method": "x", "trials_per_controller_set": 60}) == []


def test_the_pareto_figure_draws_each_front_and_its_tuned_point():
    from emasim.analysis.plots import plot_pareto

    sets = {
        "PID": {"front": [[1.0, 4.0], [2.0, 2.0]], "tuned_point": [2.0, 2.0]},
        "hybrid": {"front": [[1.5, 5.0], [3.0, 1.0]], "tuned_point": [3.0, 1.0]},
    }
    (ax,) = plot_pareto(sets).axes
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert list(lines["PID: front"].get_xdata()) == [1.0, 2.0]
    assert list(lines["hybrid: front"].get_ydata()) == [5.0, 1.0]
    assert list(lines["hybrid: tuned"].get_xdata()) == [3.0]
    assert ax.get_xscale() == ax.get_yscale() == "log"
