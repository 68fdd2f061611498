"""The speed figures of docs/speed.md, rendered from ``benchmarks/results.json``: the one place
they are worded and formatted.

    python benchmarks/speed_figures.py       # rewrite docs/speed.md's block from results.json

``bench_engine.py --write`` measures, stores ``results.json`` and calls :func:`write_page`;
``bench_peers.py --write`` does the same for its section, ``peers`` (emasim against its peers).
docs/speed.md holds the figures between ``<!-- speed-figures:begin -->`` and
``<!-- speed-figures:end -->`` and nowhere else; ``tests/test_speed_figures.py`` checks that the
block equals :func:`render` of the stored results. Standard library only: the test loads this
file by path and runs no simulation.

Formats: RTF with 3 significant digits and the factor faster than real time (2 significant
digits); seconds (milliseconds below 0.1 s) and microseconds with 2 significant digits; memory
in MB (10^6 bytes) with 3 significant digits; ratios with 2 decimals. A figure missing from the
results (a ``--quick`` run skips the long ones) is shown as "not measured".
"""

import json
import math
from pathlib import Path

from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results.json"
# the figures before the last change of the shipped scheme, shown beside today's: the same
# benchmark's results.json of then, with a "label" that says what it measured
BEFORE = ROOT / "benchmarks" / "results-before.json"
PAGE = ROOT / "docs" / "speed.md"
BLOCK = "speed-figures"
MISSING = "not measured"

RTF_HOW = "best of 3 runs in one process, compiled code loaded"
CLI_HOW = (
    "best of 3 fresh processes (meta.json's simulation wall time: the compile never counts), "
    "interleaved with 3 runs in one process"
)
STARTUP = (  # key in results["startup_s"], what the fresh process runs
    ("help", "`emasim --help`"),
    ("list", "`emasim list`"),
    ("input_error", "`emasim run speed-step --set duration_ms=2` (an input error, exit 2)"),
    ("run_speed_step_pi", "`emasim run speed-step -c speed=pi` (one run, plots included)"),
    ("run_speed_step_pi_no_plot", "`emasim run speed-step -c speed=pi --no-plot` (one run)"),
)
FRESH_RUNS = (  # top-level key, what, how
    (
        "fresh_run_warm_cache_s",
        "`emasim run speed-step` (4 controllers), warm cache, plots included",
        "best of 3 fresh processes",
    ),
    (
        "fresh_run_st_gpio_warm_cache_s",
        "`emasim run speed-step -c speed=st-gpio`, warm cache",
        "best of 3 fresh processes",
    ),
    (
        "fresh_run_cold_cache_s",
        "the first run ever: `emasim run speed-step` on an empty numba cache (compiles everything)",
        "one fresh process, new `NUMBA_CACHE_DIR`",
    ),
    (
        "reproduce_s",
        "`emasim reproduce`: every experiment and the report",
        "median of 3 fresh processes, warm cache",
    ),
)


PROJECTED_PLANTS = 10_000  # what a robustness or sensitivity analysis of a real design needs


