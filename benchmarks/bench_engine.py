"""Speed of the engine: real-time factors, start-up, memory, batch scaling, reference speed-up.

    python benchmarks/bench_engine.py [--quick] [--write] [--json FILE]

Real-time factor (RTF) = wall seconds of the simulation alone per simulated second (lower is
faster; 0.05 means 20x faster than real time), best of three runs in this process with the
compiled code loaded. Start-up: fresh ``python -m emasim`` processes with a warm numba cache
(the default cache is warmed first by one ``emasim run speed-step``), each the median of five:
``--help``, ``list``, an input error (``run speed-step --set duration_ms=2``, which must exit
with code 2) and one run (``run speed-step -c speed=pi``, with and without its plot); and a
fresh ``emasim run speed-step`` (every controller) best of three with a warm cache, and one
with an empty cache (cold compile, NUMBA_CACHE_DIR pointed at a new folder).
Reference: the same 0.05 s of speed-step on scipy Radau (rtol 1e-10) against the engine.
Reproduce: three fresh ``emasim reproduce`` processes, every paper experiment and the report;
the median.
Tick split (``tick_split``): speed-step and bench-step at 10, 20 and 40 RK4 sub-steps a
control tick, interleaved, best of 3 each; a straight line through the three splits a tick's
time into its own work and the plant's sub-steps, evaluated at the shipped count (fewer
sub-steps give too short a lever: at 4, 8 and 16 the bench's intercept came out negative).
Peak memory: a fresh process simulates 1 ms of speed-sine (it has imported emasim and loaded
the compiled code: the baseline), then 100 s of it, and prints its peak RSS (``ru_maxrss``)
after each, with the bytes its trace would take in memory (rows x columns x 8; a trace larger
than emasim.sim.spool.SPOOL_BYTES streams to disk instead); 1000 s runs in a process of its own
(MEMORY_S); and each of MEMORY_S through the command line, ``emasim run speed-sine -c speed=pi
--set duration_s=D`` (metrics, plot and result folder included), the longest of speed-step
the same way, bench-step's PID cascade with every column at 10 kHz (BENCH_EXTRA), and
speed-sine written as a MAT-file (``--format mat``) for the longest a MAT-file
variable holds (MAT_S, 2.1 GB of trace, or the longest of MEMORY_S if shorter), whose peak RSS
is the largest of its processes' (``RUSAGE_CHILDREN`` of a fresh process that runs it).
Batch: the study facility's throughput on one and on two worker processes
(``bench_study.study_scaling``); beside it, CEILING PID runs of the same Monte Carlo, cut short,
their compiled loop alone (EngineRun.advance, the GIL released) on one and on two Python
threads: the scaling this machine's two cores allow; and the same runs in one ``prange`` batch
kernel (``batch_kernel.py``) on one and on two of numba's threads, interleaved with them.
Monte Carlo:
the wall time of the 200-run bench-step robustness study of each controller set
(``bench_study.monte_carlo_seconds``). FMU: ``bench_fmu.fmu_figures``, the FMI layer's cost per
``doStep``. Acceptance: the wall time of the whole battery on bench-step's two controller sets
(``bench_acceptance.battery_figures``).

``--write`` stores the figures in ``benchmarks/results.json`` (with the date, platform, CPU
count and the Python, numpy and numba versions) and rewrites docs/speed.md's table from it
(``speed_figures.py``); ``--json FILE`` writes the same figures to FILE only. ``--write
--update NAME`` re-measures one part of the stored figures (SECTIONS: startup_s,
cli_real_time_factor, reproduce_s, peak_memory, batch, monte_carlo, reference), keeps the
rest, and notes the part's date under ``updated``, which the table's first line names. A full
``--write`` keeps the sections that another benchmark stores (KEPT: ``bench_peers.py``'s
``peers``).
``--quick`` (a few seconds, what CI runs): every scenario and controller cut to QUICK_S of
simulated time, one run each, the reference path on QUICK_REFERENCE_S, start-up of ``--help``
and of the input error once each, memory of a QUICK_MEMORY_S run (in process and through the
command line), the batch with bench_study.QUICK_PLANTS plants of its QUICK_S; no ``list``,
single or cold runs, reproduce, Monte Carlo or FMU. Its results are marked ``"quick": true``
and docs/speed.md's table says so.
"""

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import batch_kernel
import bench_acceptance
import bench_study
import numba
import numpy as np
from commands import STARTUP, process_seconds, run_meta, user_environment
from speed_figures import RESULTS, write_page

