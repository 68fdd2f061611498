"""The README's examples run as written."""

import re
import tomllib
from pathlib import Path

from emasim.scenarios.loader import validate_scenario

README = (Path(__file__).parents[1] / "README.md").read_text()


def blocks(language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", README, flags=re.S)


def test_the_scenario_example_is_valid_and_runs():
    (example,) = blocks("toml")
    scenario = validate_scenario(tomllib.loads(example))
    assert scenario.sensors.rudder.noise_std > 0  # "bench" sensors were picked up
    assert scenario.plant.backlash.width_mm == 0.2
    assert scenario.reference.loop == "position"


def test_the_python_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for code in blocks("python"):
        exec(code, namespace)  # noqa: S102 - the README's own examples
    assert (tmp_path / "runs" / "wide-gap" / "result.parquet").is_file()
    assert namespace["setup"].speed.function is namespace["my_speed_law"]
