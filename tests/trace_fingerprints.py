"""Decimated fingerprints of every shipped scenario's traces: the proof that a refactoring of
the core changes no trace.

    python tests/trace_fingerprints.py --write    # store them (before the refactoring)

Every controller set of every shipped scenario runs in full; each trace column is kept at
SAMPLES evenly spaced rows. ``tests/test_fingerprints.py`` runs them again and compares.
"""

import argparse
from pathlib import Path

import numpy as np

from emasim.experiments.batch import run_comparison
from emasim.scenarios.loader import builtin_scenarios, load_scenario

SAMPLES = 48
STORE = Path(__file__).parent / "data" / "trace_fingerprints.npz"


def fingerprints() -> dict[str, np.ndarray]:
    """'scenario/label/column' -> the column at SAMPLES evenly spaced rows."""
    out = {}
    for name in sorted(builtin_scenarios()):
        comparison = run_comparison(load_scenario(name))
        for label, result in comparison.results.items():
            rows = np.linspace(0, len(result.t) - 1, SAMPLES).round().astype(int)
            for column in result.columns:
                out[f"{name}/{label}/{column}"] = result[column][rows]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"store them in {STORE}")
    if parser.parse_args().write:
        np.savez_compressed(STORE, **fingerprints())
        print(f"wrote {STORE}")


if __name__ == "__main__":
    main()