from emasim.control.registry import CONTROLLERS
from emasim.experiments.study import plan_study
from emasim.scenarios.loader import builtin_scenarios, load_scenario
from emasim.sim.engine import EngineRun, simulate
from emasim.sim.reference import simulate_reference

QUICK_S = 0.05
CEILING = (16, 2.0)  # PID runs of the batch's Monte Carlo, simulated s each, for the loop alone
QUICK_REFERENCE_S = 0.005
MEMORY_S = (100.0, 1000.0)
# bench-step's PID cascade with every column recorded at 10 kHz (it records at 1 kHz as shipped)
BENCH_EXTRA = ("-c", "position=pid", "--set", "solver.record_period_s=0.0001")
MAT_S = 900.0  # speed-sine's 29 columns at 10 kHz: 2.09 GB, under a MAT-file variable's 2 GiB
QUICK_MEMORY_S = 1.0
BASELINE_S = 1e-3
SPLIT_SCENARIOS = ("speed-step", "bench-step")  # tick_split: the lumped plant and the bench
SPLIT_SUBSTEPS = (10, 20, 40)  # a tick's sub-steps: a lever long enough for the line's intercept

QUICK_STARTUP = ("help", "input_error")

# Run in a fresh process: simulate speed-sine for each duration in argv, in turn, and print the
# peak RSS so far (ru_maxrss: kB on Linux, bytes on macOS) and the trace's bytes after each.
MEMORY_CHILD = """
import json, resource, sys
import numpy as np
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate
setup = load_scenario("speed-sine").setup()
unit = 1 if sys.platform == "darwin" else 1024
for text in sys.argv[1:]:
    result = simulate(setup.with_(duration_s=float(text)))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * unit
    rows, columns = result.data.shape
    print(json.dumps({"duration_s": float(text), "peak_rss_bytes": peak,
                      "trace_bytes": 8 * rows * columns, "columns": columns,
                      "streamed": not isinstance(result.data, np.ndarray)}))
    del result
"""
# Run in a fresh process: the command line (argv), then print the peak RSS of the largest of its
# processes (RUSAGE_CHILDREN) and the trace's bytes that its meta.json counts. Its processes are
# children of this small one, so their figures hold none of the benchmark's memory (see RELAY).
CLI_MEMORY_CHILD = """
import json, pathlib, resource, subprocess, sys
out = pathlib.Path(sys.argv[1])
subprocess.run([sys.executable, "-m", "emasim", *sys.argv[2:], "--out", str(out)], check=True,
               capture_output=True)
unit = 1 if sys.platform == "darwin" else 1024
traces = json.loads((out / "meta.json").read_text())["traces"]
print(json.dumps({"peak_rss_bytes": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * unit,
                  "trace_bytes": 8 * traces["rows"] * traces["columns"],
                  "columns": traces["columns"]}))
"""


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


BEFORE_STEP_S = 1e-5  # ten sub-steps a tick: every scenario's step until 2026-12-07
SCHEME_SCENARIOS = ("speed-step", "bench-step", "bench-sine", "cosim-step")
SCHEME_S = 2.0  # simulated by each run of scheme_speedup


