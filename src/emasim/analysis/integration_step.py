"""What the integration-step check says (its runs: emasim.experiments.integration_step).

Each headline figure is measured at half, one and twice the bench's integration step. Against
each baseline (every set the experiment compares but the hybrid) the hybrid's margin at a step
is the verdict map's, 100 (|baseline| - |hybrid|) / |baseline| (:func:`.verdict_map.margin`;
a missing figure, tables.json's null, is a run that diverged). A verdict **holds** when its
margin has the same sign at every step; else it **turns with the step**: the integrator alone
moves the figures across it, so the simulation does not settle it, whatever the Monte Carlo
of the plants (run at the shipped step) says. :func:`step_lines` reads the table, and
:func:`markdown` is the report's section.
"""

import math

from .judged import HYBRID_LABEL, figure_words
from .tables import markdown_table, number_cell
from .verdict_map import margin

HOLDS, TURNS = "holds", "turns with the step"


def _magnitude(value) -> float:
    """|value|, inf for a run that diverged (None or NaN)."""
    return math.inf if value is None or math.isnan(value) else abs(value)


def baselines(entry: dict) -> list[str]:
    """The sets the hybrid is judged against, in the table's order."""
    return [label for label in entry["values"] if label != HYBRID_LABEL]


def margins(entry: dict, baseline: str) -> list[float]:
    """The hybrid's margin (%) against ``baseline`` at each step of ``entry``."""
    pairs = zip(entry["values"][baseline], entry["values"][HYBRID_LABEL], strict=True)
    return [margin(_magnitude(b), _magnitude(h)) for b, h in pairs]


def verdict(entry: dict, baseline: str) -> str:
    """HOLDS when the hybrid wins at every step or at none, else TURNS."""
    wins = {m > 0.0 for m in margins(entry, baseline)}
    return HOLDS if len(wins) == 1 else TURNS


def _step(entry: dict, step: float) -> str:
    shipped = " (shipped)" if step == entry["shipped_step_s"] else ""
    return f"{step:g} s{shipped}"


def _pct(value: float) -> str:
    return f"{value:+.0f} %" if math.isfinite(value) else ("+inf" if value > 0 else "-inf")


def spread(entry: dict, label: str) -> float | None:
    """How far a set's figure moves across the steps: (largest - smallest) / the shipped
    step's; 0 where it does not move, None where a run diverged or it moves off a shipped 0."""
    magnitudes = [_magnitude(v) for v in entry["values"][label]]
    shipped = magnitudes[entry["step_s"].index(entry["shipped_step_s"])]
    moved = max(magnitudes) - min(magnitudes)
    if not all(map(math.isfinite, magnitudes)) or (shipped == 0.0 and moved > 0.0):
        return None
    return moved / shipped if moved else 0.0


def step_line(name: str, entry: dict, baseline: str) -> str:
    """One headline figure's verdict against one baseline at every step, and whether it
    holds (module docstring)."""
    what = f"{figure_words(name)} against {baseline}"
    found = margins(entry, baseline)
    steps = [_step(entry, s) for s in entry["step_s"]]
    shown = ", ".join(f"{_pct(m)} at {s}" for m, s in zip(found, steps, strict=True))
    if verdict(entry, baseline) == HOLDS:
        outcome = "wins" if found[0] > 0.0 else "loses"
        return f"{what}: the hybrid {outcome} at every step (margin {shown}): it holds."
    won = [s for m, s in zip(found, steps, strict=True) if m > 0.0]
    lost = [s for m, s in zip(found, steps, strict=True) if m <= 0.0]
    return (
        f"{what}: the hybrid wins at {', '.join(won)} and loses at {', '.join(lost)} (margin "
        f"{shown}): the verdict turns with the integration step, so the simulation does not "
        "settle it."
    )


def step_lines(table: dict) -> list[str]:
    """:func:`step_line` for every figure and baseline, then how far each figure moves."""
    lines = [
        step_line(name, entry, baseline)
        for name, entry in table.items()
        for baseline in baselines(entry)
    ]
    for name, entry in table.items():
        moved = [
            f"{label} {'-' if (s := spread(entry, label)) is None else f'{100 * s:.0f} %'}"
            for label in entry["values"]
        ]
        lines.append(
            f"{figure_words(name)} ({entry['metric']}) moves "
            f"across the steps by (largest - smallest) / shipped: {', '.join(moved)}."
        )
    return lines


def table_markdown(table: dict) -> str:
    """Each headline figure of each set at every step (rows: figure and set)."""
    first = next(iter(table.values()))
    header = ["figure", "controller set", *(_step(first, s) for s in first["step_s"])]
    body = [
        [
            f"{entry['experiment']}: {entry['metric']} ({entry['unit']})",
            label,
            *map(number_cell, values),
        ]
        for entry in table.values()
        for label, values in entry["values"].items()
    ]
    return markdown_table(header, body)


def body(table: dict) -> str:
    """:func:`table_markdown`, then :func:`step_lines` as a list (the report's section and
    docs/paper.md's block)."""
    lines = "\n".join(f"- {line}" for line in step_lines(table))
    return f"{table_markdown(table)}\n\n{lines}"


def markdown(table: dict) -> list[str]:
    """The report's section: what was run, then :func:`body`."""
    return [
        "## The integration step",
        "Each bench experiment's controller sets run again at half and at twice the plant's "
        "integration step, everything else as shipped (emasim.experiments.integration_step). "
        "A verdict that changes sign across the three steps is within what the integrator "
        "alone moves: the simulation does not settle it.",
        body(table),
    ]
