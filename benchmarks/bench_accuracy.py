"""The accuracy contract's plant replay, in full: every shipped scenario and controller set.

    python benchmarks/bench_accuracy.py            # measure and print the table
    python benchmarks/bench_accuracy.py --write    # and rewrite accuracy.json and the block
                                                   # of docs/model.md
    python benchmarks/bench_accuracy.py --quick    # one set, a short window (CI)

For each shipped scenario and each controller set it compares, the closed loop runs WINDOW_S
at the shipped step; the plant alone is then replayed on the voltages it applied
(emasim.sim.replay) by the engine's scheme at each count of SUBSTEPS RK4 sub-steps a tick, and by
``solve_ivp(DOP853, rtol 1e-10)``. The window holds what a fixed step gets wrong: the start (the
current-limited acceleration), the drive train's backlash contact opening and closing (six
times each in speed-step's first 0.05 s), and the bench's hinge impacts as the rudder moves
(on bench-step its hinges close from 4 ms on and open and close again near 44 ms). A longer
window is out of the reference's reach on the bench: on bench-identify, DOP853 took 1 s for the
first 0.05 s and 244 s for the first 0.1 s, and LSODA did not finish the 0.1 s in 500 s.

For each count it keeps the largest error of a sensed state and of any other state, each
relative to the state's range over the run (emasim.sim.replay.contract_errors), and the state
it is in.

A count keeps the contract when its two errors are within SENSED_TOLERANCE and
INTERNAL_TOLERANCE, and the contract asks it of the shipped count and of one more and one
fewer: a fixed step's error at a contact event depends on where the event falls inside the
sub-step, so one lucky count proves nothing. The table states, per set, the errors at the
shipped count and its neighbours, the apparent order of the scheme between n and 2n sub-steps
(log2 of the ratio of the largest sensed errors) and the cheapest count that keeps the contract
with both its neighbours. ``--render`` rewrites the block from the stored accuracy.json alone.
``tests/test_replay.py`` runs short windows of the same check in the
suite and checks that docs/model.md's block is :func:`render` of accuracy.json.
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

from emasim.page_blocks import write_block
from emasim.scenarios.loader import builtin_scenarios, load_scenario
from emasim.sim import replay

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "accuracy.json"
DOCS = ROOT / "docs" / "model.md"
BLOCK = "accuracy-contract"
WINDOW_S = 0.05
QUICK_S = 0.02
SUBSTEPS = (2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 20)
# scenarios that ship one step between them: the cheapest that keeps the contract on all
SHARED = (("bench-step", "bench-sine"),)


def worst(errors: dict, sensed: bool) -> list:
    """[largest relative error, its state] among the sensed states or the others."""
    chosen = [(e, name) for name, e in errors.items() if (name in replay.SENSED) == sensed]
    error, name = max(chosen)
    return [error, name]


def keeps(row: dict) -> bool:
    """A count's errors are within the contract's bounds."""
    return (
        row["sensed"][0] <= replay.SENSED_TOLERANCE
        and row["internal"][0] <= replay.INTERNAL_TOLERANCE
    )


def cheapest(counts: dict) -> int | None:
    """The fewest sub-steps that keep the contract with one more and one fewer."""
    for n in sorted(counts):
        neighbours = [counts.get(m) for m in (n - 1, n, n + 1)]
        if all(row is not None and keeps(row) for row in neighbours):
            return n
    return None


def measure_set(scenario, window_s: float, substeps: tuple[int, ...]) -> dict:
    """One controller set's replay errors at each count (module docstring)."""
    setup = scenario.setup()
    inputs = replay.applied_inputs(setup, window_s)
    start = time.perf_counter()
    reference = replay.replay_reference(inputs)
    reference_s = time.perf_counter() - start
    counts = {}
    for n in substeps:
        errors = replay.contract_errors(inputs, reference, replay.replay_scheme(inputs, n))
        counts[n] = {"sensed": worst(errors, True), "internal": worst(errors, False)}
    shipped = setup.substeps
    order = (
        math.log2(counts[shipped]["sensed"][0] / counts[2 * shipped]["sensed"][0])
        if 2 * shipped in counts
        else None
    )
    return {
        "shipped": shipped,
        "counts": {str(n): row for n, row in counts.items()},
        "order": order,
        "cheapest": cheapest(counts),
        "reference_s": reference_s,
    }


