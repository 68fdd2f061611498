"""Paired speed of this tree against an earlier revision, in interleaved processes.

    python benchmarks/bench_paired.py [--before REV] [--after REV] [--pairs 5] [--quick]
                                      [--scenarios-from REV]
                                      [--commands [--only KEY]...] [--reproduce]

The shared machine is noisy, so two trees are never timed minutes apart. The package of
``--before`` (default HEAD) is extracted with ``git archive`` into a temporary folder, and
so is ``--after``'s; without ``--after``, this working tree's package is copied there when
the measurement begins, so that edits made meanwhile (this tree is shared) neither change what
is timed nor start a new numba cache, whose compile would land in a timed process. Then
``--pairs`` times, one process runs the revision and one runs this tree, the revision first
in even pairs and second in odd ones (so neither side always runs second). Each process
times every shipped scenario's first controller set once, after a warm-up. Two calls are
timed per scenario: ``simulate(setup)`` as a script calls it, and the same run with a
progress callback, as the command line runs it. A scenario re-tuned between the trees runs
other gains in each; ``--scenarios-from REV`` has both trees time that revision's scenario
files instead (each read by its path), so that only the engine differs; a file either tree
refuses is left out.

The script reports wall seconds per simulated second, the median of each tree, and the
median of the paired ratios (after / before; below 1 is faster). The two trees cannot share
one process: numba types the record classes of ``emasim.sim.core`` by name, so two copies of
one class in one process collide. ``--quick`` (CI) runs 0.05 s of each scenario, one pair.

``--commands`` times whole command lines instead: each of COMMANDS (the start-up figures'
commands of ``commands.STARTUP`` and the four-controller ``run speed-step``) as one fresh
``python -m emasim`` process of each tree, interleaved the same way, after one warm-up process
of each (numba's cache and the bytecode filled); ``--only KEY`` (repeatable) times only those
of COMMANDS, e.g. ``--only run_speed_step_pi --only run_speed_step_pi_no_plot``.
``--reproduce`` times ``emasim reproduce`` (every paper experiment and the report, about half
a minute) the same way.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

from commands import STARTUP, process_seconds, user_environment

ROOT = Path(__file__).resolve().parents[1]
QUICK_S = 0.05
MODES = ("plain", "progress")
COMMANDS = {**STARTUP, "run_speed_step": (["run", "speed-step", "--out", "{out}/run"], 0)}
REPRODUCE = {"reproduce": (["reproduce", "--out", "{out}/report"], 0)}


def extract(rev: str, folder: Path, path: str = "src/emasim") -> Path:
    """``path`` of ``rev`` (by default its package) under ``folder``; its ``src`` folder."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", rev, path],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    return folder / "src"


def snapshot(folder: Path) -> Path:
    """A copy of this working tree's package (without bytecode) under ``folder``; its src
    folder."""
    package = ROOT / "src" / "emasim"
    shutil.copytree(
        package, folder / "src" / "emasim", ignore=shutil.ignore_patterns("__pycache__")
    )
    return folder / "src"


def scenario_files(rev: str, folder: Path) -> list[str]:
    """The shipped scenario files of ``rev``, extracted under ``folder``: their paths."""
    scenarios = extract(rev, folder, "src/emasim/scenarios") / "emasim" / "scenarios"
    return sorted(str(p) for p in scenarios.glob("*.toml"))


def measure(duration_s: float | None, files: list[str]) -> dict:
    """In this process: scenario -> mode -> wall seconds per simulated second, for the shipped
    scenarios or the scenario ``files``."""
    from emasim.errors import EmasimError
    from emasim.scenarios.loader import builtin_scenarios, load_scenario
    from emasim.sim.engine import simulate

    out = {}
    for name in files or sorted(builtin_scenarios()):
        try:
            scenario = load_scenario(name)
        except EmasimError as err:  # a file of another revision that this tree refuses
            print(f"skipped: {err}", file=sys.stderr)
            continue
        name = Path(name).stem
        if scenario.compare:
            scenario = scenario.variants()[0][1]
        setup = scenario.setup()
        if duration_s is not None:
            setup = setup.with_(duration_s=duration_s)
        simulate(setup.with_(duration_s=setup.sample_period_s * 10))  # compiled code loaded
        out[name] = {}
        for mode in MODES:
            progress = (lambda fraction: None) if mode == "progress" else None
            start = time.perf_counter()
            simulate(setup, progress=progress)
            out[name][mode] = (time.perf_counter() - start) / setup.duration_s
    return out


