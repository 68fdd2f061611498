"""How a comparison is decided (SPEC section 8): paired replicas, Student-t intervals, a
declared tie band and the measurement floor.

Two controller sets ran on the same n replicas (common random numbers: replica i differs from
replica j only as two runs on a real bench differ, emasim.experiments.replicas). Set A (the
baseline) scored x_i and set B (the candidate) y_i on a figure where lower is better (every
judged figure is a magnitude). Each mean, and the mean of the paired difference
d_i = y_i - x_i, is given with its 95 % interval by Student's t:

    m +- t(0.975, n - 1) s / sqrt(n),    s the sample standard deviation

(the pairing removes what both sets share of each replica from d's spread). The **tie band**
(a region of practical equivalence, Benavoli et al. 2017) of a figure is

    B = max(resolution, RELATIVE_BAND * |mean(x)|)

``resolution`` what one encoder count or one rate quantum changes the figure by (declared per
figure where the figure is defined, with its reason), RELATIVE_BAND = 2 % of the baseline: a
difference no control engineer would call practical, whatever the sensor. The rule, in order:

* **tie at the measurement floor**: both means lie within B of the floor's mean, what a
  perfect follower scores through the same sensor chain (None: no floor, as on the true
  angle, which no sensor reads);
* **win** (B better): d's whole interval lies below -B; **loss**: above +B;
* **tie**: d's whole interval lies within [-B, B];
* **not settled**: otherwise, or fewer than MIN_REPLICAS finite pairs (a replica that
  diverged or left a figure undefined is not a number to average: it is reported beside).

The number of replicas is fixed before the runs: none is added after a look at the interval
(that would spend the 95 %), so "not settled" at n says more replicas would be needed.

A difference is printed in percent of the baseline only where the baseline's mean is at least
its resolution and the change lies within +-MAX_PERCENT (:meth:`Decision.percent`); else the
absolute difference is the figure: a percentage of a baseline below its resolution measures
round-off, and one beyond +-1000 % says no more than that the baseline is near zero.
"""

import math
from dataclasses import dataclass

import numpy as np

CONFIDENCE = 0.95
RELATIVE_BAND = 0.02  # of the baseline's mean: the tie band's relative floor
MIN_REPLICAS = 2  # fewer finite pairs give no interval
MAX_PERCENT = 1000.0  # a larger change is given in the figure's unit (module docstring)

WIN, LOSS, TIE = "win", "loss", "tie"
FLOOR_TIE = "tie at the measurement floor"
UNSETTLED = "not settled"
WORDS = (WIN, LOSS, TIE, FLOOR_TIE, UNSETTLED)

# what each word says of a claim that B (the candidate) lowers the figure
SUPPORTED, NOT_SUPPORTED, REVERSED = "supported", "not supported", "reversed"
CLAIM_WORDS = {WIN: SUPPORTED, LOSS: REVERSED, TIE: TIE, FLOOR_TIE: FLOOR_TIE, UNSETTLED: UNSETTLED}


@dataclass(frozen=True)
class Interval:
    """A mean and its two-sided interval (Student t, CONFIDENCE)."""

    mean: float
    low: float
    high: float

    def to_json(self) -> dict:
        return {"mean": self.mean, "low": self.low, "high": self.high}


def t_interval(values, confidence: float = CONFIDENCE) -> Interval:
    """The mean of ``values`` and its Student-t interval (module docstring); an infinite one
    from fewer than two values."""
    from scipy.stats import t

    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return Interval(math.nan, -math.inf, math.inf)
    mean = float(x.mean())
    if x.size < 2:
        return Interval(mean, -math.inf, math.inf)
    half = float(t.ppf(0.5 + 0.5 * confidence, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return Interval(mean, mean - half, mean + half)


def tie_band(baseline_mean: float, resolution: float, relative: float = RELATIVE_BAND) -> float:
    """B = max(resolution, relative * |baseline_mean|) (module docstring)."""
    return max(resolution, relative * abs(baseline_mean))


@dataclass(frozen=True)
class Decision:
    """One figure's verdict of B against A over paired replicas (module docstring):
    ``n`` finite pairs of ``replicas``; both sets' and the difference's (B - A) intervals; the
    tie ``band`` and the ``resolution`` behind it; the ``floor`` (None: none); the ``word``."""

    n: int
    replicas: int
    baseline: Interval
    candidate: Interval
    difference: Interval
    band: float
    resolution: float
    floor: Interval | None
    word: str

    def percent(self) -> Interval | None:
        """The difference in percent of the baseline's mean (its own uncertainty not carried);
        None where that mean is below the figure's resolution or the change beyond
        +-MAX_PERCENT (module docstring)."""
        base = abs(self.baseline.mean)
        if not base >= max(self.resolution, 1e-300):
            return None
        d = self.difference
        out = Interval(100.0 * d.mean / base, 100.0 * d.low / base, 100.0 * d.high / base)
        return out if abs(out.mean) <= MAX_PERCENT else None

    def claim(self, claimed_reduction: float | None = None) -> str:
        """What the verdict says of a claim that B lowers the figure (by ``claimed_reduction``,
        a fraction of A, when given): supported (a win, the claimed size within reach of its
        interval), not supported (a win, but all of its interval short of the claimed size),
        reversed (a loss), tie, tie at the measurement floor, not settled."""
        if self.word == WIN and claimed_reduction is not None:
            largest = -self.difference.low / abs(self.baseline.mean)
            if largest < claimed_reduction:
                return NOT_SUPPORTED
        return CLAIM_WORDS[self.word]

    def to_json(self) -> dict:
        percent = self.percent()
        return {
            "word": self.word,
            "n": self.n,
            "replicas": self.replicas,
            "baseline": self.baseline.to_json(),
            "candidate": self.candidate.to_json(),
            "difference": self.difference.to_json(),
            "percent": None if percent is None else percent.to_json(),
            "band": self.band,
            "resolution": self.resolution,
            "floor": None if self.floor is None else self.floor.to_json(),
        }


def decide(
    baseline,
    candidate,
    resolution: float,
    floor=None,
    relative: float = RELATIVE_BAND,
    confidence: float = CONFIDENCE,
) -> Decision:
    """The verdict of ``candidate`` (B) against ``baseline`` (A), both per replica in the same
    order, lower better; ``floor``: the perfect follower's figure on each replica (or None).
    A pair with a non-finite value (a diverged run, an undefined figure) is left out."""
    a = np.asarray(baseline, dtype=float)
    b = np.asarray(candidate, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError("baseline and candidate: one value per replica, the same replicas")
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    base, cand, diff = (
        t_interval(a, confidence),
        t_interval(b, confidence),
        t_interval(b - a, confidence),
    )
    band = tie_band(base.mean, resolution, relative) if a.size else resolution
    bottom = None
    if floor is not None:
        bottom = t_interval(np.asarray(floor, dtype=float)[keep], confidence)
    if a.size < MIN_REPLICAS:
        word = UNSETTLED
    elif bottom is not None and all(abs(i.mean - bottom.mean) <= band for i in (base, cand)):
        word = FLOOR_TIE
    elif diff.high < -band:
        word = WIN
    elif diff.low > band:
        word = LOSS
    elif -band <= diff.low and diff.high <= band:
        word = TIE
    else:
        word = UNSETTLED
    return Decision(int(a.size), int(keep.size), base, cand, diff, band, resolution, bottom, word)
