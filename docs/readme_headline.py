"""The headline tables of the README and of docs/paper.md, rendered from
``docs/headline.json``, ``docs/integration_step.json``, ``docs/robustness.json`` and
``docs/verdict_map.json``: the abstract's five figures, the paper's beside ours, and each at half
and twice the integration step, as ``emasim reproduce`` measured them, their robustness over the
plant uncertainty and where each verdict flips, as ``emasim reproduce --robustness`` measured
them.

    python docs/readme_headline.py REPORT_FOLDER   # store REPORT_FOLDER/tables.json's headline
                                                   # and integration step (and robustness and
                                                   # verdict map, when it has them) in docs/,
                                                   # rewrite the pages
    python docs/readme_headline.py                 # rewrite the pages from docs/

The README and docs/paper.md hold the headline table between ``<!-- headline:begin -->`` and
``<!-- headline:end -->``; docs/paper.md holds the robustness table between ``<!--
robustness:begin -->`` and ``<!-- robustness:end -->``, the integration step's table between
``<!-- integration-step:begin -->`` and ``<!-- integration-step:end -->``, and the verdict
map's lines between ``<!-- verdict-map:begin -->`` and ``<!-- verdict-map:end -->``
(:data:`PAGES`). ``tests/test_reproduce.py`` checks that the blocks equal :func:`render`,
:func:`render_robustness`, :func:`render_integration_step` and :func:`render_verdict_map` of
the stored objects, that a fresh reproduction measures the stored headline, integration step
and the stored map's nominal cells, and that its verdicts agree with the stored robustness;
``tests/test_verdict_map.py`` re-runs one cell of the stored map off the nominal bench.
The blocks follow emasim.page_blocks' rule; the lines of the map and of the integration step
are emasim.analysis.verdict_map's and emasim.analysis.integration_step's.
"""

import json
import sys
from pathlib import Path

from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "headline.json"
ROBUSTNESS = ROOT / "docs" / "robustness.json"
VERDICT_MAP = ROOT / "docs" / "verdict_map.json"
INTEGRATION_STEP = ROOT / "docs" / "integration_step.json"
README = ROOT / "README.md"
PAPER = ROOT / "docs" / "paper.md"
PAGES = {
    "headline": (README, PAPER),
    "robustness": (PAPER,),
    "verdict-map": (PAPER,),
    "integration-step": (PAPER,),
}
NAMES = {  # headline key -> the tables' wording
    "step_steady_error_reduction": "step steady-state error (RMS)",
    "step_vibration_amplitude_reduction": "step vibration amplitude",
    "step_speed_fluctuation_reduction": "step speed fluctuation",
    "sine_displacement_lag_reduction": 'sine tracking error ("lag")',
    "sine_speed_fluctuation_reduction": "sine speed fluctuation",
}
COSTS = {  # robustness key -> the table's wording
    "bench_step_tuning_cost": "tuning cost, step",
    "bench_sine_tuning_cost": "tuning cost, sine",
}


def number(x: float) -> str:
    """Two significant digits, plain (0.056, 1.3, 42)."""
    return f"{float(f'{x:.2g}'):g}"


def percent(x: float) -> str:
    return f"{'−' if x > 0 else '+'}{abs(100 * x):.0f} %"


INDUSTRIAL = "industrial PID"  # the further PID variant of every bench experiment


def pair(before: float | None, after: float | None, unit: str, change: float | None) -> str:
    """'0.056 → 0.032 deg (−43 %)'; '-' when a side is missing."""
    if before is None or after is None:
        return "-"
    text = f"{number(before)} → {number(after)} {unit}"
    return text + (f" ({percent(change)})" if change is not None else "")


def win_rate(verdict: dict | None) -> str:
    """'95 % [91, 98]' of a robustness verdict, '-' without one."""
    if not verdict or not verdict.get("runs"):
        return "-"
    low, high = (100 * x for x in verdict["win_rate_ci95"])
    return f"{100 * verdict['win_rate']:.0f} % [{low:.0f}, {high:.0f}]"


def map_wins(vmap: dict | None, key: str) -> str:
    """'10 / 10 of 24': the verdict map's cells the hybrid wins against PID and against the
    industrial PID on one headline figure, '-' without a map."""
    entry = (vmap or {}).get("figures", {}).get(key)
    if not entry:
        return "-"
    counts = [
        sum(c["margin_pct"] is not None and c["margin_pct"] > 0 for c in entry["against"][label])
        for label in ("PID", INDUSTRIAL)
    ]
    return f"{counts[0]} / {counts[1]} of {len(entry['against']['PID'])}"


