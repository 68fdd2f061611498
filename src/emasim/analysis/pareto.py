"""Tracking against chattering: the Pareto front of a controller set's tuning trials.

The tuning cost weighs two terms (emasim.analysis.report.tuning_terms): the normalised
tracking error and the current command's chattering. One weight picks one point, and a
different weight could reverse a verdict. Every trial of a tuning study records both terms,
so each set has a front: the trials that no other trial beats on both (:func:`pareto_front`).
Two sets are then compared at equal chattering (:func:`best_tracking_within`): the best
tracking each achieves without chattering more than a given level.
"""

import math

MAX_FRONT_POINTS = 40  # a longer front is thinned evenly for the tuned file's record


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The non-dominated (chatter, tracking) points, both to be minimised, sorted by chatter
    (so tracking falls along the front); non-finite points are left out, duplicates kept once."""
    finite = sorted({p for p in points if all(math.isfinite(v) for v in p)})
    front = []
    for chatter, tracking in finite:
        if not front or tracking < front[-1][1]:
            front.append((chatter, tracking))
    return front


def thinned(front: list, at_most: int = MAX_FRONT_POINTS) -> list:
    """At most ``at_most`` points of a front, evenly spread, both ends kept."""
    if len(front) <= at_most:
        return list(front)
    step = (len(front) - 1) / (at_most - 1)
    return [front[round(i * step)] for i in range(at_most)]


def best_tracking_within(front: list, chatter: float) -> float | None:
    """The best tracking on ``front`` with chattering at most ``chatter``; None if every
    point chatters more."""
    within = [tracking for c, tracking in front if c <= chatter]
    return min(within) if within else None


def equal_chatter_table(fronts: dict[str, list], levels: dict[str, float]) -> list[dict]:
    """One row per chattering level (``levels``: name -> chatter, e.g. each set's tuned point):
    the level and each set's best tracking within it (None where its front has no point)."""
    return [
        {
            "at the chattering of": name,
            "chatter": level,
            **{label: best_tracking_within(front, level) for label, front in fronts.items()},
        }
        for name, level in sorted(levels.items(), key=lambda item: item[1])
    ]
