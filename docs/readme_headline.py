"""The README's headline tables, rendered from ``docs/headline.json`` and
``docs/robustness.json``: the abstract's five figures, the paper's beside ours, as ``emasim
reproduce`` measured them, and their robustness over the plant uncertainty, as ``emasim
reproduce --robustness`` measured it.

    python docs/readme_headline.py REPORT_FOLDER   # store REPORT_FOLDER/tables.json's headline
                                                   # (and robustness, when it has one) in docs/,
                                                   # rewrite the README
    python docs/readme_headline.py                 # rewrite the README from docs/

The README holds the tables between ``<!-- headline:begin -->`` and ``<!-- headline:end -->``,
and ``<!-- robustness:begin -->`` and ``<!-- robustness:end -->``; ``tests/test_reproduce.py``
checks that the blocks equal :func:`render` and :func:`render_robustness` of the stored
objects, that a fresh reproduction measures the stored headline, and that its verdicts agree
with the stored robustness. Standard library only.
"""

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "headline.json"
ROBUSTNESS = ROOT / "docs" / "robustness.json"
README = ROOT / "README.md"
BLOCKS = {"headline": "<!-- headline:{}-->", "robustness": "<!-- robustness:{}-->"}
NAMES = {  # headline key -> the README's wording
    "step_steady_error_reduction": "step steady-state error (RMS)",
    "step_vibration_amplitude_reduction": "step vibration amplitude",
    "step_speed_fluctuation_reduction": "step speed fluctuation",
    "sine_displacement_lag_reduction": 'sine tracking error ("lag")',
    "sine_speed_fluctuation_reduction": "sine speed fluctuation",
}
COSTS = {  # robustness key -> the README's wording
    "bench_step_tuning_cost": "tuning cost, step",
    "bench_sine_tuning_cost": "tuning cost, sine",
}


def number(x: float) -> str:
    """Two significant digits, plain (0.056, 1.3, 42)."""
    return f"{float(f'{x:.2g}'):g}"


def percent(x: float) -> str:
    return f"{'−' if x > 0 else '+'}{abs(100 * x):.0f} %"


def render(headline: dict) -> str:
    """The README's table of the headline object of tables.json."""
    lines = [
        "| headline figure (abstract) | paper: PID → hybrid | ours: PID → hybrid |",
        "|---|---|---|",
    ]
    for key, words in NAMES.items():
        h = headline[key]
        paper = f"{number(h['paper_pid'])} → {number(h['paper_hybrid'])} {h['unit']} "
        paper += f"({percent(h['paper_reduction'])}"
        abstract = h["paper_abstract_reduction"]
        if round(100 * abstract) != round(100 * h["paper_reduction"]):
            paper += f"; abstract {percent(abstract)}"
        ours = f"{number(h['ours_pid'])} → {number(h['ours_hybrid'])} {h['unit']} "
        ours += f"({percent(h['ours_reduction'])})"
        lines.append(f"| {words} | {paper}) | {ours} |")
    return "\n".join(lines + ["", verdict_line(headline)] + variant_lines(headline))


def verdict_line(headline: dict) -> str:
    """Which side the nominal bench's five figures take (lower magnitude is better)."""
    losses = [words for key, words in NAMES.items() if not headline[key]["hybrid_better"]]
    if not losses:
        return "On the nominal bench the hybrid beats PID on all five figures."
    wins = len(NAMES) - len(losses)
    return (
        f"On the nominal bench the hybrid beats PID on {wins} of the five figures; PID is "
        f"better on: {', '.join(losses)}."
    )


def variant_lines(headline: dict) -> list[str]:
    """A sentence per further PID variant of ours (the paper has none): the figures of the
    experiments that compare it, the variant's value against the hybrid's."""
    lines = []
    labels = dict.fromkeys(label for h in headline.values() for label in h.get("variants", {}))
    for label in labels:
        figures = []
        for key, words in NAMES.items():
            h = headline[key]
            v = h.get("variants", {}).get(label)
            if v:
                figures.append(
                    f"{words} {number(v['value'])} → {number(h['ours_hybrid'])} {h['unit']} "
                    f"({percent(v['hybrid_reduction'])})"
                )
        lines += ["", f"Ours, {label} → hybrid: " + "; ".join(figures) + "."]
    return lines


def signed(x: float) -> str:
    """A whole percentage with its sign, the minus as in the headline table (−91 %, +17 %)."""
    return f"{x:+.0f}".replace("-", "−")


def render_robustness(verdicts: dict, headline: dict) -> str:
    """The README's table of the robustness object of tables.json, the nominal bench's
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
        nominal = f"{signed(-100 * headline[key]['ours_reduction'])} %" if key in headline else "-"
        lines.append(
            f"| {words} | {100 * v['win_rate']:.0f} % of {v['runs']} plants "
            f"[{low:.0f}, {high:.0f}] | {signed(-v['median_improvement_pct'])} % "
            f"[{signed(-gain_high)}, {signed(-gain_low)}] "
            f"| {signed(-v['improvement_p95_pct'])} to {signed(-v['improvement_p05_pct'])} % "
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


def block_of(text: str, name: str) -> str:
    """The README's text between the block's markers, without the newlines that frame it."""
    begin, end = BLOCKS[name].format("begin "), BLOCKS[name].format("end ")
    return text[text.index(begin) + len(begin) : text.index(end)].strip("\n")


def write_readme(headline: dict, verdicts: dict) -> None:
    text = README.read_text()
    robustness = render_robustness(verdicts, headline)
    for name, body in (("headline", render(headline)), ("robustness", robustness)):
        begin, end = BLOCKS[name].format("begin "), BLOCKS[name].format("end ")
        start, stop = text.index(begin) + len(begin), text.index(end)
        text = text[:start] + "\n" + body + "\n" + text[stop:]
    README.write_text(text)


def main() -> None:
    if len(sys.argv) > 1:
        tables = json.loads((Path(sys.argv[1]) / "tables.json").read_text())
        STORE.write_text(json.dumps(tables["headline"], indent=1) + "\n")
        if "robustness" in tables:
            ROBUSTNESS.write_text(json.dumps(tables["robustness"], indent=1) + "\n")
    write_readme(json.loads(STORE.read_text()), json.loads(ROBUSTNESS.read_text()))


if __name__ == "__main__":
    main()