def sig(x: float, digits: int) -> str:
    """``x`` with ``digits`` significant digits, in plain notation (870, 5.1, 0.0469)."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    decimals = digits - 1 - math.floor(math.log10(abs(x)))
    rounded = round(x, decimals)
    decimals = digits - 1 - math.floor(math.log10(abs(rounded)))  # 9.96 -> 10, not 10.0
    return f"{rounded:.{max(decimals, 0)}f}"


def seconds(x: float | None) -> str:
    if x is None:
        return MISSING
    return f"{sig(1e3 * x, 2)} ms" if x < 0.1 else f"{sig(x, 2)} s"


def given(x: float) -> str:
    """A length the benchmark chose (not a measurement): as short as it is."""
    return f"{x:g} s"


def megabytes(n: float) -> str:
    return f"{sig(n / 1e6, 3)} MB"


def rtf(r: float) -> str:
    return f"RTF {sig(r, 3)}, {sig(1 / r, 2)}× faster than real time"


def rtf_rows(results: dict, before: dict | None = None) -> list[tuple[str, str, str]]:
    rows = []
    durations = results["scenario_duration_s"]
    controllers = results["scenario_controllers"]
    through = results.get("cli_real_time_factor", {})
    for name, r in results["real_time_factor"].items():
        what = f"`{name}` ({controllers[name]}), {given(durations[name])} simulated"
        rows.append((what, RTF_HOW, rtf(r)))
        if name in through:
            pair = through[name]
            rows.append(
                (
                    f"the same through the command line: `emasim run {name} -c ...`, plots "
                    "included, against the same runs in one process",
                    CLI_HOW,
                    f"RTF {sig(pair['cli'], 3)} against {sig(pair['in_process'], 3)}: "
                    f"{sig(pair['ratio'], 3)}× the in-process time",
                )
            )
    controllers = results["controller_real_time_factor"]
    fastest = min(controllers, key=controllers.get)
    slowest = max(controllers, key=controllers.get)
    rows.append(
        (
            "each speed controller on `speed-step`, each position controller on `position-step`",
            RTF_HOW,
            f"RTF {sig(controllers[fastest], 3)} (`{fastest}`) to "
            f"{sig(controllers[slowest], 3)} (`{slowest}`)",
        )
    )
    rows += scheme_rows(results, before) + split_rows(results)
    ref = results["reference"]
    rows.append(
        (
            f"engine against the scipy Radau reference (rtol 1e-10), "
            f"{given(ref['duration_s'])} of `speed-step`",
            "engine best of 3, reference one run, in one process",
            f"{sig(ref['speedup'], 2)}× faster ({seconds(ref['engine_s'])} against "
            f"{seconds(ref['reference_s'])})",
        )
    )
    return rows


def split_rows(results: dict) -> list[tuple[str, str, str]]:
    """Where a tick's time goes (bench_engine.tick_split): the plant's RK4 sub-steps against
    the tick's own work."""
    rows = []
    for name, split in results.get("tick_split", {}).items():
        counts = ", ".join(split["substeps"])
        share = split["plant_rtf"] / split["rtf"]
        rows.append(
            (
                f"`{name}`: a control tick's time split into its own work (sensors, controllers, "
                "drive limits, recording) and the plant's shipped RK4 sub-steps (four "
                "right-hand sides each)",
                f"a straight line through the RTF at {counts} sub-steps a tick (`solver.step_s`), "
                "best of 3 each, interleaved, in one process",
                f"at {split['shipped_substeps']} sub-steps a tick, the sub-steps alone RTF "
                f"{sig(split['plant_rtf'], 3)} of {sig(split['rtf'], 3)} "
                f"({100 * share:.0f} %): {sig(1e9 * split['sub_step_s'], 3)} ns a sub-step, "
                f"{sig(1e9 * split['tick_s'], 3)} ns a tick's own work; were that work free, "
                f"{sig(1 / share, 3)}× faster at most",
            )
        )
    return rows


def scheme_rows(results: dict, before: dict | None = None) -> list[tuple[str, str, str]]:
    """What the shipped step bought (bench_engine.scheme_speedup): each scenario at its
    shipped sub-steps against the same run at ten, interleaved, measured the same day; with
    ``before``, the RTF the same scenario had then at ten, which shows the machine's drift."""
    rows = []
    then = (before or {}).get("real_time_factor", {})
    for name, pair in results.get("scheme_speedup", {}).items():
        drift = (
            f" (at ten sub-steps on {before['date']}: RTF {sig(then[name], 3)}, this "
            "machine's speed that day)"
            if name in then
            else ""
        )
        rows.append(
            (
                f"`{name}` at its shipped {pair['substeps']} RK4 sub-steps a tick against "
                f"{pair['before_substeps']}, {given(pair['simulated_s'])} simulated",
                "best of 5 runs each, interleaved, in one process",
                f"RTF {sig(pair['rtf'], 3)} against {sig(pair['before_rtf'], 3)}: "
                f"{sig(pair['speedup'], 3)}× faster{drift}",
            )
        )
    return rows


def peer_rows(results: dict) -> list[tuple[str, str, str]]:
    """``bench_peers.py``'s section: emasim's command line, then each peer on the same
    experiment."""
    peers = results.get("peers")
    if peers is None:
        return []
    emasim = peers["emasim"]
    rounds = f"median of {peers['pairs']} fresh processes"
    rows = [
        (
            f"`emasim run {peers['scenario']} -c {peers['controller']} --no-plot`, "
            f"{given(peers['duration_s'])} simulated, against the same experiment on its peers "
            "(`benchmarks/bench_peers.py`; each script in `benchmarks/peers/` says what matches "
            "and what differs)",
            f"{rounds} (meta.json's simulation wall time), interleaved with the peers', after "
            f"one warm-up each; measured on {peers['date']}",
            f"{sig(emasim['s_per_s'], 3)} s per simulated s; the whole process "
            f"{seconds(emasim['process_s'])}",
        )
    ]
    for name, peer in peers["peers"].items():
        rows.append(
            (
                f"the same on {name} {peer['version']} (`{peer['script']}`: {peer['setup']}; "
                "the same PMSM, inertia, friction levels, gains and steps, on rigid mechanics)",
                f"{rounds}, its simulation loop alone, interleaved with emasim's",
                f"{sig(peer['s_per_s'], 3)} s per simulated s: {sig(peer['ratio'], 2)}× "
                f"emasim's (median of the paired ratios); the whole process "
                f"{seconds(peer['process_s'])}",
            )
        )
    return rows


