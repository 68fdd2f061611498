"""The README's headline table, rendered from ``docs/headline.json``: the abstract's five
figures, the paper's beside ours, as ``emasim reproduce`` measured them.

    python docs/readme_headline.py REPORT_FOLDER   # store REPORT_FOLDER/tables.json's headline
                                                   # in docs/headline.json, rewrite the README
    python docs/readme_headline.py                 # rewrite the README from docs/headline.json

The README holds the table between ``<!-- headline:begin -->`` and ``<!-- headline:end -->``;
``tests/test_reproduce.py`` checks that the block equals :func:`render` of the stored headline
and that a fresh reproduction measures the stored numbers. Standard library only.
"""

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "headline.json"
README = ROOT / "README.md"
BEGIN = "<!-- headline:begin -->"
END = "<!-- headline:end -->"
NAMES = {  # headline key -> the README's wording
    "step_steady_error_reduction": "step steady-state error (RMS)",
    "step_vibration_amplitude_reduction": "step vibration amplitude",
    "step_speed_fluctuation_reduction": "step speed fluctuation",
    "sine_displacement_lag_reduction": 'sine tracking error ("lag")',
    "sine_speed_fluctuation_reduction": "sine speed fluctuation",
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
    return "\n".join(lines)


def write_readme(headline: dict) -> None:
    text = README.read_text()
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    README.write_text(text[:start] + "\n" + render(headline) + "\n" + text[end:])


def main() -> None:
    if len(sys.argv) > 1:
        tables = json.loads((Path(sys.argv[1]) / "tables.json").read_text())
        STORE.write_text(json.dumps(tables["headline"], indent=1) + "\n")
    write_readme(json.loads(STORE.read_text()))


if __name__ == "__main__":
    main()
