"""Decimated fingerprints of every shipped scenario's traces: the proof that a refactoring of
the core changes no trace.

    python tests/trace_fingerprints.py --write    # store them (before the refactoring)

Every controller set of every shipped scenario runs in full; each trace column is kept at
SAMPLES evenly spaced rows. ``tests/test_fingerprints.py`` runs them again and compares.

The bench scenarios have since moved to the realistic bench (preset sea805-bench): their
fingerprints are those of the idealised bench they were, whose definitions are kept in
IDEALISED (the sea805-linkage preset, the rod sensor in the loop, no delays, no load motor).
"""

import argparse
from pathlib import Path

import numpy as np

from emasim.experiments.batch import run_comparison
from emasim.scenarios.loader import builtin_scenarios, load_scenario

SAMPLES = 48
DATA = Path(__file__).parent / "data"
STORE = DATA / "trace_fingerprints.npz"
IDEALISED = DATA / "idealised"  # the bench scenarios as they were when fingerprinted


def fingerprinted_scenarios() -> dict[str, str]:
    """Name -> the scenario (a shipped name, or a path) that the stored fingerprints were of."""
    chosen = {name: name for name in builtin_scenarios()}
    chosen.update({path.stem: str(path) for path in IDEALISED.glob("*.toml")})
    return chosen


def fingerprints() -> dict[str, np.ndarray]:
    """'scenario/label/column' -> the column at SAMPLES evenly spaced rows."""
    out = {}
    for name, source in sorted(fingerprinted_scenarios().items()):
        comparison = run_comparison(load_scenario(source))
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