def process_rows(results: dict) -> list[tuple[str, str, str]]:
    startup = results.get("startup_s", {})
    rows = [
        (f"{what}, warm cache", "median of 5 fresh processes", seconds(startup.get(key)))
        for key, what in STARTUP
    ]
    rows += [(what, how, seconds(results.get(key))) for key, what, how in FRESH_RUNS]
    batch = results.get("batch")
    if batch is not None:
        labels = batch.get("labels", ["PID"])
        sets = (
            f"{' and '.join(labels)} on each of {batch['plants']} plants"
            if "plants" in batch
            else ", ".join(labels)
        )
        rows.append(
            (
                f"{batch['runs']} metrics-only Monte Carlo runs of `{batch['scenario']}` "
                f"({sets}; the bench's plant uncertainty drawn, "
                f"{given(batch['duration_s'])} each) through "
                "`emasim study`'s facility, 1 worker process against 2",
                f"median of {batch.get('repeats', 3)} each, interleaved, one cluster at a time, "
                "started beforehand",
                f"{sig(batch['one_worker_sim_s_per_s'], 3)} against "
                f"{sig(batch['two_workers_sim_s_per_s'], 3)} simulated s per s: "
                f"speed-up {batch['speedup']:.2f}",
            )
        )
        if "runs_speedup" in batch:
            rows.append(
                (
                    "the same studies to their last run's end (without the summary's table "
                    "and figure, which the client draws alone afterwards)",
                    "the same processes",
                    f"{seconds(batch['one_worker_runs_s'])} against "
                    f"{seconds(batch['two_workers_runs_s'])}: "
                    f"speed-up {batch['runs_speedup']:.2f}",
                )
            )
        plants = PROJECTED_PLANTS * 2 * batch["duration_s"] / batch["two_workers_sim_s_per_s"]
        rows.append(
            (
                f"{PROJECTED_PLANTS:,} plants of the Monte Carlo above, PID and the hybrid on "
                "each (the robustness study's shape)",
                "projected from the 2-worker throughput above (the runs' count times their "
                "simulated time over it)",
                f"{plants / 3600:.1f} h (the goal: 0.5 h)",
            )
        )
        rows.append(
            (
                f"{batch['ceiling_runs']} PID runs of the same Monte Carlo, "
                f"{given(batch['ceiling_s'])} each: their compiled loop alone (no set-up, no "
                "metrics, GIL released), 1 thread against 2: the machine's ceiling",
                "median of 3 each, interleaved, in one process",
                f"speed-up {batch['core_speedup']:.2f}",
            )
        )
        if "prange_speedup" in batch:
            rows.append(
                (
                    "the same runs in one `prange` batch kernel (`benchmarks/batch_kernel.py`: "
                    "one compiled call, numba's threads), 1 thread against 2",
                    "median of 3 each, interleaved with the threads above",
                    f"speed-up {batch['prange_speedup']:.2f}; on 2 threads "
                    f"{batch['prange_vs_threads']:.2f}× the speed of 2 Python threads",
                )
            )
    battery = results.get("acceptance")
    if battery is not None:
        rows.append(
            (
                f"the acceptance battery of `{battery['scenario']}`'s "
                f"{len(battery['labels'])} controller sets (`emasim acceptance`: "
                f"{battery['runs']} runs, {battery['simulated_s']:.0f} s simulated)",
                f"median of {battery['repeats']}, threads in one process, warm cache; "
                f"measured on {battery['date']}",
                seconds(battery["wall_s"]),
            )
        )
        chirp = battery.get("chirp")
        if chirp is not None:
            rows.append(
                (
                    f"the same with `--excitation chirp` ({chirp['runs']} runs, "
                    f"{chirp['simulated_s']:.0f} s simulated)",
                    "median of the same number, interleaved with the runs above",
                    seconds(chirp["wall_s"]),
                )
            )
    mc = results.get("monte_carlo")
    if mc is not None:
        rows.append(
            (
                f"the {mc['runs']}-run `{mc['scenario']}` robustness Monte Carlo "
                "(`reproduce --robustness`), each controller set alone",
                f"one `run_study` on {mc['workers']} worker processes, cluster start included",
                f"PID {seconds(mc['PID_s'])}, hybrid {seconds(mc['hybrid_s'])}",
            )
        )
    return rows