def scheme_speedup(runs: int = 5, duration_s: float = SCHEME_S) -> dict:
    """What the shipped step bought, free of the machine's drift between days: each of
    SCHEME_SCENARIOS (its RTF table's controllers) at its shipped step and at BEFORE_STEP_S,
    ``runs`` rounds interleaved in one process, the best of each. name -> the simulated
    seconds, the sub-steps, both RTFs and their ratio."""
    out = {}
    for name in SCHEME_SCENARIOS:
        shipped = load_scenario(name).setup().with_(duration_s=duration_s)
        before = load_scenario(name, settings=[f"solver.step_s={BEFORE_STEP_S!r}"]).setup()
        before = before.with_(duration_s=duration_s)
        for setup in (shipped, before):
            simulate(setup.with_(duration_s=setup.sample_period_s * 10))  # load compiled code
        best = {"shipped": math.inf, "before": math.inf}
        for _ in range(runs):
            for key, setup in (("shipped", shipped), ("before", before)):
                start = time.perf_counter()
                simulate(setup)
                best[key] = min(best[key], (time.perf_counter() - start) / duration_s)
        out[name] = {
            "simulated_s": duration_s,
            "substeps": shipped.substeps,
            "before_substeps": before.substeps,
            "rtf": best["shipped"],
            "before_rtf": best["before"],
            "speedup": best["before"] / best["shipped"],
        }
    return out


def real_time_factors(runs: int = 3, duration_s: float | None = None) -> dict:
    return {
        name: real_time_factor(load_scenario(name), runs, duration_s)
        for name in sorted(builtin_scenarios())
    }


def cli_real_time_factors(
    runs: int = 3, duration_s: float | None = None, names: tuple[str, ...] | None = None
) -> dict:
    """Each scenario as a user runs it, ``emasim run NAME -c ...`` (the controllers
    ``real_time_factors`` times, plots included) in a fresh process, against the same scenario
    simulated in this process: ``runs`` pairs, interleaved, the best of each. The command
    line's figure is its meta.json's simulation wall time (the compile never counts) per
    simulated second. name -> {"cli", "in_process", "ratio"}."""
    out = {}
    for name in names or sorted(builtin_scenarios()):
        choices = load_scenario(name).controllers_label().split(", ")
        args = [name, *(w for c in choices for w in ("-c", c)), "--out", "{out}/run"]
        if duration_s is not None:
            args += ["--set", f"duration_s={duration_s}"]
        setup = load_scenario(name, controllers=choices).setup()
        if duration_s is not None:
            setup = setup.with_(duration_s=duration_s)
        simulate(setup.with_(duration_s=setup.sample_period_s * 10))  # load compiled code
        cli, here = [], []
        for _ in range(runs):
            meta = run_meta(args)
            cli.append(meta["simulation_wall_s"] / setup.duration_s)
            start = time.perf_counter()
            simulate(setup)
            here.append((time.perf_counter() - start) / setup.duration_s)
        out[name] = {"cli": min(cli), "in_process": min(here), "ratio": min(cli) / min(here)}
    return out


def scenario_runs(duration_s: float | None = None) -> tuple[dict, dict]:
    """What ``real_time_factors`` timed: the simulated seconds and the controllers of each."""
    scenarios = {name: load_scenario(name) for name in sorted(builtin_scenarios())}
    durations = {
        name: duration_s if duration_s is not None else s.duration_s
        for name, s in scenarios.items()
    }
    return durations, {name: s.controllers_label() for name, s in scenarios.items()}


def controller_real_time_factors(runs: int = 3, duration_s: float | None = None) -> dict:
    """RTF of every controller, each on the experiment of its loop (speed-step, position-step)."""
    out = {}
    for loop, scenario_name in (("speed", "speed-step"), ("position", "position-step")):
        for name in CONTROLLERS[loop]:
            scenario = load_scenario(scenario_name, controllers=[f"{loop}={name}"])
            out[f"{loop}={name}"] = real_time_factor(scenario, runs, duration_s)
    return out


def startup_seconds(keys=tuple(STARTUP), runs: int = 5) -> dict:
    """Median wall time of ``runs`` fresh processes of each STARTUP command (warm cache)."""
    return {
        key: statistics.median(process_seconds(*STARTUP[key]) for _ in range(runs)) for key in keys
    }


