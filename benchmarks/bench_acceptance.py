"""Wall time of the acceptance battery (emasim.experiments.acceptance) on bench-step's plant.

    python benchmarks/bench_acceptance.py [--quick] [--write]

The whole battery (the default Battery) for both controller sets of bench-step, as
``emasim acceptance bench-step`` runs it: threads in this process, the compiled core loaded
beforehand (one short run), REPEATS times; the median wall time. The target (issue 14) is
under two minutes on the 2-core development machine. Interleaved with each, the same battery
with ``excitation="chirp"`` (``emasim acceptance --excitation chirp``): its figures under
``chirp``. Each battery runs in a new temporary folder: the battery keeps its runs in a job
store under ``runs/acceptance/`` of the working folder, and a second battery there would find
them finished and time their reading.

``bench_engine.py`` calls :func:`battery_figures` for its results; ``--write`` stores this
figure alone in benchmarks/results.json (with the day it was measured) and rewrites
docs/speed.md's table. ``--quick`` (what CI runs): one set, QUICK_FREQUENCIES frequencies.
"""

import argparse
import contextlib
import dataclasses
import datetime
import json
import statistics
import tempfile
import time
from pathlib import Path

from speed_figures import RESULTS, write_page

from emasim.experiments.acceptance import Battery, run_acceptance
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate

SCENARIO, REPEATS = "bench-step", 3
QUICK_FREQUENCIES = (1.0, 10.0)


def battery_figures(quick: bool = False) -> dict:
    scenario = load_scenario(SCENARIO)
    simulate(load_scenario(SCENARIO, settings=["duration_s=0.01"]).setup())  # load the core
    if quick:
        battery = Battery(frequencies_Hz=QUICK_FREQUENCIES, stiffness_frequencies_Hz=(1.0,))
        labels, repeats = [scenario.compare[0].label], 1
    else:
        battery, labels, repeats = Battery(), None, REPEATS
    batteries = {"stepped": battery, "chirp": dataclasses.replace(battery, excitation="chirp")}
    walls, results = {name: [] for name in batteries}, {}
    for _ in range(repeats):
        for name, chosen in batteries.items():
            with tempfile.TemporaryDirectory() as folder, contextlib.chdir(folder):
                start = time.perf_counter()
                results[name] = run_acceptance(scenario, labels=labels, battery=chosen)
                walls[name].append(time.perf_counter() - start)
    result, chirp = results["stepped"], results["chirp"]
    return {
        "scenario": SCENARIO,
        "labels": list(result.figures),
        "runs": result.meta["runs"],
        "simulated_s": result.meta["simulated_s"],
        "repeats": repeats,
        "wall_s": statistics.median(walls["stepped"]),
        "chirp": {
            "runs": chirp.meta["runs"],
            "simulated_s": chirp.meta["simulated_s"],
            "wall_s": statistics.median(walls["chirp"]),
        },
        "date": datetime.date.today().isoformat(),
    }


def report(figures: dict) -> None:
    print(
        f"acceptance battery of {figures['scenario']} ({', '.join(figures['labels'])}): "
        f"{figures['runs']} runs, {figures['simulated_s']:.0f} s simulated, "
        f"median wall {figures['wall_s']:.1f} s of {figures['repeats']}"
    )
    chirp = figures.get("chirp")
    if chirp is not None:
        print(
            f"  with --excitation chirp: {chirp['runs']} runs, {chirp['simulated_s']:.0f} s "
            f"simulated, median wall {chirp['wall_s']:.1f} s"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one set, two frequencies")
    parser.add_argument("--write", action="store_true", help="store it and rewrite docs/speed.md")
    args = parser.parse_args()
    figures = battery_figures(args.quick)
    report(figures)
    if args.write and not args.quick:
        results = json.loads(Path(RESULTS).read_text())
        results["acceptance"] = figures
        Path(RESULTS).write_text(json.dumps(results, indent=2) + "\n")
        write_page(results)
        print(f"wrote {RESULTS} and docs/speed.md's table")


if __name__ == "__main__":
    main()
