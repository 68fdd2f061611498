"""The step figures computed in passes over blocks (emasim.analysis.passes) against the
whole-array functions of emasim.analysis.metrics, on every way of cutting a response into
blocks, seams between the crossing rows included: they must agree bit for bit."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import emasim.analysis.metrics as m
from emasim.analysis import passes
from emasim.sim.result import seamed_blocks


def _blocks(cuts, *columns):
    """seamed_blocks of ``columns`` cut at the sorted row indices ``cuts``."""
    edges = [0, *sorted(set(cuts)), columns[0].size]
    groups = [[c[a:b] for c in columns] for a, b in zip(edges, edges[1:], strict=False) if b > a]
    return seamed_blocks(groups)


RESPONSE = st.lists(st.floats(-0.5, 1.5), min_size=6, max_size=40)


@settings(max_examples=300, deadline=None)
@given(RESPONSE, st.lists(st.integers(1, 39), max_size=6), st.floats(0.01, 0.3))
def test_step_info_in_blocks_is_the_whole_arrays(values, cuts, dead_zone):
    y = np.array([0.0, *values])
    t = np.arange(y.size) * 0.01
    cuts = [c for c in cuts if c < y.size]
    end = t[-1] + 1.0  # every row (the load step's interval is tested below)
    step = passes.StepInfo(0.0, 1.0, end, dead_zone)
    for block in _blocks(cuts, t, y):
        step.add(*block.columns, block.own_from)
    whole = m.step_info(t, y, initial=0.0, final=1.0, dead_zone_threshold=dead_zone)
    got = step.info()
    assert got.keys() == whole.keys()
    for key, value in whole.items():
        assert got[key] == value or (np.isnan(got[key]) and np.isnan(value)), key


@settings(max_examples=300, deadline=None)
@given(RESPONSE, st.lists(st.integers(1, 39), max_size=6), st.integers(1, 5))
def test_load_recovery_in_blocks_is_the_whole_arrays(values, cuts, load_row):
    y = np.array([0.0, *values])
    t = np.arange(y.size) * 0.01
    reference = np.full(y.size, 0.2)
    cuts = [c for c in cuts if c < y.size]
    t_load = t[load_row] - 0.004  # between rows, so the interval's first row is a whole one

    def read():
        return [(block.own_from, block.columns) for block in _blocks(cuts, t, y, reference)]

    got = passes.load_recovery(read, t_load, t[-1], 0.05, 0.1)
    whole = m.load_recovery(t, y, reference, t_load, band=0.05, t_end=t[-1], dip_fraction=0.1)
    for key in ("dip", "dip_time", "recovery_time", "band"):
        a, b = getattr(got, key), getattr(whole, key)
        assert a == b or (np.isnan(a) and np.isnan(b)), key


def test_a_crossing_at_a_seam_is_interpolated_across_it():
    """A response that reaches 90 % between rows 2 and 3, cut between them: the rise time is
    interpolated across the seam, as on the whole arrays, not taken at the block's first row."""
    t, y = np.arange(6) * 0.1, np.array([0.0, 0.05, 0.5, 1.0, 1.0, 1.0])
    step = passes.StepInfo(0.0, 1.0, 10.0, None)
    for block in _blocks([3], t, y):
        step.add(*block.columns, block.own_from)
    assert step.info()["rise_time_s"] == m.rise_time(t, y, 0.0, 1.0)
