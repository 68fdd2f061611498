"""The accuracy contract's distribution equivalence (docs/model.md): each headline figure's
ensemble over paired replicas agrees at the shipped integration step h and at h/3, within the
figure's tie band.

A closed-loop figure of the bench never converges with h: the controllers act on encoder
counts, so a change of h, like a new noise seed, moves a single run's figure as far as a count
moves it. The step's effect is therefore judged as any other difference is
(emasim.analysis.verdict_rule): on the same replicas (emasim.experiments.replicas: the same
noise seeds and encoder phases at both steps), for each controller set, the difference of the
figure at h/3 less at h, its 95 % interval, the figure's tie band and measurement floor. The
contract holds where every figure of every set, measured and true, is a tie or a tie at the
measurement floor. The full check is ``benchmarks/bench_equivalence.py``; the replicas at h are
the claims' own study.
"""

from pathlib import Path

from .replicas import DEFAULT_SEED, ROOT, SCENARIOS, all_tied, compared, record, run_tables

FACTOR = 1.0 / 3.0  # the finer step, of the shipped one


def fine_settings(scenario: str) -> tuple[str, ...]:
    """The settings that run ``scenario`` at FACTOR times its shipped step."""
    from ..scenarios.loader import load_scenario

    return (f"solver.step_s={FACTOR * load_scenario(scenario).solver.step_s!r}",)


def run_equivalence(
    replicas: int,
    root: Path = ROOT,
    progress=None,
    client=None,
    seed: int = DEFAULT_SEED,
    settings: dict[str, tuple[str, ...]] | None = None,
) -> dict:
    """Run (or resume) the replicas at the shipped step and at FACTOR of it, and return
    :func:`equivalence`; ``settings`` (scenario -> ``KEY=VALUE`` texts) change both from
    the shipped scenarios (a shorter run, for a quick look)."""
    base = settings or {}
    shipped = run_tables(replicas, root, progress, client, seed, settings=base)
    fine = {s: base.get(s, ()) + fine_settings(s) for s in SCENARIOS}
    finer = run_tables(replicas, root, progress, client, seed, settings=fine)
    return equivalence(shipped, finer, replicas, seed, base)


def equivalence(
    shipped: dict,
    fine: dict,
    replicas: int,
    seed: int = DEFAULT_SEED,
    settings: dict[str, tuple[str, ...]] | None = None,
) -> dict:
    """Each headline figure's decision, per controller set and column, of its ensemble at the
    finer step (``fine``, scenario -> study table) against the shipped step's (``shipped``,
    its scenarios changed by ``settings``: emasim.experiments.replicas.compared), and whether
    every one keeps the contract (``holds``)."""
    from ..scenarios.loader import load_scenario

    figures = compared(shipped, fine, settings)
    step = {s: load_scenario(s).solver.step_s for s in SCENARIOS}
    return record(replicas, seed) | {
        "conditions": ["h", "h/3"],
        "step_s": {s: [h, FACTOR * h] for s, h in step.items()},
        "figures": figures,
        "holds": all_tied(figures),
    }
