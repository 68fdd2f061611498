"""Paired speed of this tree against an earlier revision, interleaved in one process.

    python benchmarks/bench_paired.py [--before REV] [--pairs 5] [--quick]

The shared machine is noisy, so two trees are never timed minutes apart. The package of
``REV`` (default HEAD) is extracted with ``git archive`` into a temporary folder as the package
``emasim_before`` and imported beside this tree's ``emasim``. For every shipped scenario, the
first controller set of its comparison is then run alternately on both, ``--pairs`` times each.
The script reports wall seconds per simulated second, the median of each, and the median of
the paired ratios (after / before; below 1 is faster). Two runs are timed per scenario:
``simulate(setup)`` as a script calls it, and the same run with a progress callback, as the
command line runs it. ``--quick`` (CI) runs 0.05 s of each scenario, one pair.
"""

import argparse
import importlib
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

import emasim
from emasim.scenarios.loader import builtin_scenarios

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "emasim_before"
QUICK_S = 0.05


def extract(rev: str, folder: Path) -> None:
    """The package emasim at ``rev`` into ``folder/emasim_before``."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", "--format=tar", rev, "src/emasim"],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    (folder / "src" / "emasim").rename(folder / BEFORE)


def prepared(package: str, name: str, duration_s: float | None):
    """(simulate, setup) of a scenario's first controller set in one of the two packages."""
    loader = importlib.import_module(f"{package}.scenarios.loader")
    engine = importlib.import_module(f"{package}.sim.engine")
    scenario = loader.load_scenario(name)
    if scenario.compare:
        scenario = scenario.variants()[0][1]
    setup = scenario.setup()
    if duration_s is not None:
        setup = setup.with_(duration_s=duration_s)
    engine.simulate(setup.with_(duration_s=setup.sample_period_s * 10))  # compiled code loaded
    return engine.simulate, setup


def timed(simulate, setup, progress) -> float:
    start = time.perf_counter()
    simulate(setup, progress=progress)
    return (time.perf_counter() - start) / setup.duration_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="HEAD", help="git revision to compare against")
    parser.add_argument("--pairs", type=int, default=5, help="interleaved runs of each tree")
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_S} s runs, one pair")
    args = parser.parse_args()
    pairs, duration = (1, QUICK_S) if args.quick else (args.pairs, None)
    with tempfile.TemporaryDirectory() as folder:
        extract(args.before, Path(folder))
        sys.path.insert(0, folder)
        print(f"after: this tree (emasim {emasim.__version__}); before: {args.before}")
        print("scenario          progress  before s/s  after s/s  median after/before")
        for name in sorted(builtin_scenarios()):
            runs = {side: prepared(side, name, duration) for side in (BEFORE, "emasim")}
            for progress in (None, lambda fraction: None):
                times = {side: [] for side in runs}
                for _ in range(pairs):
                    for side, (simulate, setup) in runs.items():
                        times[side].append(timed(simulate, setup, progress))
                before, after = times[BEFORE], times["emasim"]
                ratio = statistics.median(a / b for a, b in zip(after, before, strict=True))
                print(
                    f"{name:16s}  {'yes' if progress else 'no':8s}  "
                    f"{statistics.median(before):10.4f}  {statistics.median(after):9.4f}  "
                    f"{ratio:.3f}"
                )


if __name__ == "__main__":
    main()