def measure(quick: bool) -> dict:
    """Every shipped scenario's sets (quick: the first set of speed-step)."""
    names = ["speed-step"] if quick else sorted(builtin_scenarios())
    window_s = QUICK_S if quick else WINDOW_S
    results = {"window_s": window_s, "substeps": list(SUBSTEPS), "scenarios": {}}
    for name in names:
        variants = load_scenario(name).variants()[: 1 if quick else None]
        for label, scenario in variants:
            row = measure_set(scenario, window_s, SUBSTEPS)
            results["scenarios"].setdefault(name, {})[label] = row
            n = row["shipped"]
            at = row["counts"][str(n)]
            print(
                f"{name} {label}: at {n} sub-steps {at['sensed'][0]:.2g} ({at['sensed'][1]}), "
                f"{at['internal'][0]:.2g} ({at['internal'][1]}); cheapest {row['cheapest']} "
                f"(reference {row['reference_s']:.0f} s)",
                flush=True,
            )
    return results


def _cell(row: dict) -> str:
    """'sensed / internal' errors of one count, a mark where the contract is broken."""
    mark = "" if keeps(row) else " ✗"
    return f"{row['sensed'][0]:.1e} / {row['internal'][0]:.1e}{mark}"


def render(results: dict) -> str:
    """docs/model.md's block: a row per scenario and set."""
    lines = [
        f"Measured by `benchmarks/bench_accuracy.py --write` over the first "
        f"{results['window_s']:g} s of each run: the largest error of a sensed state / of any "
        f"other state, each relative to the state's range over the run (bounds "
        f"{replay.SENSED_TOLERANCE:g} / {replay.INTERNAL_TOLERANCE:g}; ✗: beyond).",
        "",
        "| scenario | set | n - 1 | n (shipped) | n + 1 | where, at n | order | cheapest n |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, sets in results["scenarios"].items():
        for label, row in sets.items():
            n, counts = row["shipped"], row["counts"]
            cells = [_cell(counts[str(m)]) for m in (n - 1, n, n + 1)]
            where = f"{counts[str(n)]['sensed'][1]} / {counts[str(n)]['internal'][1]}"
            order = "" if row["order"] is None else f"{row['order']:.1f}"
            lines.append(
                f"| {name} | {label} | " + " | ".join(cells) + f" | {where} (n = {n}) | "
                f"{order} | {row['cheapest']} |"
            )
    lines += ["", shipped_line(results)]
    return "\n".join([*lines, ""])


def scenario_cheapest(sets: dict) -> int | None:
    """The fewest sub-steps that keep the contract, with one more and one fewer, for every
    controller set of a scenario (None: a set keeps it at no measured count)."""
    counts = [row["cheapest"] for row in sets.values()]
    return None if None in counts else max(counts)


def due_count(results: dict, name: str) -> int | None:
    """The count scenario ``name`` should ship: the cheapest that keeps the contract for all
    its sets, or for all the sets of every scenario it shares its step with (SHARED)."""
    group = next((g for g in SHARED if name in g), (name,))
    counts = [scenario_cheapest(results["scenarios"][member]) for member in group]
    return None if None in counts else max(counts)


def shipped_line(results: dict) -> str:
    """Each scenario's shipped count beside the cheapest that keeps the contract for all its
    sets, where the two differ."""
    cells = []
    for name, sets in results["scenarios"].items():
        shipped = {row["shipped"] for row in sets.values()}.pop()
        cheapest = scenario_cheapest(sets)
        differs = "" if shipped == cheapest else f" (its own cheapest {cheapest})"
        cells.append(f"{name} {shipped}{differs}")
    shared = "; ".join(" and ".join(group) for group in SHARED)
    return (
        "Shipped sub-steps a tick: each scenario's cheapest count that keeps the contract with "
        f"one more and one fewer for all its sets, and one count for {shared}, the judged "
        "bench experiments, so that the computation delay's prior draws whole sub-steps on "
        "both: " + ", ".join(cells) + "."
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one set, a short window")
    parser.add_argument("--write", action="store_true", help="write the json and docs block")
    parser.add_argument("--render", action="store_true", help="the block from accuracy.json")
    args = parser.parse_args()
    if args.render:
        write_block(DOCS, BLOCK, render(json.loads(RESULTS.read_text())))
        return 0
    results = measure(args.quick)
    print(render(results))
    if args.write and not args.quick:
        RESULTS.write_text(json.dumps(results, indent=1) + "\n")
        write_block(DOCS, BLOCK, render(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
