"""The speed figures of docs/speed.md are the stored measurements, rendered; none is typed by
hand.

``benchmarks/bench_engine.py --write`` measures, stores ``benchmarks/results.json`` and writes
docs/speed.md's block between the speed-figures markers with ``benchmarks/speed_figures.py``.
These tests read the stored file and run no simulation.
"""

import json
import re
from pathlib import Path

from helpers import module_at

from emasim.page_blocks import block_of

ROOT = Path(__file__).parents[1]
README = (ROOT / "README.md").read_text()
SPEED = (ROOT / "docs" / "speed.md").read_text()
DEVELOPMENT = (ROOT / "docs" / "development.md").read_text()


figures = module_at("benchmarks/speed_figures.py")
commands = module_at("benchmarks/readme_commands.py")
RESULTS = json.loads((ROOT / "benchmarks" / "results.json").read_text())

# A timing figure: a number, then a unit of time or a factor faster.
TIMING = re.compile(
    r"\d\s*(s|ms|µs|us|seconds?|min|minutes?)\b|\d\s*(×|x|times)\s*faster", re.IGNORECASE
)


def test_the_page_block_is_the_stored_results_rendered():
    """Run ``python benchmarks/speed_figures.py`` (or the full benchmark) after editing
    results.json or the renderer."""
    assert block_of(SPEED, figures.BLOCK) == figures.render(RESULTS, figures.load_before())
    assert figures.PAGE.read_text() == SPEED


def test_the_stored_results_say_where_they_were_measured():
    for key in ("quick", "date", "platform", "cpu_count", "python", "numpy", "numba"):
        assert key in RESULTS, key
    if RESULTS["quick"]:
        assert "Quick run" in figures.render(RESULTS)


def test_no_timing_figure_is_typed_outside_the_blocks():
    """Outside the generated block, the Speed and Development pages hold no number followed
    by a unit of time (s, ms, µs, minutes) or by "× faster": such a figure would be typed by
    hand and drift. Other pages say "(timing: see Speed)" instead; their lengths of simulated
    time ("a load step at 0.4 s", "h = 1e-5 s") are inputs, not timings, so the check stays
    within these two pages, which hold no such inputs. The README may hold no "about N s" and
    no "N µs" or "N× faster" outside its block of the two commands' times
    (benchmarks/readme_commands.py)."""
    for name, text in (
        ("speed", SPEED.replace(block_of(SPEED, figures.BLOCK), "")),
        ("development", DEVELOPMENT),
    ):
        found = [line for line in text.splitlines() if TIMING.search(line)]
        assert found == [], name
    without_block = README.replace(block_of(README, commands.BLOCK), "")
    loose = re.compile(r"about \d[\d.]*\s*(s|ms|µs)\b|\d\s*µs|\d\s*(×|x) faster")
    assert [line for line in without_block.splitlines() if loose.search(line)] == []


def test_the_renderer_formats_figures():
    assert figures.sig(868, 2) == "870"
    assert figures.sig(0.04691, 3) == "0.0469"
    assert figures.sig(9.96, 2) == "10"
    assert figures.rtf(0.0412) == "RTF 0.0412, 24× faster than real time"
    assert figures.seconds(2.71) == "2.7 s"
    assert figures.seconds(0.00073) == "0.73 ms"
    assert figures.megabytes(1.76e9) == "1760 MB"
