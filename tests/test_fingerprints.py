"""Every shipped scenario gives the traces it gave before the core was redesigned.

``tests/data/trace_fingerprints.npz`` holds every trace column of every controller set of every
shipped scenario at 48 evenly spaced rows, stored by ``tests/trace_fingerprints.py`` before the
composable-plant redesign. The runs are deterministic (two runs in one process agree bit for
bit, sliding-mode sets included), so the comparison allows only 1e-12 of each column's scale:
the round-off of a reordered sum, not a changed model.
"""

import numpy as np
import pytest
from trace_fingerprints import STORE, fingerprints

RELATIVE = 1e-12


@pytest.fixture(scope="module")
def now():
    return fingerprints()


def test_every_stored_trace_is_reproduced(now):
    stored = np.load(STORE)
    assert set(stored.files) <= set(now), "a column or a controller set disappeared"
    worse = []
    for key in stored.files:
        before, after = stored[key], now[key]
        scale = max(np.nanmax(np.abs(before), initial=0.0), 1e-300)
        same_nan = np.array_equal(np.isnan(before), np.isnan(after))
        error = np.nanmax(np.abs(after - before), initial=0.0) / scale
        if not same_nan or error > RELATIVE:
            worse.append((key, error))
    assert worse == []
