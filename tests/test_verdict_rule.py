"""The verdict rule (SPEC section 8, emasim.analysis.verdict_rule) on synthetic pairs whose
answer is known: a clear difference is a win or a loss, a difference inside the band a tie,
one straddling the band's edge not settled, two sets at the floor a tie at the floor."""

import math

import numpy as np
import pytest
from scipy import stats

from emasim.analysis.verdict_rule import (
    FLOOR_TIE,
    LOSS,
    NOT_SUPPORTED,
    RELATIVE_BAND,
    REVERSED,
    SUPPORTED,
    TIE,
    UNSETTLED,
    WIN,
    decide,
    t_interval,
)

N = 16


def replicas(mean: float, spread: float, seed: int) -> np.ndarray:
    """N values about ``mean``: the replica-to-replica spread both sets share."""
    return mean + spread * np.random.default_rng(seed).standard_normal(N)


def test_the_interval_is_students_t_of_the_mean():
    x = replicas(1.0, 0.3, 1)
    low, high = stats.t.interval(0.95, N - 1, loc=x.mean(), scale=stats.sem(x))
    got = t_interval(x)
    assert (got.mean, got.low, got.high) == pytest.approx((x.mean(), low, high), rel=1e-12)


def test_a_clear_reduction_is_a_win_and_a_clear_increase_a_loss():
    shared = replicas(1.0, 0.3, 2)
    own = 0.01 * np.random.default_rng(3).standard_normal(N)
    lower = shared - 0.2 + own  # 20 % below the baseline, far beyond its 2 % band
    assert decide(shared, lower, resolution=0.001).word == WIN
    assert decide(shared, shared + 0.2 + own, resolution=0.001).word == LOSS


def test_pairing_lets_a_difference_smaller_than_the_spread_be_seen():
    """The replicas' shared spread (0.3) is 6 times the difference (0.05): unpaired, the
    intervals would overlap; paired, the difference is a win."""
    shared = replicas(1.0, 0.3, 4)
    candidate = shared - 0.05 + 0.002 * np.random.default_rng(5).standard_normal(N)
    decision = decide(shared, candidate, resolution=0.001)
    assert decision.word == WIN
    assert decision.baseline.low < decision.candidate.high  # the means' intervals overlap


def test_a_difference_inside_the_band_is_a_tie():
    shared = replicas(1.0, 0.3, 6)
    candidate = shared + 0.002 * np.random.default_rng(7).standard_normal(N)
    decision = decide(shared, candidate, resolution=0.001)
    assert decision.band == pytest.approx(RELATIVE_BAND * abs(shared.mean()))
    assert decision.word == TIE


def test_a_difference_straddling_the_band_is_not_settled():
    shared = replicas(1.0, 0.1, 8)
    band = RELATIVE_BAND * shared.mean()
    candidate = shared - band + 0.02 * np.random.default_rng(9).standard_normal(N)
    decision = decide(shared, candidate, resolution=0.0)
    assert decision.difference.low < -decision.band < decision.difference.high
    assert decision.word == UNSETTLED


def test_the_resolution_widens_the_band_beyond_the_relative_floor():
    shared = replicas(1.0, 0.3, 10)
    candidate = shared - 0.05 + 0.002 * np.random.default_rng(11).standard_normal(N)
    decision = decide(shared, candidate, resolution=0.1)  # one count coarser than the gain
    assert decision.band == 0.1
    assert decision.word == TIE


def test_both_sets_at_the_measurement_floor_tie_there_whatever_their_difference():
    """A perfect follower scores 0.026 through the encoder; a set on the floor and one a
    third of a count above it cannot be told apart by that bench."""
    floor = np.full(N, 0.026)
    baseline = floor.copy()
    candidate = floor + 0.03 + 1e-4 * np.random.default_rng(12).standard_normal(N)
    decision = decide(baseline, candidate, resolution=0.088, floor=floor)
    assert decision.word == FLOOR_TIE
    assert decision.floor.mean == pytest.approx(0.026)
    # one count away from the floor is no longer at it
    assert decide(baseline, floor + 0.1, resolution=0.088, floor=floor).word == LOSS


def test_no_percentage_of_a_baseline_below_its_resolution():
    zero = np.zeros(N)
    decision = decide(zero, zero + 1.2, resolution=0.44)
    assert decision.word == LOSS
    assert decision.percent() is None
    above = decide(np.full(N, 2.0), np.full(N, 1.0), resolution=0.44)
    assert above.percent().mean == pytest.approx(-50.0)
    # nor beyond +-1000 %: 0.1 -> 3.8 is given as +3.7, not +3700 %
    assert decide(np.full(N, 0.1), np.full(N, 3.8), resolution=0.0).percent() is None


def test_diverged_or_undefined_replicas_are_left_out_and_counted():
    baseline = replicas(1.0, 0.1, 13)
    candidate = baseline - 0.5
    candidate[3], baseline[5] = math.inf, math.nan
    decision = decide(baseline, candidate, resolution=0.0)
    assert (decision.n, decision.replicas) == (N - 2, N)
    assert decision.word == WIN
    assert decide(baseline[:1], candidate[:1], resolution=0.0).word == UNSETTLED


def test_the_claims_words():
    baseline = np.full(N, 1.0) + replicas(0.0, 0.01, 14)
    halved = baseline * 0.5
    assert decide(baseline, halved, 0.0).claim(0.4) == SUPPORTED
    assert decide(baseline, halved, 0.0).claim(0.75) == NOT_SUPPORTED  # a gain, but short
    assert decide(baseline, baseline * 1.5, 0.0).claim(0.5) == REVERSED
    assert decide(baseline, baseline, 0.0).claim(0.5) == TIE


def test_refuses_unpaired_sets():
    with pytest.raises(ValueError, match="same replicas"):
        decide(np.ones(3), np.ones(4), 0.0)