def warm_startup_seconds() -> dict:
    """:func:`startup_seconds` of every STARTUP command, after one fresh run that makes sure
    the default cache is warm."""
    fresh_process_seconds(None)
    return startup_seconds()


def fresh_process_seconds(cache_dir: str | None, *extra: str) -> float:
    env = user_environment(**({"NUMBA_CACHE_DIR": cache_dir} if cache_dir is not None else {}))
    return process_seconds(["run", "speed-step", *extra, "--out", "{out}/run"], env=env)


def reference_speedup(duration_s: float = 0.05) -> dict:
    setup = load_scenario("speed-step", settings=[f"duration_s={duration_s}"]).setup()
    engine = best_of(3, lambda: simulate(setup))
    simulate_reference(setup.with_(duration_s=setup.sample_period_s))  # its compiled code loaded
    start = time.perf_counter()
    simulate_reference(setup)
    reference = time.perf_counter() - start
    return {
        "duration_s": duration_s,
        "engine_s": engine,
        "reference_s": reference,
        "speedup": reference / engine,
    }


def tick_split(
    runs: int = 3, duration_s: float | None = None, names=SPLIT_SCENARIOS, substeps=SPLIT_SUBSTEPS
) -> dict:
    """Where a control tick's time goes: each scenario (its RTF table's controllers) run with
    each of ``substeps`` RK4 sub-steps a tick (``solver.step_s`` = Ts / n, nothing else
    changed), ``runs`` rounds interleaved, the best of each; a least-squares
    line through them, RTF(n) = (tick + n sub_step) / Ts, splits the time into the tick's
    own work (sensors, controllers, drive limits, recording) and the plant's sub-steps (four
    right-hand sides and the bristle's exact steps each). name -> the seconds of each and the
    shares at the shipped sub-step."""
    out = {}
    for name in names:
        base = load_scenario(name)
        ts, shipped = (
            base.solver.sample_period_s,
            round(base.solver.sample_period_s / base.solver.step_s),
        )
        setups = {}
        for n in substeps:
            setup = load_scenario(name, settings=[f"solver.step_s={ts / n!r}"]).setup()
            setups[n] = setup if duration_s is None else setup.with_(duration_s=duration_s)
        simulate(setups[substeps[0]].with_(duration_s=10 * ts))  # load compiled code
        best = dict.fromkeys(substeps, float("inf"))
        for _ in range(runs):
            for n, setup in setups.items():
                start = time.perf_counter()
                simulate(setup)
                best[n] = min(best[n], (time.perf_counter() - start) / setup.duration_s)
        sub_step, tick = np.polyfit(list(best), [ts * best[n] for n in best], 1)
        out[name] = {
            "substeps": {str(n): rtf for n, rtf in best.items()},
            "shipped_substeps": shipped,
            "tick_s": float(tick),
            "sub_step_s": float(sub_step),
            "plant_rtf": float(shipped * sub_step / ts),
            "rtf": float((tick + shipped * sub_step) / ts),
        }
    return out


def reproduce_seconds(runs: int = 3) -> float:
    """Median wall time of ``runs`` fresh ``emasim reproduce`` processes (warm numba cache),
    every experiment."""
    return statistics.median(
        process_seconds(["reproduce", "--out", "{out}/report"]) for _ in range(runs)
    )


# Run the command line (argv) as a child of this small process. A process started straight
# from this benchmark would count the benchmark's own memory in its ru_maxrss: Linux carries the
# peak RSS of the memory a process replaces at exec into its own (the parent's, after a fork or
# vfork), so a child of a 300 MB parent reads 300 MB however little it uses.
RELAY = "import subprocess, sys; sys.exit(subprocess.run(sys.argv[1:]).returncode)"


def peak_memory(*durations_s: float) -> list[dict]:
    """Peak RSS of one fresh process after simulating each of ``durations_s`` of speed-sine in
    turn, and the trace's bytes (MEMORY_CHILD, started through RELAY)."""
    cmd = [sys.executable, "-c", RELAY, sys.executable, "-c", MEMORY_CHILD]
    cmd += [repr(float(d)) for d in durations_s]
    proc = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return [json.loads(line) for line in proc.stdout.splitlines()]