def render(
    headline: dict,
    verdicts: dict | None = None,
    vmap: dict | None = None,
    steps: dict | None = None,
) -> str:
    """The table of the headline object of tables.json: the paper's figures, ours as
    the bench measures them against both PID variants, the true angle's beside them and, with
    a robustness study (``verdicts``), the hybrid's win rate against each variant, and with a
    verdict map (``vmap``) the cells of it the hybrid wins against each; then
    :func:`verdict_line`, which names the verdicts that turn with the integration step
    (``steps``, tables.json's integration_step object)."""
    lines = [
        "| headline figure (abstract) | paper: PID → hybrid | ours, measured: PID → hybrid "
        f"| ours, measured: {INDUSTRIAL} → hybrid | true angle: PID → hybrid "
        f"| hybrid better than PID / {INDUSTRIAL}, share of plants [95 % interval] "
        "| cells of the verdict map it wins, against PID / the industrial PID |",
        "|---|---|---|---|---|---|---|",
    ]
    for key, words in NAMES.items():
        h = headline[key]
        paper = pair(h["paper_pid"], h["paper_hybrid"], h["unit"], None)
        paper += f" ({percent(h['paper_reduction'])}"
        abstract = h["paper_abstract_reduction"]
        if round(100 * abstract) != round(100 * h["paper_reduction"]):
            paper += f"; abstract {percent(abstract)}"
        ours = pair(h["ours_pid"], h["ours_hybrid"], h["unit"], h["ours_reduction"])
        variant = h.get("variants", {}).get(INDUSTRIAL) or {}
        industrial = pair(
            variant.get("value"), h["ours_hybrid"], h["unit"], variant.get("hybrid_reduction")
        )
        true = pair(h.get("true_pid"), h.get("true_hybrid"), h["unit"], h.get("true_reduction"))
        against = (verdicts or {}).get(key, {}).get("against", {})
        rates = f"{win_rate(against.get('PID'))} / {win_rate(against.get(INDUSTRIAL))}"
        cells = map_wins(vmap, key)
        lines.append(f"| {words} | {paper}) | {ours} | {industrial} | {true} | {rates} | {cells} |")
    return "\n".join([*lines, "", verdict_line(headline, verdicts, steps)])


def wins_against(headline: dict, label: str) -> list[str]:
    """The figures on which the hybrid, as measured on the nominal bench, is below ``label``
    ('PID' or a variant's label)."""
    out = []
    for key, words in NAMES.items():
        h = headline[key]
        if label == "PID":
            better = h["hybrid_better"]
        else:
            variant = h.get("variants", {}).get(label)
            better = variant is not None and abs(h["ours_hybrid"]) < abs(variant["value"])
        if better:
            out.append(words)
    return out


def settled(verdicts: dict | None, label: str) -> bool:
    """True when, on all five figures, the win rate's interval against ``label`` lies above
    one half."""
    if not verdicts:
        return False
    for key in NAMES:
        verdict = verdicts.get(key, {}).get("against", {}).get(label)
        if not verdict or not verdict.get("runs") or verdict["win_rate_ci95"][0] <= 0.5:
            return False
    return True


def turning(steps: dict | None, label: str) -> list[str]:
    """The figures whose verdict against ``label`` turns with the integration step
    (emasim.analysis.integration_step), in the headline's order."""
    from emasim.analysis.integration_step import TURNS, verdict

    return [
        words
        for key, words in NAMES.items()
        if key in (steps or {})
        and label in steps[key]["values"]
        and verdict(steps[key], label) == TURNS
    ]


def verdict_line(headline: dict, verdicts: dict | None = None, steps: dict | None = None) -> str:
    """Which figures the hybrid wins on the nominal bench, as measured, against each PID
    variant ('all five' only where the Monte Carlo settles all five for it too and none turns
    with the integration step); then, given ``steps``, the verdicts that turn with it."""
    parts, unsettled = [], []
    for label in ("PID", INDUSTRIAL):
        wins = wins_against(headline, label)
        turned = turning(steps, label)
        if turned:
            unsettled.append(f"against {'the ' if label == INDUSTRIAL else ''}{label} on "
                             f"{' and '.join(turned)}")  # fmt: skip
        if len(wins) == len(NAMES) and settled(verdicts, label) and not turned:
            parts.append(f"{label} on all five figures, on the nominal bench and over the plants")
        elif not wins:
            parts.append(f"{label} on none of the five figures")
        else:
            parts.append(f"{label} on {len(wins)} of the five ({', '.join(wins)})")
    line = "As measured on the nominal bench, the hybrid beats " + "; and the ".join(parts) + "."
    if unsettled:
        line += (
            " The verdicts " + " and ".join(unsettled) + " turn at half or twice the integration "
            "step: the simulation does not settle them."
        )
    return line


