"""Steady means steady: whether the step test is long enough for its steady figures, and how
the step's claims depend on its length.

The paper's step test ends at 10 s, and its steady figures are read from BENCH_STEADY_S to the
end. A loop that parks on one count for 10 s may start hunting just after (a slow integral
action winds up under the friction), so a verdict read at 10 s can be the window's, not the
controller's. Each controller set's step figures are read again over LONG_S, on the same
replicas (emasim.experiments.replicas), and the two ensembles compared by the verdict rule
(emasim.analysis.verdict_rule; the longer run's figure less the paper's): a set's steady
figures are **established** at the paper's length where every one of them is a tie, measured
and true. The step's claims at LONG_S, beside the paper's length's, show how the verdict
depends on the length.
"""

from pathlib import Path

from .replicas import DEFAULT_SEED, ROOT, all_tied, claims, compared, record, run_tables

SCENARIO = "bench-step"
LONG_S = 40.0  # four times the paper's 10 s: 38 s of steady window against its 8 s


def long_settings() -> dict[str, tuple[str, ...]]:
    """The settings that run the step test over LONG_S."""
    return {SCENARIO: (f"duration_s={LONG_S!r}",)}


def run_length(
    replicas: int,
    root: Path = ROOT,
    progress=None,
    client=None,
    seed: int = DEFAULT_SEED,
) -> dict:
    """Run (or resume) the step's replicas over LONG_S (those at the paper's length are the
    claims' own study, emasim.experiments.replicas) and return :func:`length_table`."""
    paper = run_tables(replicas, root, progress, client, seed)
    longer = run_tables(replicas, root, progress, client, seed, settings=long_settings())
    return length_table(paper, longer, replicas, seed)


def length_table(paper: dict, longer: dict, replicas: int, seed: int = DEFAULT_SEED) -> dict:
    """From the replica study tables of the step at the paper's length (``paper``) and over
    LONG_S (``longer``): each step figure's comparison per set (``figures``, emasim.
    experiments.replicas.compared), whether each set's figures are established (``steady``:
    label -> all tied) and the step's claims over LONG_S (``claims``)."""
    from ..scenarios.loader import load_scenario

    figures = compared({SCENARIO: paper[SCENARIO]}, {SCENARIO: longer[SCENARIO]})
    labels = list(figures[0]["sets"]) if figures else []
    steady = {
        label: all_tied([{"sets": {label: f["sets"][label]}} for f in figures]) for label in labels
    }
    return record(replicas, seed) | {
        "conditions": [f"{load_scenario(SCENARIO).duration_s:g} s", f"{LONG_S:g} s"],
        "figures": figures,
        "steady": steady,
        "claims": claims({SCENARIO: longer[SCENARIO]}, replicas, seed, long_settings()),
    }