def command_line_memory(
    duration_s: float, scenario: str = "speed-sine", trace_format: str = "parquet", extra=()
) -> dict:
    """Peak RSS of ``emasim run SCENARIO -c speed=pi EXTRA --set duration_s=D --format F`` (the
    largest of its processes, CLI_MEMORY_CHILD), in a new temporary folder, with the trace's
    bytes."""
    args = ["run", scenario, "-c", "speed=pi", *extra, "--set", f"duration_s={duration_s:g}",
            "--format", trace_format]  # fmt: skip
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-c", CLI_MEMORY_CHILD, f"{out}/run", *args]
        proc = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=out,
                              env=user_environment())  # fmt: skip
    return {"scenario": scenario, "duration_s": duration_s, "format": trace_format,
            "extra": " ".join(extra), **json.loads(proc.stdout)}  # fmt: skip


def memory_figures(durations_s) -> dict:
    """The baseline (BASELINE_S: import and compiled code) and the first duration in one
    process, every other duration in a process of its own; each duration through the command
    line, the longest also of speed-step (a step's metrics, in passes) and of bench-step with
    every column at 10 kHz (BENCH_EXTRA: its metrics read their columns whole), and speed-sine's
    MAT-file for the longest of them up to MAT_S."""
    baseline, *runs = peak_memory(BASELINE_S, durations_s[0])
    for duration in durations_s[1:]:
        runs += peak_memory(duration)
    cli = [command_line_memory(duration) for duration in durations_s]
    cli.append(command_line_memory(durations_s[-1], "speed-step"))
    cli.append(command_line_memory(durations_s[-1], "bench-step", extra=BENCH_EXTRA))
    cli.append(command_line_memory(min(durations_s[-1], MAT_S), trace_format="mat"))
    return {"baseline": baseline, "runs": runs, "command_line": cli}


def core_seconds(setups: list, threads: int) -> float:
    """Wall time of the compiled loop alone (EngineRun.advance: no set-up, no metrics, the GIL
    released) on each setup, spread over ``threads`` Python threads."""

    def run(chunk):
        for setup in chunk:
            EngineRun(setup).advance(setup.n_ticks)

    workers = [threading.Thread(target=run, args=(setups[i::threads],)) for i in range(threads)]
    start = time.perf_counter()
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    return time.perf_counter() - start


def batch_scaling(plants: int, duration_s: float | None, repeats: int, ceiling: tuple) -> dict:
    """The study facility on 1 and 2 worker processes (bench_study.study_scaling); and the
    ``ceiling`` (runs, duration_s) of the same Monte Carlo's compiled loop alone, PID (one
    structure, as the batch kernel needs), on 1 and 2 threads, interleaved: the machine's
    ceiling."""
    figures = bench_study.study_scaling(plants, duration_s, repeats)
    ceiling_spec = bench_study.scaling_spec(*ceiling, labels=bench_study.LABELS[:1])
    setups = [job.scenario.setup() for job in plan_study(ceiling_spec).jobs]
    core_seconds(setups[:1], 1)  # load compiled code
    warm = batch_kernel.stack(setups[:2])
    batch_kernel.run_stacked(warm, 2)  # compile the kernel
    batch_kernel.check_against_plain(setups[:2], warm)
    core = {1: [], 2: []}
    kernel = {1: [], 2: []}
    for _ in range(repeats):
        for threads in core:
            core[threads].append(core_seconds(setups, threads))
            stacked = batch_kernel.stack(setups)
            start = time.perf_counter()
            batch_kernel.run_stacked(stacked, threads)
            kernel[threads].append(time.perf_counter() - start)
    core_s = {threads: statistics.median(times) for threads, times in core.items()}
    kernel_s = {threads: statistics.median(times) for threads, times in kernel.items()}
    figures["ceiling_runs"], figures["ceiling_s"] = ceiling
    figures["core_speedup"] = core_s[1] / core_s[2]
    figures["prange_speedup"] = kernel_s[1] / kernel_s[2]
    figures["prange_vs_threads"] = core_s[2] / kernel_s[2]  # above 1: the kernel is faster
    return figures


