"""The headline tables of the README and of docs/paper.md, rendered from ``docs/claims.json``,
``docs/run_length.json``, ``docs/headline.json``, ``docs/robustness.json`` and
``docs/verdict_map.json``: the abstract's five claims decided over paired replicas, the step
test's length, and the five figures' single runs (the paper's beside ours), as ``emasim
reproduce`` measured them, their robustness over the plant uncertainty and where each verdict
flips, as ``emasim reproduce --robustness`` measured them.

    python docs/readme_headline.py REPORT_FOLDER   # store REPORT_FOLDER/tables.json's claims,
                                                   # run length and headline (and robustness
                                                   # and verdict map, when it has them) in
                                                   # docs/, rewrite the pages
    python docs/readme_headline.py                 # rewrite the pages from docs/

The README, docs/paper.md and docs/verdicts.md hold the claims between ``<!-- claims:begin
-->`` and ``<!-- claims:end -->``; docs/verdicts.md the step test's length between ``<!--
run-length:begin -->`` and ``<!-- run-length:end -->``; the README and docs/paper.md the
headline table between ``<!-- headline:begin -->`` and ``<!-- headline:end -->``;
docs/paper.md the robustness table between ``<!-- robustness:begin -->`` and ``<!--
robustness:end -->`` and the verdict map's lines between ``<!-- verdict-map:begin -->`` and
``<!-- verdict-map:end -->`` (:data:`PAGES`). ``tests/test_reproduce.py`` checks that the
blocks equal :func:`render`, :func:`render_robustness` and :func:`render_verdict_map` of the
stored objects, that a fresh reproduction measures the stored headline and the stored map's
nominal cells, and that its verdicts agree with the stored robustness;
``tests/test_replicas.py`` that the claims' and the run length's blocks equal
:func:`render_claims` and :func:`render_run_length` of their stored objects and that every
stored word follows from its interval, band and floor; ``tests/test_verdict_map.py`` re-runs
one cell of the stored map off the nominal bench. The blocks follow emasim.page_blocks' rule;
the lines of the claims and of the map are emasim.analysis.claims' and
emasim.analysis.verdict_map's.
"""

import json
import sys
from pathlib import Path

from emasim.analysis.verdict_rule import MAX_PERCENT
from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "headline.json"
ROBUSTNESS = ROOT / "docs" / "robustness.json"
VERDICT_MAP = ROOT / "docs" / "verdict_map.json"
CLAIMS = ROOT / "docs" / "claims.json"
RUN_LENGTH = ROOT / "docs" / "run_length.json"
README = ROOT / "README.md"
PAPER = ROOT / "docs" / "paper.md"
VERDICTS = ROOT / "docs" / "verdicts.md"
PAGES = {
    "claims": (README, PAPER, VERDICTS),
    "run-length": (VERDICTS,),
    "headline": (README, PAPER),
    "robustness": (PAPER,),
    "verdict-map": (PAPER,),
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


def whole(percentage: float) -> str:
    """|percentage| in whole percent, one decimal below 1 % (never a bare '0' for a change)."""
    magnitude = abs(percentage)
    return f"{magnitude:.0f}" if magnitude >= 0.95 or magnitude == 0 else f"{magnitude:.1f}"


def percent(x: float) -> str:
    return f"{'−' if x > 0 else '+'}{whole(100 * x)} %"


INDUSTRIAL = "industrial PID"  # the further PID variant of every bench experiment


def pair(before: float | None, after: float | None, unit: str, change: float | None) -> str:
    """'0.056 → 0.032 deg (−43 %)'; '-' when a side is missing; no percentage beyond
    ±MAX_PERCENT (emasim.analysis.verdict_rule: it says only that the baseline is near 0)."""
    if before is None or after is None:
        return "-"
    text = f"{number(before)} → {number(after)} {unit}"
    if change is None or abs(100 * change) > MAX_PERCENT:
        return text
    return text + f" ({percent(change)})"


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
) -> str:
    """The table of the headline object of tables.json: the paper's figures, ours as
    the bench measures them against both PID variants, the true angle's beside them and, with
    a robustness study (``verdicts``), the hybrid's win rate against each variant, and with a
    verdict map (``vmap``) the cells of it the hybrid wins against each. Single runs, one
    replica each: the verdicts are the claims' (:func:`render_claims`)."""
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
    return "\n".join(lines)


def signed(x: float | None) -> str:
    """A whole percentage with its sign, the minus as in the headline table (−91 %, +17 %;
    one decimal below 1 %: −0.4 %);
    None (tables.json's null for an infinite change: PID's figure 0, the hybrid's not) as +∞."""
    return "+∞" if x is None else f"{'−' if x < 0 else '+'}{whole(x)}"


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


def render_claims(claims: dict) -> str:
    """The abstract's claims decided over paired replicas (tables.json's claims object):
    emasim.analysis.claims.summary_table."""
    from emasim.analysis.claims import summary_table

    return "\n".join(summary_table(claims))


def render_run_length(table: dict) -> str:
    """The step test's length (tables.json's run_length object):
    emasim.analysis.claims.length_body."""
    from emasim.analysis.claims import length_body

    return "\n".join(length_body(table))


def write_pages(headline: dict, verdicts: dict, vmap: dict, claims: dict, run_length: dict) -> None:
    """Rewrite each block on each of its :data:`PAGES`."""
    blocks = {
        "claims": render_claims(claims),
        "run-length": render_run_length(run_length),
        "headline": render(headline, verdicts, vmap),
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
        if "robustness" in tables:
            ROBUSTNESS.write_text(json.dumps(tables["robustness"], indent=1) + "\n")
        if "verdict_map" in tables:
            VERDICT_MAP.write_text(json.dumps(tables["verdict_map"], indent=1) + "\n")
        if "claims" in tables:
            CLAIMS.write_text(json.dumps(tables["claims"], indent=1) + "\n")
        if "run_length" in tables:
            RUN_LENGTH.write_text(json.dumps(tables["run_length"], indent=1) + "\n")
    write_pages(
        json.loads(STORE.read_text()),
        json.loads(ROBUSTNESS.read_text()),
        json.loads(VERDICT_MAP.read_text()),
        json.loads(CLAIMS.read_text()),
        json.loads(RUN_LENGTH.read_text()),
    )


if __name__ == "__main__":
    main()
