"""The report's, the pages' and the command line's words on decisions over paired replicas
(the rule in emasim.analysis.verdict_rule): the abstract's claims (the table of
emasim.experiments.replicas.claims) and the integration step's distribution equivalence
(emasim.experiments.step_equivalence.equivalence)."""

import math

from .verdict_rule import FLOOR_TIE, TIE, UNSETTLED


def _number(value: float) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.3g}"


def _interval(i: dict) -> str:
    return f"{_number(i['mean'])} [{_number(i['low'])}, {_number(i['high'])}]"


def _signed(value: float) -> str:
    """+0.0139, −53.7 (the minus sign as the pages' other tables write it)."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:+.3g}".replace("-", "−")


def _difference(d: dict, unit: str) -> str:
    """The difference (hybrid - baseline, signed) with its interval: in percent of the
    baseline where Decision.percent gives one, else in the unit."""
    i, tail = (d["percent"], " %") if d["percent"] is not None else (d["difference"], f" {unit}")
    return f"{_signed(i['mean'])} [{_signed(i['low'])}, {_signed(i['high'])}]{tail}"


def markdown(table: dict) -> list[str]:
    """The report's section on the claims (emasim.experiments.replicas.claims), then
    :func:`summary_line`."""
    n, confidence = table["replicas"], round(100 * table["confidence"])
    lines = [
        "## The abstract's claims over paired replicas",
        f"Each figure over {n} replicas, every controller set on the same ones: the sensors' "
        "noise and each encoder grid's phase drawn afresh (emasim.experiments.replicas). "
        f"Means with their {confidence} % interval ({table['interval']}); the difference is "
        "the hybrid's less the baseline's (negative: the hybrid lower, better), paired, in "
        "percent of the baseline where the baseline's mean is at least the figure's "
        "resolution, else in its unit. Band: the tie band, the larger of the figure's "
        f"resolution and {100 * table['relative_band']:g} % of the baseline's mean. Floor: "
        "what a perfect follower scores through the same encoder. *Measured* is what the "
        "bench sees (the rudder encoder); *true* is the rudder's angle, which no sensor on "
        "the bench reads. Claim: supported (a win), not supported (a win short of the paper's "
        "size), reversed (a loss), tie, tie at the measurement floor, or not settled.",
    ]
    for baseline in table["claims"][0]["against"]:
        lines += [
            f"### Hybrid against {baseline}",
            "| figure | column | baseline | hybrid | floor | difference | band | claim |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for claim in table["claims"]:
            unit = claim["unit"]
            for column, d in claim["against"][baseline].items():
                floor = "-" if d["floor"] is None else _number(d["floor"]["mean"])
                lines.append(
                    f"| {claim['words']} ({unit}) | {column} | {_interval(d['baseline'])} "
                    f"| {_interval(d['candidate'])} | {floor} | {_difference(d, unit)} "
                    f"| {_number(d['band'])} | {d['claim']} |"
                )
    return [*lines, summary_line(table)]


def claim_lines(table: dict) -> list[str]:
    """One line per claim and baseline: the measured and the true claim words (the command
    line's summary of :func:`claims`)."""
    lines = []
    for claim in table["claims"]:
        for baseline, columns in claim["against"].items():
            lines.append(
                f"{claim['words']} against {baseline}: measured {columns['measured']['claim']}, "
                f"true {columns['true']['claim']}"
            )
    return lines


def _counted(words: list[tuple[str, str]]) -> str:
    """'supported on 1 (a); tie at the measurement floor on 2 (b, c)' from (word, figure)
    pairs, in the order the words first appear."""
    order = list(dict.fromkeys(word for word, _ in words))
    return "; ".join(
        f"{word} on {sum(w == word for w, _ in words)} "
        f"({', '.join(f for w, f in words if w == word)})"
        for word in order
    )


def summary_line(table: dict) -> str:
    """The claims' verdicts in one paragraph: for each baseline, what the bench measures,
    then the true angle, which it cannot see."""
    parts = []
    for column, seen in (
        ("measured", "as the bench measures (its rudder encoder)"),
        ("true", "on the true rudder angle, which the bench cannot see"),
    ):
        against = []
        for baseline in table["claims"][0]["against"]:
            words = [(c["against"][baseline][column]["claim"], c["words"]) for c in table["claims"]]
            against.append(f"against {baseline}: {_counted(words)}")
        parts.append(f"{seen}, the abstract's claims are, " + "; ".join(against))
    return f"Over {table['replicas']} paired replicas, " + ". And ".join(parts) + "."


def summary_table(table: dict) -> list[str]:
    """The claims in one table, a row a figure: the paper's reduction, then each baseline's
    measured and true claim with its difference (hybrid less baseline) and interval, the
    band and the floor; then :func:`summary_line`."""
    baselines = list(table["claims"][0]["against"])
    header = ["claim: the hybrid lowers", "paper"]
    for baseline in baselines:
        header += [f"against {baseline}, measured", f"against {baseline}, true"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for claim in table["claims"]:
        unit = claim["unit"]
        cells = [f"{claim['words']} ({unit})", f"−{100 * claim['paper_reduction']:.0f} %"]
        for baseline in baselines:
            for d in claim["against"][baseline].values():
                cells.append(_cell(d, unit, d["claim"]))
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, "", summary_line(table)]


def _cell(d: dict, unit: str, word: str) -> str:
    """'word: difference [interval] (band b, floor f)' of one decision."""
    extra = f"band {_number(d['band'])}"
    if d["floor"] is not None:
        extra += f", floor {_number(d['floor']['mean'])}"
    return f"{word}: {_difference(d, unit)} ({extra})"


def _compared_rows(table: dict) -> tuple[list[str], list[str]]:
    """The rows of a comparison of two conditions over paired replicas (the ``figures`` of
    emasim.experiments.replicas.compared, ``conditions`` [before, after]), a row a figure and
    controller set, and the decisions that are no tie, named."""
    before, after = table["conditions"]
    lines = [
        f"| figure | controller set | measured: {after} less {before} "
        f"| true: {after} less {before} |",
        "|---|---|---|---|",
    ]
    untied = []
    for figure in table["figures"]:
        unit = figure["unit"]
        for label, columns in figure["sets"].items():
            cells = [_cell(d, unit, d["word"]) for d in columns.values()]
            lines.append(f"| {figure['words']} ({unit}) | {label} | {' | '.join(cells)} |")
            untied += [
                f"{figure['words']} of {label} ({column}: {d['word']})"
                for column, d in columns.items()
                if d["word"] not in (TIE, FLOOR_TIE)
            ]
    return lines, untied


def equivalence_table(table: dict) -> list[str]:
    """The distribution equivalence (emasim.experiments.step_equivalence.equivalence) in one
    table, then one line: whether the contract holds (every decision a tie), and otherwise
    which figures moved beyond their band (a win or a loss) and which are not settled."""
    lines, untied = _compared_rows(table)
    steps = ", ".join(f"{name} {h:g} s" for name, (h, _) in table["step_s"].items())
    line = f"Over {table['replicas']} paired replicas at the shipped step h ({steps}) and at h/3: "
    if table["holds"]:
        line += "every figure of every set, measured and true, is a tie: the contract holds."
    else:
        moved = [u for u in untied if f": {UNSETTLED})" not in u]
        unsettled = [u for u in untied if f": {UNSETTLED})" in u]
        total = sum(len(c) for f in table["figures"] for c in f["sets"].values())
        line += (
            f"{total - len(untied)} of {total} decisions are ties; moved beyond the band: "
            f"{'; '.join(moved) if moved else 'none'}; not settled at this many replicas: "
            f"{'; '.join(unsettled) if unsettled else 'none'}. The contract is shown where "
            "every decision is a tie."
        )
    return [*lines, "", line]


def length_markdown(table: dict) -> list[str]:
    """The report's section on the step test's length: a heading, then :func:`length_body`."""
    short, long = table["conditions"]
    return [f"## Steady means steady: the step over {short} and over {long}", *length_body(table)]


def length_body(table: dict) -> list[str]:
    """The step test's length (emasim.experiments.run_length.length_table): each set's step
    figures at the paper's length against a longer test, whether each set's are established,
    and the step's claims over the longer test."""
    short, long = table["conditions"]
    lines, _ = _compared_rows(table)
    verdicts = [
        f"{label}: {'established' if steady else 'not established'} at {short}"
        for label, steady in table["steady"].items()
    ]
    return [
        f"The step test again over {long}, on the same {table['replicas']} replicas: each "
        f"set's steady figures are established at {short} where every one is a tie with the "
        f"longer test's (the longer figure less the paper's length's), measured and true.",
        *lines,
        "",
        "Steady figures, per set: " + "; ".join(verdicts) + ".",
        "",
        f"The step's claims over {long}:",
        "",
        *summary_table(table["claims"]),
    ]
