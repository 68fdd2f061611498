"""The hybrid proven part by part: its headline figures with each of its parts switched off,
and with its loops crossed with the PID cascade's, on each bench experiment.

The tuned hybrid is the RBF-network sliding-mode position law (emasim.control.rbf) over the
super-twisting speed law with its GPIO observer (emasim.control.super_twisting). Each
component run changes one thing of the tuned set, everything else as tuned:

* RBF off: adaptation gain 0 (the network's weights stay at W(0) = 0, so f_hat = 0);
* SMC switching off: switching gain eps = 0 (the surface law c de + q s alone);
* GPIO off: the speed law without its observer (``st-improved``, the same gains);
* all three off;
* the hybrid's position law over the PID cascade's speed loop, and the PID's position law over
  the hybrid's speed loop (both as tuned).

:func:`component_lines` reads the numbers: a part whose switching off moves no headline
figure by INERT or more is inert, and for each figure the share of the hybrid's lead over PID
that each crossed cascade keeps says which loop carries it.
"""

from typing import TYPE_CHECKING

from ..analysis.paper_report import (
    BENCH_SINE_ROWS,
    BENCH_STEP_ROWS,
    HEADLINE,
    HYBRID_LABEL,
    PID_LABEL,
)

if TYPE_CHECKING:
    from ..scenarios.schema import Scenario

INERT = 0.05  # a part that moves no headline figure by 5 % or more is inert
TUNED = "as tuned"
PARTS = {  # component -> (position loop changes, speed loop changes)
    "RBF off": ({"adaptation_gain": 0.0}, {}),
    "SMC switching off": ({"switching_gain_m_s2": 0.0}, {}),
    "GPIO off": ({}, {"name": "st-improved"}),
    "all three off": (
        {"adaptation_gain": 0.0, "switching_gain_m_s2": 0.0},
        {"name": "st-improved"},
    ),
}
HYBRID_OVER_PID = "hybrid position law, PID speed loop"
PID_OVER_HYBRID = "PID position law, hybrid speed loop"
COMPONENTS = (TUNED, *PARTS, HYBRID_OVER_PID, PID_OVER_HYBRID)


def figures_of(experiment: str) -> list[str]:
    """The headline figures' metric keys of a bench experiment ('bench_step' or
    'bench_sine'), in the headline's order."""
    rows = BENCH_STEP_ROWS if experiment == "bench_step" else BENCH_SINE_ROWS
    return [rows[row][0] for exp, row, _ in HEADLINE.values() if exp == experiment]


def component_runs(chosen: dict[str, "Scenario"]) -> list[tuple[str, str, "Scenario"]]:
    """(experiment, component, single-set scenario) for every component of COMPONENTS, on
    each chosen bench experiment that compares the hybrid with PID."""
    runs = []
    for name, scenario in chosen.items():
        sets = dict(scenario.variants())
        if not name.startswith("bench") or not {PID_LABEL, HYBRID_LABEL} <= set(sets):
            continue
        hybrid, pid = sets[HYBRID_LABEL].controllers, sets[PID_LABEL].controllers
        crossed = {
            TUNED: hybrid,
            HYBRID_OVER_PID: hybrid.model_copy(update={"speed": pid.speed}),
            PID_OVER_HYBRID: hybrid.model_copy(update={"position": pid.position}),
        }
        for part, (position, speed) in PARTS.items():
            crossed[part] = hybrid.model_copy(
                update={
                    "position": hybrid.position.model_copy(update=position),
                    "speed": type(hybrid.speed).model_validate(hybrid.speed.model_dump() | speed),
                }
            )
        for component in COMPONENTS:
            runs.append(
                (
                    name,
                    component,
                    sets[HYBRID_LABEL].model_copy(update={"controllers": crossed[component]}),
                )
            )
    return runs


def component_tables(runs: list[tuple], results: list, metrics: dict) -> dict[str, list[dict]]:
    """experiment key ('bench_step') -> rows {component, <figure>: value, true_<figure>:
    value}: the component runs' headline figures (measured, and of the true angle), with
    PID's own (``metrics``: experiment name -> label -> metrics) as the last row."""
    tables = {}
    for (name, component, _), result in zip(runs, results, strict=True):
        key = name.replace("-", "_")
        keys = figures_of(key)
        row = {"component": component}
        for figure in keys:
            row[figure] = result.metrics.get(figure)
            row[f"true_{figure}"] = result.metrics.get(f"true_{figure}")
        tables.setdefault(key, []).append(row)
    for key, rows in tables.items():
        pid = metrics[key.replace("_", "-")][PID_LABEL]
        row = {"component": PID_LABEL}
        for figure in figures_of(key):
            row[figure] = pid.get(figure)
            row[f"true_{figure}"] = pid.get(f"true_{figure}")
        rows.append(row)
    return tables


def _relative(value: float, reference: float) -> float:
    return abs(abs(value) - abs(reference)) / abs(reference) if reference else float("inf")


def component_lines(experiment: str, rows: list[dict]) -> list[str]:
    """What the component table says, read off its numbers (measured figures): which of the
    hybrid's parts move its figures (or that they are inert), and for each figure the share of
    the hybrid's lead over PID that each crossed cascade keeps."""
    by = {row["component"]: row for row in rows}
    tuned, pid = by[TUNED], by[PID_LABEL]
    keys = figures_of(experiment)
    moves = {
        part: max(_relative(by[part][k], tuned[k]) for k in keys)
        for part in PARTS
        if part != "all three off"
    }
    lines = []
    if all(move < INERT for move in moves.values()):
        lines.append(
            "The tuned hybrid's own parts are inert here: switching off the RBF, the SMC "
            f"switching or the GPIO moves no headline figure by {INERT:.0%} or more (at most "
            f"{max(moves.values()):.0%}); its figures come from the structure left, the sliding "
            "surface law over the super-twisting speed loop."
        )
    else:
        carried = [f"{part} moves them by up to {move:.0%}" for part, move in moves.items()]
        lines.append("Of the hybrid's parts, " + "; ".join(carried) + ".")
    for k in keys:
        lead = abs(pid[k]) - abs(tuned[k])
        if lead <= 0:
            lines.append(f"{k}: the hybrid has no lead over PID to share out.")
            continue
        kept = {
            name: (abs(pid[k]) - abs(by[name][k])) / lead
            for name in (HYBRID_OVER_PID, PID_OVER_HYBRID)
        }
        lines.append(
            f"{k}: of the hybrid's lead over PID, its position law over the PID's speed loop "
            f"keeps {kept[HYBRID_OVER_PID]:.0%}, the PID's position law over its speed loop "
            f"{kept[PID_OVER_HYBRID]:.0%}."
        )
    return lines
