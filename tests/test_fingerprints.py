"""Every shipped scenario gives the traces it gave before the core was redesigned.

``tests/data/trace_fingerprints.npz`` holds every trace column of every controller set of every
shipped scenario at 48 evenly spaced rows, stored by ``tests/trace_fingerprints.py`` before the
composable-plant redesign, and stored again when the fair tuning rule re-tuned the shipped gains
(only the runs whose gains moved changed: position-step's four sets and speed-step's ST-SMC;
every column of the plant's elements since, the end stops' included; and again when the
verdicts' cost and the five-gain PID re-tuned the simulation scenarios: only speed-step's,
speed-sine's and position-step's traces moved, the frozen bench ones not at all). The runs are
deterministic (two runs in one process agree bit for bit, sliding-mode sets included), so the
comparison allows only 1e-12 of each column's scale: the round-off of a reordered sum, not a
changed model.

They are a same-code regression net, never a check of the physics (docs/model.md, "The accuracy
contract", holds that): last bits change them. Stored again on 2026-12-07, on a machine whose
numpy finds AVX2 but not AVX-512 (X86_V3): there the idealised bench-step's and bench-sine's
traces differed from the stored ones from their first row on (the rod command at t = 0 by
8e-15 of itself, then by up to twice a column's scale on bench-sine), every other scenario's
bit for bit. The rudder table's squares went through np.float_power, which numpy computes by
the processor's SIMD (SVML on AVX-512); they now go through libm's pow on every machine
(emasim.plant.elements.linkage), which gives this machine's values unchanged. bench-identify is
fingerprinted since. Stored again on 2026-12-07 when each shipped scenario moved to the
cheapest step that keeps the accuracy contract (three sub-steps a tick, four on bench-step and
bench-sine, bench-identify's ten unchanged): position-step's, speed-sine's and speed-step's
traces moved, on purpose (the bench's are fingerprinted as the idealised bench they were, at
its own step, and did not); the evidence is the plant replay (benchmarks/accuracy.json) and
the distribution equivalence at h/3 (benchmarks/equivalence.json), stored in the same commit.

The end stops (emasim.plant.elements.stops) came after the fingerprints: a run that stays inside the
stroke must be unchanged, and one that leaves it is compared up to its last stored row before
the first stored row beyond the stroke (position-step's PI sets overshoot 120 mm by 5.8 mm,
onto the 125 mm stop).
"""

import numpy as np
import pytest
from trace_fingerprints import STORE, fingerprinted_scenarios, fingerprints

from emasim.scenarios.loader import load_scenario

RELATIVE = 1e-12


def inside_stroke(stored, run: str) -> slice:
    """The stored rows of run 'scenario/label' before the rod first left the stroke."""
    scenario = load_scenario(fingerprinted_scenarios()[run.split("/")[0]])
    half = 0.5e-3 * scenario.plant.drivetrain.stroke_mm
    beyond = np.flatnonzero(np.abs(stored[f"{run}/actuator_position_m"]) > half)
    return slice(0, beyond[0] if beyond.size else None)


@pytest.fixture(scope="module")
def now():
    return fingerprints()


def test_every_stored_trace_is_reproduced(now):
    stored = np.load(STORE)
    assert set(stored.files) <= set(now), "a column or a controller set disappeared"
    worse = []
    for key in stored.files:
        rows = inside_stroke(stored, key.rsplit("/", 1)[0])
        before, after = stored[key][rows], now[key][rows]
        scale = max(np.nanmax(np.abs(before), initial=0.0), 1e-300)
        same_nan = np.array_equal(np.isnan(before), np.isnan(after))
        error = np.nanmax(np.abs(after - before), initial=0.0) / scale
        if not same_nan or error > RELATIVE:
            worse.append((key, error))
    assert worse == []
