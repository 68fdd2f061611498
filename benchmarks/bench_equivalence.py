"""The accuracy contract's distribution equivalence, in full: each headline figure's ensemble
over paired replicas at the shipped integration step h and at h/3 (emasim.experiments.
step_equivalence).

    python benchmarks/bench_equivalence.py              # run (or resume) and print the table
    python benchmarks/bench_equivalence.py --write      # and rewrite equivalence.json and the
                                                        # block of docs/model.md
    python benchmarks/bench_equivalence.py --render     # the block from equivalence.json
    python benchmarks/bench_equivalence.py --replicas 32
    python benchmarks/bench_equivalence.py --quick      # 2 replicas of 0.5 s, in a temporary
                                                        # folder, nothing written (CI)

Both bench experiments, every controller set, REPLICAS replicas at each step (the same noise
seeds and encoder phases at both): the replicas at h are the claims' own study
(``runs/replicas/``, shared with ``emasim reproduce``), those at h/3 a study of their own beside
it; both resume when interrupted. It prints the wall time it took. ``tests/test_replicas.py``
checks that docs/model.md's block is :func:`render` of equivalence.json and that it holds.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from emasim.analysis.claims import equivalence_table
from emasim.experiments.batch import dask_client
from emasim.experiments.replicas import DEFAULT_REPLICAS, SCENARIOS
from emasim.experiments.step_equivalence import run_equivalence
from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "equivalence.json"
DOCS = ROOT / "docs" / "model.md"
BLOCK = "distribution-equivalence"
QUICK = {scenario: ("duration_s=0.5",) for scenario in SCENARIOS}  # --quick: 2 replicas of it


def render(results: dict) -> str:
    return "\n".join(equivalence_table(results))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicas", type=int, default=DEFAULT_REPLICAS)
    parser.add_argument("--write", action="store_true", help="write the json and docs block")
    parser.add_argument("--render", action="store_true", help="the block from equivalence.json")
    parser.add_argument("--quick", action="store_true", help="2 replicas of 0.5 s, nothing kept")
    args = parser.parse_args()
    if args.render:
        write_block(DOCS, BLOCK, render(json.loads(RESULTS.read_text())))
        return 0
    if args.quick:
        with tempfile.TemporaryDirectory() as root, dask_client(processes=False) as client:
            print(render(run_equivalence(2, Path(root), client=client, settings=QUICK)))
        return 0
    start = time.perf_counter()
    results = run_equivalence(args.replicas)
    print(render(results))
    print(f"wall time {time.perf_counter() - start:.0f} s")
    if args.write:
        RESULTS.write_text(json.dumps(results, indent=1) + "\n")
        write_block(DOCS, BLOCK, render(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