def machine(quick: bool) -> dict:
    return {
        "quick": quick,
        "date": datetime.date.today().isoformat(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }


def quick_results() -> dict:
    results = machine(quick=True)
    results["real_time_factor"] = real_time_factors(1, QUICK_S)
    results["scenario_duration_s"], results["scenario_controllers"] = scenario_runs(QUICK_S)
    results["controller_real_time_factor"] = controller_real_time_factors(1, QUICK_S)
    results["reference"] = reference_speedup(QUICK_REFERENCE_S)
    results["tick_split"] = tick_split(1, QUICK_S)
    results["scheme_speedup"] = scheme_speedup(1, QUICK_S)
    results["cli_real_time_factor"] = cli_real_time_factors(1, QUICK_S, ("speed-step",))
    results["startup_s"] = startup_seconds(QUICK_STARTUP, runs=1)
    results["peak_memory"] = memory_figures((QUICK_MEMORY_S,))
    quick = (bench_study.QUICK_PLANTS, bench_study.QUICK_S)
    results["batch"] = batch_scaling(*quick, 1, ceiling=quick)
    return results


def full_results() -> dict:
    import bench_fmu  # the plant FMU: pythonfmu and fmpy, only for the full run

    results = machine(quick=False)
    results["real_time_factor"] = real_time_factors()
    results["scenario_duration_s"], results["scenario_controllers"] = scenario_runs()
    results["controller_real_time_factor"] = controller_real_time_factors()
    results["startup_s"] = warm_startup_seconds()
    results["fresh_run_warm_cache_s"] = min(fresh_process_seconds(None) for _ in range(3))
    results["fresh_run_st_gpio_warm_cache_s"] = min(
        fresh_process_seconds(None, "--controller", "speed=st-gpio") for _ in range(3)
    )
    with tempfile.TemporaryDirectory() as cold:
        results["fresh_run_cold_cache_s"] = fresh_process_seconds(cold)
    for name, measure in SECTIONS.items():
        if name not in results:  # start-up, measured above, where it always was
            results[name] = measure()
    results["fmu"] = bench_fmu.fmu_figures(5, 2000)
    results["acceptance"] = bench_acceptance.battery_figures()
    return results


KEPT = ("peers",)  # results.json's sections that another benchmark measures (bench_peers.py)

SECTIONS = {  # the full run's figures that --update re-measures alone
    "real_time_factor": real_time_factors,
    "scenario_duration_s": lambda: scenario_runs()[0],
    "scenario_controllers": lambda: scenario_runs()[1],
    "controller_real_time_factor": controller_real_time_factors,
    "startup_s": warm_startup_seconds,
    "cli_real_time_factor": cli_real_time_factors,
    "reproduce_s": reproduce_seconds,
    "peak_memory": lambda: memory_figures(MEMORY_S),
    "batch": lambda: batch_scaling(
        bench_study.SCALING_PLANTS, None, bench_study.REPEATS, ceiling=CEILING
    ),
    "monte_carlo": lambda: bench_study.monte_carlo_seconds(bench_study.MC_RUNS),
    "reference": reference_speedup,
    "tick_split": tick_split,
    "scheme_speedup": scheme_speedup,
}


def updated_results(names: list[str]) -> dict:
    """The stored results with the ``names`` sections re-measured (each noted in ``updated``
    with today's date)."""
    results = json.loads(RESULTS.read_text())
    for name in names:
        results[name] = SECTIONS[name]()
        results.setdefault("updated", {})[name] = datetime.date.today().isoformat()
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few seconds (module docstring)")
    parser.add_argument(
        "--write",
        action="store_true",
        help="store the figures in benchmarks/results.json and rewrite docs/speed.md's table",
    )
    parser.add_argument("--json", help="also write the figures to this file")
    parser.add_argument(
        "--update",
        action="append",
        choices=list(SECTIONS),
        help="re-measure only this part of the stored results (repeatable; with --write)",
    )
    args = parser.parse_args()
    if args.update and (args.quick or not args.write):
        parser.error("--update re-measures stored results: give --write, not --quick")
    if args.update:
        results = updated_results(args.update)
    else:
        results = quick_results() if args.quick else full_results()
        if args.write:
            stored = json.loads(RESULTS.read_text())
            results.update({key: stored[key] for key in KEPT if key in stored})
    report(results)
    text = json.dumps(results, indent=2) + "\n"
    if args.json:
        Path(args.json).write_text(text)
    if args.write:
        RESULTS.write_text(text)
        write_page(results)
        print(f"wrote {RESULTS} and docs/speed.md's table")


def report(results: dict) -> None:
    for name, rtf in results["real_time_factor"].items():
        print(f"{name:16s} RTF {rtf:.4f} s/s  ({1 / rtf:.0f}x faster than real time)")
    for name, rtf in results["controller_real_time_factor"].items():
        print(f"  {name:20s} RTF {rtf:.4f} s/s")
    for name, pair in results.get("cli_real_time_factor", {}).items():
        print(
            f"{name:16s} command line RTF {pair['cli']:.4f} s/s against {pair['in_process']:.4f}"
            f" in process: {pair['ratio']:.2f}x"
        )
    for key, seconds in results["startup_s"].items():
        print(f"fresh `emasim {' '.join(STARTUP[key][0])}`, warm cache: {seconds:.2f} s")
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
    for name, split in results["tick_split"].items():
        print(
            f"{name}: a tick's own work {split['tick_s'] * 1e9:.0f} ns, a sub-step "
            f"{split['sub_step_s'] * 1e9:.0f} ns; at {split['shipped_substeps']} sub-steps the "
            f"plant's RTF {split['plant_rtf']:.4f} of {split['rtf']:.4f}"
        )
    for name, pair in results.get("scheme_speedup", {}).items():
        print(
            f"{name}: at {pair['substeps']} sub-steps RTF {pair['rtf']:.4f}, at "
            f"{pair['before_substeps']} {pair['before_rtf']:.4f}: {pair['speedup']:.2f}x"
        )
    memory = results["peak_memory"]
    print(f"peak RSS, import + 1 ms run: {memory['baseline']['peak_rss_bytes'] / 1e6:.0f} MB")
    for run in memory["runs"]:
        print(
            f"peak RSS, {run['duration_s']:g} s of speed-sine: "
            f"{run['peak_rss_bytes'] / 1e6:.0f} MB, trace {run['trace_bytes'] / 1e6:.1f} MB "
            f"({'streamed to disk' if run['streamed'] else 'in memory'})"
        )
    for run in memory["command_line"]:
        print(
            f"peak RSS, emasim run {run.get('scenario', 'speed-sine')} -c speed=pi, "
            f"{run['duration_s']:g} s, {run.get('format', 'parquet')}: "
            f"{run['peak_rss_bytes'] / 1e6:.0f} MB, trace {run['trace_bytes'] / 1e6:.1f} MB"
        )
    bench_study.report(results["batch"], results.get("monte_carlo"))
    if "acceptance" in results:
        bench_acceptance.report(results["acceptance"])
    batch = results["batch"]
    print(f"compiled loop alone, 1 against 2 threads: speed-up {batch['core_speedup']:.2f}")
    print(
        f"prange batch kernel, 1 against 2 threads: speed-up {batch['prange_speedup']:.2f}; "
        f"{batch['prange_vs_threads']:.2f}x the speed of 2 Python threads"
    )
    if "fmu" in results:
        fmu = results["fmu"]
        print(
            f"plant FMU doStep {fmu['fmu_us']:.1f} us vs in process {fmu['in_process_us']:.1f} us"
            f" ({fmu['ratio']:.2f}x)"
        )


if __name__ == "__main__":
    main()
