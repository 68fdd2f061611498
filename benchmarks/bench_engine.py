"""Speed of the engine: real-time factors, start-up times, speed-up over the reference path.

    python benchmarks/bench_engine.py [--quick] [--json FILE]

Real-time factor (RTF) = wall seconds of the simulation alone per simulated second (lower is
faster; 0.05 means 20x faster than real time), best of three runs in this process with the
compiled code loaded. Start-up: a fresh ``emasim run speed-step`` process end to end with a warm
numba cache, and with an empty cache (cold compile, NUMBA_CACHE_DIR pointed at a new folder).
Reference: the same 0.05 s of speed-step on scipy Radau (rtol 1e-10) against the engine.
Reproduce: a fresh ``emasim reproduce`` process, every paper experiment and the report.
``--quick`` (a few seconds, what CI runs): every scenario and controller cut to QUICK_S of
simulated time, one run each, the reference path on QUICK_REFERENCE_S, and no fresh processes.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from emasim.control.registry import CONTROLLERS
from emasim.scenarios.loader import builtin_scenarios, load_scenario
from emasim.sim.engine import simulate
from emasim.sim.reference import simulate_reference

QUICK_S = 0.05
QUICK_REFERENCE_S = 0.005


def best_of(n, fn):
    best = float("inf")
    for _ in range(n):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def real_time_factor(scenario, runs: int, duration_s: float | None) -> float:
    """Best wall time of ``runs`` simulations per simulated second (compiled code loaded)."""
    setup = scenario.setup()
    if duration_s is not None:
        setup = setup.with_(duration_s=duration_s)
    simulate(setup.with_(duration_s=setup.sample_period_s * 10))  # load compiled code
    return best_of(runs, lambda: simulate(setup)) / setup.duration_s


def real_time_factors(runs: int = 3, duration_s: float | None = None) -> dict:
    return {
        name: real_time_factor(load_scenario(name), runs, duration_s)
        for name in sorted(builtin_scenarios())
    }


def controller_real_time_factors(runs: int = 3, duration_s: float | None = None) -> dict:
    """RTF of every controller, each on the experiment of its loop (speed-step, position-step)."""
    out = {}
    for loop, scenario_name in (("speed", "speed-step"), ("position", "position-step")):
        for name in CONTROLLERS[loop]:
            scenario = load_scenario(scenario_name, controllers=[f"{loop}={name}"])
            out[f"{loop}={name}"] = real_time_factor(scenario, runs, duration_s)
    return out


def fresh_process_seconds(cache_dir: str | None, *extra: str) -> float:
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "emasim", "run", "speed-step", *extra, "--out", f"{out}/run"]
        start = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, capture_output=True)
        return time.perf_counter() - start


def reference_speedup(duration_s: float = 0.05) -> dict:
    setup = load_scenario("speed-step", settings=[f"duration_s={duration_s}"]).setup()
    engine = best_of(3, lambda: simulate(setup))
    start = time.perf_counter()
    simulate_reference(setup)
    reference = time.perf_counter() - start
    return {"engine_s": engine, "reference_s": reference, "speedup": reference / engine}


def reproduce_seconds() -> float:
    """Wall time of a fresh ``emasim reproduce`` (warm numba cache), every experiment."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "emasim", "reproduce", "--out", f"{out}/report"]
        start = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="also write the figures to this file")
    parser.add_argument("--quick", action="store_true", help="a few seconds (module docstring)")
    args = parser.parse_args()
    if args.quick:
        results = {
            "real_time_factor": real_time_factors(1, QUICK_S),
            "controller_real_time_factor": controller_real_time_factors(1, QUICK_S),
            "reference": reference_speedup(QUICK_REFERENCE_S),
        }
        report(results)
        return
    results = {"real_time_factor": real_time_factors()}
    results["controller_real_time_factor"] = controller_real_time_factors()
    fresh_process_seconds(None)  # make sure the default cache is warm
    results["fresh_run_warm_cache_s"] = min(fresh_process_seconds(None) for _ in range(3))
    results["fresh_run_st_gpio_warm_cache_s"] = min(
        fresh_process_seconds(None, "--controller", "speed=st-gpio") for _ in range(3)
    )
    with tempfile.TemporaryDirectory() as cold:
        results["fresh_run_cold_cache_s"] = fresh_process_seconds(cold)
    results["reference"] = reference_speedup()
    results["reproduce_s"] = reproduce_seconds()
    report(results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)


def report(results: dict) -> None:
    for name, rtf in results["real_time_factor"].items():
        print(f"{name:16s} RTF {rtf:.4f} s/s  ({1 / rtf:.0f}x faster than real time)")
    for name, rtf in results["controller_real_time_factor"].items():
        print(f"  {name:20s} RTF {rtf:.4f} s/s")
    for key, what in (
        ("fresh_run_warm_cache_s", "fresh `emasim run speed-step`, warm cache"),
        ("fresh_run_st_gpio_warm_cache_s", "fresh `emasim run speed-step -c speed=st-gpio`, warm"),
        ("fresh_run_cold_cache_s", "fresh `emasim run speed-step`, cold cache"),
        ("reproduce_s", "fresh `emasim reproduce` (all experiments, report)"),
    ):
        if key in results:
            print(f"{what}: {results[key]:.2f} s")
    ref = results["reference"]
    print(
        f"engine vs scipy Radau reference: {ref['engine_s']:.4f} s vs "
        f"{ref['reference_s']:.2f} s, speed-up {ref['speedup']:.0f}x"
    )


if __name__ == "__main__":
    main()
