"""Reliability of single runs (issue 26): what --label with --controller runs and is called,
a custom law that fails, results that prove themselves whole, and every command honouring or
refusing each solver setting."""

import json

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
