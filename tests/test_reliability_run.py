"""Reliability of single runs (issue 26): what --label with --controller runs and is called,
a custom law that fails, results that prove themselves whole, and every command honouring or
refusing each solver setting."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from emasim.cli import app

runner = CliRunner()
SHORT = ["--set", "duration_s=0.05", "--no-plot"]


def invoke(*args: str):
    return runner.invoke(app, list(args))


def one_error_line(result) -> str:
    """The single ``error:`` line of a refused command (the cold-cache note aside)."""
    shown = f"exit {result.exit_code}\nstdout: {result.stdout}\nstderr: {result.stderr}"
    lines = [
        line
        for line in result.stderr.splitlines()
        if line.strip() and not line.startswith("compiling the simulation core")
    ]
    assert result.exit_code == 2, shown
    assert len(lines) == 1 and lines[0].startswith("error:"), shown
    assert "Traceback" not in result.stdout + result.stderr, shown
    return lines[0]


# --- --label with --controller -------------------------------------------------------------


def test_label_with_controller_runs_the_override_and_says_so(tmp_path):
    out = tmp_path / "run"
    result = invoke("run", "speed-step", "--label", "PI", "--controller", "speed=smc",
                    *SHORT, "--out", str(out))  # fmt: skip
    assert result.exit_code == 0, result.output
    meta = json.loads((out / "meta.json").read_text())
    assert meta["label"] == "PI (speed=smc)"
    assert "PI (speed=smc)" in result.stdout  # the metrics table's column
    scenario = (out / "scenario.toml").read_text()
    assert 'name = "smc"' in scenario and 'controller_set = "PI (speed=smc)"' in scenario
    again = invoke("run", str(out / "scenario.toml"), *SHORT, "--out", str(tmp_path / "again"))
    assert again.exit_code == 0, again.output
    assert json.loads((tmp_path / "again" / "meta.json").read_text())["label"] == meta["label"]


# --- a custom law that fails -----------------------------------------------------------------


@pytest.fixture(scope="module")
def speed_scenario():
    from emasim.scenarios.loader import load_scenario

    return load_scenario("speed-step", label="PI", settings=["duration_s=0.05"])


def run_with_speed_law(scenario, law):
    from emasim.control.slot import Compiled
    from emasim.experiments.runs import run_scenario

    setup = scenario.setup().with_(speed=Compiled(law, np.array([0.5]), np.zeros(1)))
    return run_scenario(scenario, setup=setup)


def test_a_law_that_raises_stops_the_run_in_one_line(speed_scenario, capfd):
    import numba

    from emasim.control.slot import CONTROLLER_SIG
    from emasim.errors import LawFailed

    @numba.njit(CONTROLLER_SIG)
    def raising_law(state, params, meas, ref, ts, out):
        if meas[0] > 1.0:
            raise ValueError("table index out of range")
        out[0] = params[0] * (ref[0] - meas[0])
        out[1] = 0.0

    with pytest.raises(LawFailed) as err:
        run_with_speed_law(speed_scenario, raising_law)
    message = str(err.value)
    assert message.startswith("the speed loop's law 'raising_law' raised ValueError: ")
    assert "table index out of range at t = " in message and "\n" not in message
    captured = capfd.readouterr()
    assert "Exception ignored" not in captured.err + captured.out


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_a_law_returning_a_non_finite_command_is_named(speed_scenario, value):
    import numba

    from emasim.control.slot import CONTROLLER_SIG
    from emasim.errors import LawFailed

    @numba.njit(CONTROLLER_SIG)
    def blind_law(state, params, meas, ref, ts, out):
        state[0] += 1.0  # the tick count: the law fails at its sixth call
        out[0] = value if state[0] > 5.0 else 0.1
        out[1] = 0.0

    with pytest.raises(LawFailed) as err:
        run_with_speed_law(speed_scenario, blind_law)
    message = str(err.value)
    assert message.startswith(
        f"the speed loop's law 'blind_law' returned out[0] (current command) = {value!r} at t = "
    )
    assert message.endswith("at t = 0.0005 s; a command must be finite")
    assert "gains" not in message
