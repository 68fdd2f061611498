"""The examples in examples/ run as a user runs them: a fresh process in an empty folder.

* design_a_controller: the PI bandwidth chosen on the linearised loop gives a simulated
  small-signal bandwidth (friction and backlash back in) within 10 % of the target;
* compare_under_backlash: a study table of three gaps by two controller sets, the error
  growing with the gap for PI;
* export_fmu: an FMU file that fmpy runs, the motor turning forward.
"""

import re
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).parents[1] / "examples"
HANG_GUARD_S = 1800  # stops a hung example; not a speed check


def run_example(name: str, folder: Path) -> str:
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py")],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert done.returncode == 0, done.stderr
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