def signed(x: float | None) -> str:
    """A whole percentage with its sign, the minus as in the headline table (−91 %, +17 %);
    None (tables.json's null for an infinite change: PID's figure 0, the hybrid's not) as +∞."""
    return "+∞" if x is None else f"{x:+.0f}".replace("-", "−")


def negated(x: float | None) -> float | None:
    """-x, the hybrid's change against PID from the improvement (None stays None)."""
    return None if x is None else -x


def render_robustness(verdicts: dict, headline: dict) -> str:
    """The table of the robustness object of tables.json, the nominal bench's
    improvement (the headline object) beside it."""
    lines = [
        "| figure | hybrid better than PID on | median change, hybrid against PID "
        "[95 % interval] | 90 % of plants within | nominal bench |",
        "|---|---|---|---|---|",
    ]
    for key, words in {**NAMES, **COSTS}.items():
        v = verdicts[key]
        low, high = (100 * x for x in v["win_rate_ci95"])
        gain_low, gain_high = v["ci95_pct"]
        change = headline[key]["ours_reduction"] if key in headline else None
        nominal = "-" if change is None else f"{signed(-100 * change)} %"  # None: PID at 0
        lines.append(
            f"| {words} | {100 * v['win_rate']:.0f} % of {v['runs']} plants "
            f"[{low:.0f}, {high:.0f}] | {signed(negated(v['median_improvement_pct']))} % "
            f"[{signed(negated(gain_high))}, {signed(negated(gain_low))}] "
            f"| {signed(negated(v['improvement_p95_pct']))} to "
            f"{signed(negated(v['improvement_p05_pct']))} % "
            f"| {nominal} |"
        )
    verdicts_of = {True: [], False: [], None: []}  # hybrid better, PID better, open
    for key, words in NAMES.items():
        low, high = verdicts[key]["win_rate_ci95"]
        settled = True if low > 0.5 else False if high < 0.5 else None
        verdicts_of[settled].append(words)
    against = [
        w for k, w in NAMES.items() if w in verdicts_of[False] and headline[k]["hybrid_better"]
    ]
    lines.append("")
    lines.append(
        "Settled for the hybrid (the win rate's interval above one half): "
        + (", ".join(verdicts_of[True]) or "none")
        + ". Settled for PID: "
        + (", ".join(verdicts_of[False]) or "none")
        + ". Open: "
        + (", ".join(verdicts_of[None]) or "none")
        + "."
        + (
            f" The nominal bench's verdict does not hold for: {', '.join(against)}."
            if against
            else ""
        )
    )
    return "\n".join(lines)


def render_verdict_map(vmap: dict) -> str:
    """The list of where each verdict flips: the lines of
    emasim.analysis.verdict_map.flip_lines, read off the stored map."""
    from emasim.analysis.verdict_map import flip_lines

    return "\n".join(f"- {line}" for line in flip_lines(vmap))


def render_integration_step(steps: dict) -> str:
    """The integration step's table and lines (emasim.analysis.integration_step.body)."""
    from emasim.analysis.integration_step import body

    return body(steps)


def write_pages(headline: dict, verdicts: dict, vmap: dict, steps: dict) -> None:
    """Rewrite each block on each of its :data:`PAGES`."""
    blocks = {
        "headline": render(headline, verdicts, vmap, steps),
        "integration-step": render_integration_step(steps),
        "robustness": render_robustness(verdicts, headline),
        "verdict-map": render_verdict_map(vmap),
    }
    for name, body in blocks.items():
        for page in PAGES[name]:
            write_block(page, name, body)


def main() -> None:
    if len(sys.argv) > 1:
        tables = json.loads((Path(sys.argv[1]) / "tables.json").read_text())
        STORE.write_text(json.dumps(tables["headline"], indent=1) + "\n")
        INTEGRATION_STEP.write_text(json.dumps(tables["integration_step"], indent=1) + "\n")
        if "robustness" in tables:
            ROBUSTNESS.write_text(json.dumps(tables["robustness"], indent=1) + "\n")
        if "verdict_map" in tables:
            VERDICT_MAP.write_text(json.dumps(tables["verdict_map"], indent=1) + "\n")
    write_pages(
        json.loads(STORE.read_text()),
        json.loads(ROBUSTNESS.read_text()),
        json.loads(VERDICT_MAP.read_text()),
        json.loads(INTEGRATION_STEP.read_text()),
    )


if __name__ == "__main__":
    main()
