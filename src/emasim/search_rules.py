"""When a tuning search stops and where it looks: the budget, convergence and bound widening.

A controller set with more knobs needs more trials, so a fixed trial count for every set
favours the one with fewer knobs. :class:`Budget` gives each set

* a cap of ``trials_per_knob`` x its number of knobs (or one fixed ``trials`` for all), and
* an early stop once converged: the best cost of the last ``patience_per_knob`` x knobs
  trials is less than ``tolerance`` (relative) below the best before them (:func:`converged`).
  The window grows with the knobs too: a search of 8 knobs takes longer to find a better
  point than one of 3, and a fixed window would stop it first.

An optimum that sits on a bound of its search range (:func:`bound_side`: within BOUND_MARGIN
of the range's log width) says the range was too narrow. The range is widened on that side by
WIDEN_FACTOR, as far as the config's own validation allows
(:func:`emasim.config.hard_limits`), and the search goes on for another round under the same
rule, at most ``widenings`` times. An optimum still on a bound after that is reported.
"""

import math
from dataclasses import dataclass

BOUND_MARGIN = 0.02  # an optimum this close to a bound, as a fraction of the log range, is on it
WIDEN_FACTOR = 4.0  # a bound the optimum sits on moves out by this factor


@dataclass(frozen=True)
class Budget:
    """How long each controller set is searched (module docstring). ``trials``: one count for
    every set, per round; else ``trials_per_knob`` x knobs. ``patience_per_knob``: stop a round
    early once its last ``patience_per_knob`` x knobs trials improved the best by less than
    ``tolerance`` (None: never early). ``widenings``: rounds of widening a bound the optimum
    sits on."""

    trials: int | None = None
    trials_per_knob: int = 40
    patience_per_knob: int | None = 10
    tolerance: float = 0.01
    widenings: int = 3
    neighbours: int = 32  # points of the neighbourhood check of the optimum (0: none)

    @classmethod
    def fixed(cls, trials: int) -> "Budget":
        """A fixed count of trials for every set: no early stop, no widening, no
        neighbourhood check."""
        return cls(trials=trials, patience_per_knob=None, widenings=0, neighbours=0)

    def cap(self, knobs: int) -> int:
        """The trials of one round for a set with ``knobs`` knobs."""
        return self.trials if self.trials is not None else self.trials_per_knob * knobs

    def window(self, knobs: int) -> int | None:
        """The trials over which a set with ``knobs`` knobs must improve (None: no early stop)."""
        return self.patience_per_knob * knobs if self.patience_per_knob else None

    def describe(self) -> str:
        """The rule in words, for the tuned file's record and the report."""
        cap = (
            f"{self.trials} trials per controller set"
            if self.trials is not None
            else f"at most {self.trials_per_knob} trials per knob"
        )
        early = (
            f", stopped once the best cost improved by less than {self.tolerance:.0%} over the "
            f"last {self.patience_per_knob} trials per knob"
            if self.patience_per_knob
            else ""
        )
        widen = (
            f"; an optimum on a bound widens it x{WIDEN_FACTOR:g} and the search goes on "
            f"(at most {self.widenings} times)"
            if self.widenings
            else ""
        )
        return cap + early + widen


def converged(values: list[float], patience: int, tolerance: float) -> bool:
    """True when the best of ``values`` (costs in trial order) is less than ``tolerance``
    (relative) below the best of all but the last ``patience`` of them."""
    if patience < 1 or len(values) <= patience:
        return False
    before, now = min(values[:-patience]), min(values)
    return before - now <= tolerance * abs(before)


def bound_side(value: float, low: float, high: float) -> str | None:
    """'lower' or 'upper' when ``value`` lies within BOUND_MARGIN of that bound of the log
    range [low, high], else None."""
    where = (math.log(value) - math.log(low)) / (math.log(high) - math.log(low))
    if where <= BOUND_MARGIN:
        return "lower"
    if where >= 1.0 - BOUND_MARGIN:
        return "upper"
    return None


def widened(low: float, high: float, side: str, limits: tuple[float, float]):
    """The range with ``side`` moved out by WIDEN_FACTOR, kept inside ``limits`` (the lower
    bound strictly above a zero or exclusive limit)."""
    lower_limit, upper_limit = limits
    if side == "lower":
        return max(low / WIDEN_FACTOR, lower_limit * (1.0 + 1e-9), math.nextafter(0.0, 1.0)), high
    return low, min(high * WIDEN_FACTOR, upper_limit)
