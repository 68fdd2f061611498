"""The README's speed figures are the stored measurements, rendered; none is typed by hand.

``benchmarks/bench_engine.py --write`` measures, stores ``benchmarks/results.json`` and writes
the README's block between the speed-figures markers with ``benchmarks/readme_figures.py``.
These tests read the stored file and run no simulation.
"""

import json
import re
from pathlib import Path

from helpers import module_at

ROOT = Path(__file__).parents[1]
README = (ROOT / "README.md").read_text()


figures = module_at("benchmarks/readme_figures.py")
RESULTS = json.loads((ROOT / "benchmarks" / "results.json").read_text())

# A timing figure: a number, then a unit of time or a factor faster.
TIMING = re.compile(
    r"\d\s*(s|ms|µs|us|seconds?|min|minutes?)\b|\d\s*(×|x|times)\s*faster", re.IGNORECASE
)


def section(title: str) -> str:
    """The README text from the heading ``## title`` to the next ``## `` heading."""
    start = README.index(f"\n## {title}\n")
    end = README.find("\n## ", start + 1)
    return README[start : end if end != -1 else len(README)]


def test_the_readme_block_is_the_stored_results_rendered():
    """Run ``python benchmarks/readme_figures.py`` (or the full benchmark) after editing
    results.json or the renderer."""
    assert figures.block_of(README) == figures.render(RESULTS)


def test_the_stored_results_say_where_they_were_measured():
    for key in ("quick", "date", "platform", "cpu_count", "python", "numpy", "numba"):
        assert key in RESULTS, key
    if RESULTS["quick"]:
        assert "Quick run" in figures.render(RESULTS)


def test_no_timing_figure_is_typed_outside_the_block():
    """Outside the generated block, the Speed and Development sections hold no number followed
    by a unit of time (s, ms, µs, minutes) or by "× faster": such a figure would be typed by
    hand and drift. Other sections say "(timings: see Speed)" instead; their lengths of
    simulated time ("a load step at 0.4 s", "h = 1e-5 s") are inputs, not timings, so the check
    stays within these two sections, which hold no such inputs. The whole README may hold no
    "about N s" and no "N µs" or "N× faster" outside the block."""
    without_block = README.replace(figures.block_of(README), "")
    for title in ("Speed", "Development"):
        text = section(title).replace(figures.block_of(README), "")
        found = [line for line in text.splitlines() if TIMING.search(line)]
        assert found == [], title
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
