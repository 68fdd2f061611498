"""The examples in examples/ run as a user runs them: a fresh process in an empty folder.

* design_a_controller: the PI bandwidth chosen on the linearised loop gives a simulated
  small-signal bandwidth (friction and backlash back in) within 10 % of the target;
* compare_under_backlash: a study table of three gaps by two controller sets, the error
  growing with the gap for PI;
* export_fmu: an FMU file that fmpy runs, the motor turning forward.

Each also draws the figures the examples gallery (docs/examples.md) shows: the same runs check
that they are images of a readable size, and that the gallery shows each example's code (put in
by docs/hooks.py when the site is built) and each of its figures, as
``python docs/example_figures.py`` stored them in docs/examples/.
"""

import re
import runpy
import subprocess
import sys
from pathlib import Path

from helpers import HANG_GUARD_S
from PIL import Image

ROOT = Path(__file__).parents[1]
EXAMPLES = ROOT / "examples"
GALLERY = ROOT / "docs" / "examples.md"
FIGURES = {  # example -> the figures it draws, the gallery's docs/examples/NAME
    "design_a_controller": ("design-bode.png",),
    "compare_under_backlash": ("backlash-error.png",),
    "export_fmu": ("fmu-response.png",),
}

example_code = runpy.run_path(str(ROOT / "docs" / "hooks.py"))["example_code"]  # not helpers':
# it imports the simulator, a second of this file's time


def run_example(name: str, folder: Path) -> str:
    """stdout of ``python examples/NAME.py figures`` in ``folder``; checks its figures."""
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py"), "figures"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert done.returncode == 0, done.stderr
    for figure in FIGURES[name]:
        with Image.open(folder / "figures" / figure) as image:
            image.load()  # decodes the whole file: a truncated or broken one raises
            assert image.format == "PNG"
            assert image.width >= 600 and image.height >= 400, image.size
            darkest, lightest = image.convert("L").getextrema()
            assert lightest - darkest > 128  # ink on a background, not a blank page
    return done.stdout


def numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"-?\d+\.\d+", text)]


def test_design_a_controller(tmp_path):
    output = run_example("design_a_controller", tmp_path)
    designed = output.splitlines()[-1]
    assert designed.startswith("simulated small-signal bandwidth")
    assert abs(numbers(designed)[0] - 4.0) <= 0.4


def test_compare_under_backlash(tmp_path):
    output = run_example("compare_under_backlash", tmp_path)
    rows = [line.split() for line in output.splitlines() if re.match(r"^\d", line)]
    assert [float(r[0]) for r in rows] == [0.05, 0.2, 0.4]
    pi = [float(r[1]) for r in rows]
    assert pi == sorted(pi)  # PI's steady error grows with the gap
    assert (tmp_path / "studies" / "backlash" / "metrics.parquet").exists()


def test_export_fmu(tmp_path):
    output = run_example("export_fmu", tmp_path)
    assert (tmp_path / "emasim-plant.fmu").stat().st_size > 0
    assert numbers(output)[0] > 0  # the motor turns forward


def test_the_gallery_shows_each_examples_code_and_figures():
    page = GALLERY.read_text()
    assert sorted(FIGURES) == sorted(p.stem for p in EXAMPLES.glob("*.py"))
    for name, figures in FIGURES.items():
        assert page.count(f"<!-- example: {name}.py -->\n") == 1, name
        for figure in figures:
            assert f"](examples/{figure})" in page, figure
    stored = sorted(p.name for p in (ROOT / "docs" / "examples").iterdir())
    assert stored == sorted(f for figures in FIGURES.values() for f in figures)


def test_the_hook_puts_in_the_examples_code(caplog):
    page = "# Gallery\n\n<!-- example: export_fmu.py -->\n\ntext\n"
    code = (EXAMPLES / "export_fmu.py").read_text()
    assert example_code(page, "x.md") == f"# Gallery\n\n```python\n{code}```\n\ntext\n"
    assert not caplog.records
    missing = "<!-- example: no_such_example.py -->"
    assert example_code(missing, "x.md") == missing
    assert "no example no_such_example.py" in caplog.records[-1].getMessage()
