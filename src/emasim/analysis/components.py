"""What the hybrid's part-by-part table says (the runs: emasim.experiments.components).

Each row is the tuned hybrid with one thing changed: a part switched off (PART_NAMES), or its
loops crossed with the PID cascade's (HYBRID_OVER_PID, PID_OVER_HYBRID); the last row is the
PID cascade itself. :func:`component_lines` reads the numbers: a part whose switching off
moves no headline figure by INERT or more is inert, and for each figure the share of the
hybrid's lead over PID that each crossed cascade keeps says which loop carries it.
"""

from .judged import BENCH_SINE_ROWS, BENCH_STEP_ROWS, HEADLINE, PID_LABEL

INERT = 0.05  # a part that moves no headline figure by 5 % or more is inert
TUNED = "as tuned"
PART_NAMES = ("RBF off", "SMC switching off", "GPIO off", "all three off")
SINGLE_PARTS = PART_NAMES[:3]  # each part alone
HYBRID_OVER_PID = "hybrid position law, PID speed loop"
PID_OVER_HYBRID = "PID position law, hybrid speed loop"
COMPONENTS = (TUNED, *PART_NAMES, HYBRID_OVER_PID, PID_OVER_HYBRID)


def figures_of(experiment: str) -> list[str]:
    """The headline figures' metric keys of a bench experiment ('bench_step' or
    'bench_sine'), in the headline's order."""
    rows = BENCH_STEP_ROWS if experiment == "bench_step" else BENCH_SINE_ROWS
    return [rows[row][0] for exp, row, _ in HEADLINE.values() if exp == experiment]


def _relative(value: float, reference: float) -> float:
    return abs(abs(value) - abs(reference)) / abs(reference) if reference else float("inf")


def component_lines(experiment: str, rows: list[dict]) -> list[str]:
    """What the component table says, read off its numbers (measured figures): which of the
    hybrid's parts move its figures (or that they are inert), and for each figure the share of
    the hybrid's lead over PID that each crossed cascade keeps."""
    by = {row["component"]: row for row in rows}
    tuned, pid = by[TUNED], by[PID_LABEL]
    keys = figures_of(experiment)
    moves = {part: max(_relative(by[part][k], tuned[k]) for k in keys) for part in SINGLE_PARTS}
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