def more_arguments(run: dict) -> str:
    """The command line's other arguments (bench_engine.command_line_memory's ``extra``), and
    `` --format F`` where it wrote its trace in another format than Parquet."""
    trace_format = run.get("format", "parquet")
    extra = f" {run['extra']}" if run.get("extra") else ""
    return extra + ("" if trace_format == "parquet" else f" --format {trace_format}")


def memory_rows(results: dict) -> list[tuple[str, str, str]]:
    memory = results.get("peak_memory")
    if memory is None:
        return []
    how = "peak RSS (`ru_maxrss`) of a fresh process"
    base = memory["baseline"]
    rows = [
        (
            f"import emasim and load the compiled code (a {1e3 * base['duration_s']:g} ms run of "
            "`speed-sine`)",
            how,
            megabytes(base["peak_rss_bytes"]),
        )
    ]
    for run in memory["runs"]:
        kept = "streamed to disk" if run["streamed"] else "kept in memory"
        rows.append(
            (
                f"simulate {given(run['duration_s'])} of `speed-sine` at 10 kHz in process, its "
                f"trace of {run['columns']} columns ({megabytes(run['trace_bytes'])}) {kept}",
                how,
                megabytes(run["peak_rss_bytes"]),
            )
        )
    for run in memory.get("command_line", []):
        rows.append(
            (
                f"`emasim run {run.get('scenario', 'speed-sine')} -c speed=pi --set "
                f"duration_s={run['duration_s']:g}{more_arguments(run)}` "
                f"(metrics, plot and result folder), a trace of {run['columns']} columns "
                f"({megabytes(run['trace_bytes'])})",
                "peak RSS of the largest of its processes (`RUSAGE_CHILDREN` of a fresh process "
                "that runs it)",
                megabytes(run["peak_rss_bytes"]),
            )
        )
    return rows


def fmu_rows(results: dict) -> list[tuple[str, str, str]]:
    fmu = results.get("fmu")
    what = "plant FMU `doStep` (one tick, 10 sub-steps) against the same sub-steps in process"
    how = "best of 5 runs of 2000 ticks (`bench_fmu.py`)"
    if fmu is None:
        return [(what, how, MISSING)]
    figure = (
        f"{sig(fmu['fmu_us'], 2)} µs against {sig(fmu['in_process_us'], 2)} µs "
        f"(+{sig(fmu['layer_us'], 2)} µs, {fmu['ratio']:.2f}×)"
    )
    return [(what, how, figure)]


def beside(rows: list, before_rows: list, label: str) -> list[tuple[str, str, str]]:
    """Each row's figure with the figure that the row of the same wording had before (its
    measurement ``label``), where there was one and it differs."""
    old = {what: figure for what, _, figure in before_rows}
    out = []
    for what, how, figure in rows:
        was = old.get(what)
        if was is not None and was != figure and MISSING not in (was, figure):
            figure = f"{figure} (before, {label}: {was})"
        out.append((what, how, figure))
    return out


def table_rows(results: dict, before: dict | None = None) -> list[tuple[str, str, str]]:
    rows = rtf_rows(results, before) + peer_rows(results) + process_rows(results)
    return rows + memory_rows(results) + fmu_rows(results)


def load_before() -> dict | None:
    """The stored figures of before (BEFORE), or None."""
    return json.loads(BEFORE.read_text()) if BEFORE.exists() else None


def render(results: dict, before: dict | None = None) -> str:
    """The Markdown between the page's markers (emasim.page_blocks' rule); with ``before``,
    each changed figure beside its old value."""
    lines = []
    if results.get("quick"):
        lines += [
            "**Quick run (`--quick`): short runs, mostly measured once, and the long figures "
            "not measured. These are not the project's figures: "
            "`python benchmarks/bench_engine.py --write` measures them.**",
            "",
        ]
    later = results.get("updated", {})
    lines += [
        f"Measured on {results['date']}: {results['platform']}, {results['cpu_count']} CPUs, "
        f"Python {results['python']}, numpy {results['numpy']}, numba {results['numba']}."
        + "".join(f" `{name}` re-measured on {date}." for name, date in later.items()),
        "",
        "| what | how | measured |",
        "|---|---|---|",
    ]
    rows = table_rows(results, before)
    if before is not None:
        rows = beside(rows, table_rows(before), before["label"])
        lines[-2:-2] = [f"Beside a changed figure: its value before, {before['label']}.", ""]
    lines += [f"| {what} | {how} | {figure} |" for what, how, figure in rows]
    return "\n".join(lines)


def write_page(results: dict, path: Path = PAGE) -> None:
    write_block(path, BLOCK, render(results, load_before()))


def main() -> None:
    write_page(json.loads(RESULTS.read_text()))


if __name__ == "__main__":
    main()
