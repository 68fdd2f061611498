"""The acceptance datasheet of docs/acceptance.md, rendered from ``docs/datasheet.json``: the
figures ``emasim acceptance bench-step`` measured for bench-step's controller sets.

    python docs/readme_datasheet.py SHEET_FOLDER   # store SHEET_FOLDER/datasheet.json and its
                                                   # bode.png in docs/, rewrite the page
    python docs/readme_datasheet.py                # rewrite the page from docs/

docs/acceptance.md holds the table between ``<!-- datasheet:begin -->`` and
``<!-- datasheet:end -->`` (the file keeps its name from when the README held it);
(emasim.page_blocks' rule); ``tests/test_acceptance.py`` checks that the block equals
:func:`render` of the stored sheet.
"""

import json
import shutil
import sys
from pathlib import Path

from emasim.page_blocks import write_block

ROOT = Path(__file__).resolve().parents[1]
STORE = ROOT / "docs" / "datasheet.json"
BODE = ROOT / "docs" / "acceptance-bode.png"
PAGE = ROOT / "docs" / "acceptance.md"
BLOCK = "datasheet"
ROWS = (  # datasheet key, the table's wording, unit
    ("bandwidth_small_Hz", "bandwidth (-3 dB), small signal", "Hz"),
    ("phase_90_small_Hz", "-90 deg phase, small signal", "Hz"),
    ("bandwidth_large_Hz", "bandwidth (-3 dB), large signal", "Hz"),
    ("threshold_mm", "threshold", "mm"),
    ("hysteresis_mm", "hysteresis width", "mm"),
    ("limit_cycle_mm", "limit cycle in the slow triangle (±)", "mm"),
    ("load_step_stiffness_N_per_mm", "stiffness under a load step (peak deflection)", "N/mm"),
    ("dynamic_stiffness_min_N_per_mm", "least dynamic stiffness", "N/mm"),
    ("no_load_rate_mm_s", "no-load rate", "mm/s"),
    ("rate_at_rated_load_mm_s", "rate at rated load", "mm/s"),
    ("stall_force_N", "stall force", "N"),
    ("energy_per_cycle_J", "energy per large-signal cycle at 1 Hz", "J"),
)


def number(x) -> str:
    """A figure's cell as the datasheet's report writes it (emasim.analysis.datasheet.cell),
    to 3 significant figures."""
    from emasim.analysis.datasheet import cell

    return cell(x, 3)


def render(sheet: dict) -> str:
    """The Markdown between the page's markers."""
    labels = list(sheet["sets"])
    first = sheet["sets"][labels[0]]
    lines = [
        f"| `{sheet['scenario']}`, small signal ±{number(first['small_amplitude_mm'])} mm, "
        f"large ±{number(first['large_amplitude_mm'])} mm | unit | " + " | ".join(labels) + " |",
        "|---|---|" + "---|" * len(labels),
    ]
    for key, name, unit in ROWS:
        cells = " | ".join(number(sheet["sets"][label][key]) for label in labels)
        lines.append(f"| {name} | {unit} | {cells} |")
    return "\n".join(lines)


def main() -> None:
    if len(sys.argv) > 1:
        folder = Path(sys.argv[1])
        STORE.write_text((folder / "datasheet.json").read_text())
        shutil.copyfile(folder / "bode.png", BODE)
    write_block(PAGE, BLOCK, render(json.loads(STORE.read_text())))


if __name__ == "__main__":
    main()