def run_tree(src: Path, duration_s: float | None, files: list[str]) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src))
    cmd = [sys.executable, "-W", "ignore", __file__, "--measure", *files]
    if duration_s is not None:
        cmd += ["--duration", str(duration_s)]
    done = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout)


def command_seconds(src: Path, commands: dict) -> dict:
    """Wall seconds of one fresh process of each of ``commands`` (key -> (arguments, exit
    code)), importing the tree ``src``."""
    env = user_environment(PYTHONPATH=str(src))
    return {key: process_seconds(args, expect, env) for key, (args, expect) in commands.items()}


def interleaved(trees: dict, pairs: int, measure_one) -> dict:
    """side -> [measure_one(tree) of each pair], before first in even pairs, after in odd."""
    times = {side: [] for side in trees}
    for i in range(pairs):
        for side in ("before", "after") if i % 2 == 0 else ("after", "before"):
            times[side].append(measure_one(trees[side]))
    return times


def print_medians(rows: list[tuple[str, list, list]]) -> None:
    """One line per (name, before values, after values): both medians and the median of the
    paired ratios."""
    for name, before, after in rows:
        ratio = statistics.median(a / b for a, b in zip(after, before, strict=True))
        print(
            f"{name:36s}  {statistics.median(before):10.4f}  "
            f"{statistics.median(after):9.4f}  {ratio:.3f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="HEAD", help="git revision to compare against")
    parser.add_argument(
        "--after", default=None, help="git revision to time (default: a copy of this tree)"
    )
    parser.add_argument("--pairs", type=int, default=5, help="interleaved runs of each tree")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_S} s runs, one pair")
    parser.add_argument(
        "--commands", action="store_true", help="time whole command lines (module docstring)"
    )
    parser.add_argument(
        "--only",
        action="append",
        choices=list(COMMANDS),
        help="with --commands: time only this command (repeatable)",
    )
    parser.add_argument("--reproduce", action="store_true", help="time `emasim reproduce`")
    parser.add_argument(
        "--scenarios-from", default=None, help="both trees time this revision's scenario files"
    )
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("files", nargs="*", help=argparse.SUPPRESS)
    parser.add_argument("--duration", type=float, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        print(json.dumps(measure(args.duration, args.files)))
        return
    pairs, duration = (1, QUICK_S) if args.quick else (args.pairs, None)
    if args.only and not args.commands:
        parser.error("--only picks commands: give --commands")
    with tempfile.TemporaryDirectory() as folder:
        before, after = Path(folder) / "before", Path(folder) / "after"
        trees = {
            "before": extract(args.before, before),
            "after": extract(args.after, after) if args.after else snapshot(after),
        }
        files = scenario_files(args.scenarios_from, Path(folder)) if args.scenarios_from else []
        commands = {key: COMMANDS[key] for key in args.only or COMMANDS}
        commands = REPRODUCE if args.reproduce else commands if args.commands else None
        if commands:
            for src in trees.values():
                command_seconds(src, commands)  # numba's cache and the bytecode filled
            times = interleaved(trees, pairs, lambda src: command_seconds(src, commands))
        else:
            for src in trees.values():
                run_tree(src, QUICK_S, files)  # fill each tree's numba cache before timing
            times = interleaved(trees, pairs, lambda src: run_tree(src, duration, files))
    print(
        f"after: {args.after or 'this tree'}; before: {args.before}; {pairs} interleaved pairs "
        "of processes" + (f"; both on the scenario files of {args.scenarios_from}" if files else "")
    )
    if commands:
        print(
            f"{'command (wall s of a fresh process)':36s}  {'before':>10s}  {'after':>9s}  "
            "median after/before"
        )
        print_medians(
            [
                (key, [t[key] for t in times["before"]], [t[key] for t in times["after"]])
                for key in commands
            ]
        )
        return
    print(f"{'scenario, mode (s/s)':36s}  {'before':>10s}  {'after':>9s}  median after/before")
    print_medians(
        [
            (
                f"{name} {mode}",
                [t[name][mode] for t in times["before"]],
                [t[name][mode] for t in times["after"]],
            )
            for name in times["before"][0]
            if name in times["after"][0]
            for mode in MODES
        ]
    )


if __name__ == "__main__":
    main()
