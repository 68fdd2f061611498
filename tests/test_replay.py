"""The accuracy contract's plant replay (emasim.sim.replay, docs/model.md "The accuracy
contract"): the plant alone, on the voltages a closed-loop run applied, by the engine's scheme
against ``solve_ivp(DOP853, rtol 1e-10)``.

Short windows that hold contact events (the drive train's backlash opening and closing, the
bench's hinges opening and closing) at the shipped sub-step count and one more and one fewer;
the full check, every scenario and set over 0.5 s, is benchmarks/bench_accuracy.py, whose
stored table docs/model.md shows.
"""

import functools
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from emasim.page_blocks import block_of
from emasim.plant import actuator as A
from emasim.scenarios.loader import load_scenario
from emasim.sim import replay

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_accuracy  # noqa: E402

# scenario: (window start, window end) in s, each holding contact events (test_..._events)
WINDOWS = {
    "speed-step": (0.125, 0.135),  # the backlash closes at 0.1287 s and opens at 0.1303 s
    "position-step": (0.0085, 0.0155),  # closes at 0.0113 s, opens at 0.0137 s, closes again
    "bench-step": (0.04, 0.05),  # hinges 2 to 4 open and close near 0.044 s
}


@functools.cache
def applied(name: str):
    """(its first set's Setup, the applied inputs over the scenario's window), made once."""
    setup = load_scenario(name).variants()[0][1].setup()
    start, end = WINDOWS[name]
    return setup, replay.applied_inputs(setup, end).window(start, end)


@functools.cache
def reference(name: str) -> np.ndarray:
    """The scipy replay of the scenario's window, made once."""
    return replay.replay_reference(applied(name)[1])


@pytest.fixture(scope="module", params=sorted(WINDOWS))
def window(request):
    """(scenario name, its first set's Setup, the applied inputs over the window)."""
    return request.param, *applied(request.param)


def contact_changes(states: np.ndarray, p: np.ndarray, output: str) -> int:
    """How often a contact force ``output`` goes from zero to not zero or back."""
    force = np.array([A.output(output)(x, p) for x in states])
    touching = force != 0.0
    return int(np.count_nonzero(touching[1:] != touching[:-1]))


def test_each_window_holds_contact_events(window):
    name, setup, inputs = window
    outputs = ["drivetrain_force_N"] if name != "bench-step" else ["hinge2_force_N"]
    assert all(contact_changes(inputs.states, setup.plant, o) >= 2 for o in outputs)


def test_the_replay_at_the_shipped_count_is_the_closed_loop_run_bit_for_bit(window):
    """The same scheme on the same inputs, from inside the run (the voltage acting at the
    window's start carried over: bench-step's computation delay is a whole tick)."""
    _, setup, inputs = window
    assert np.array_equal(replay.replay_scheme(inputs, setup.substeps), inputs.states)


def test_the_plant_keeps_the_contract_at_the_shipped_count_and_one_either_side(window):
    name, setup, inputs = window
    for n in (setup.substeps - 1, setup.substeps, setup.substeps + 1):
        errors = replay.contract_errors(inputs, reference(name), replay.replay_scheme(inputs, n))
        assert set(replay.SENSED) & set(errors), errors  # the sensed states moved
        assert replay.breaches(errors) == {}, (name, n, errors)


def test_the_contract_sees_a_voltage_a_tick_late():
    """The check can fail: bench-step's window replayed without the voltage acting at its
    start (0 V over the first tick's delay, a whole tick) breaks the bound on the currents."""
    setup, inputs = applied("bench-step")
    late = replace(inputs, before=(0.0, 0.0))
    replayed = replay.replay_scheme(late, setup.substeps)
    errors = replay.contract_errors(inputs, reference("bench-step"), replayed)
    assert {"id_A", "iq_A"} <= set(replay.breaches(errors)), errors


def test_a_window_outside_the_run_is_refused():
    setup = load_scenario("speed-step").setup()
    inputs = replay.applied_inputs(setup, 0.001)
    with pytest.raises(ValueError, match="outside the run"):
        inputs.window(0.0, 0.002)


def test_the_docs_table_is_what_the_benchmark_measured():
    """docs/model.md's block is the benchmark's rendering of accuracy.json (python
    benchmarks/bench_accuracy.py --write rewrites both), and its verdicts follow from its
    errors."""
    results = json.loads(bench_accuracy.RESULTS.read_text())
    assert block_of(bench_accuracy.DOCS.read_text(), bench_accuracy.BLOCK) == (
        bench_accuracy.render(results)
    )
    for sets in results["scenarios"].values():
        for row in sets.values():
            counts = {int(n): c for n, c in row["counts"].items()}
            assert row["cheapest"] == bench_accuracy.cheapest(counts)


def test_each_scenario_ships_the_cheapest_count_that_keeps_the_contract():
    """The sub-step count a scenario ships (its solver.step_s) is the one the stored
    measurement ran at, and the fewest that keeps the contract, with one more and one fewer,
    for every controller set of the scenario (of the scenarios that share one step, for all
    their sets): no cheaper count was shown to keep it, and no dearer one is paid for
    nothing."""
    results = json.loads(bench_accuracy.RESULTS.read_text())
    for name, sets in results["scenarios"].items():
        shipped = load_scenario(name).solver.substeps
        assert {row["shipped"] for row in sets.values()} == {shipped}, name
        assert bench_accuracy.due_count(results, name) == shipped, name
