"""Reliability of single runs (issue 26): what --label with --controller runs and is called,
a custom law that fails, results that prove themselves whole, and every command honouring or
refusing each solver setting."""

import json
from pathlib import Path

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


# --- results that prove themselves whole -----------------------------------------------------


@pytest.fixture(scope="module")
def saved_runs(tmp_path_factory):
    """One saved run in each trace format."""
    base = tmp_path_factory.mktemp("saved")
    for fmt in ("parquet", "csv", "mat"):
        result = invoke("run", "speed-step", "-c", "speed=pi", *SHORT, "--format", fmt,
                        "--out", str(base / fmt))  # fmt: skip
        assert result.exit_code == 0, result.output
    return base


def damaged_copy(saved_runs, tmp_path, fmt: str, name: str, damage) -> Path:
    import shutil

    folder = tmp_path / f"{fmt}-copy"
    shutil.copytree(saved_runs / fmt, folder)
    path = folder / name
    path.write_bytes(damage(path.read_bytes()))
    return folder


def cut_at_a_line_break(data: bytes) -> bytes:
    half = data[: len(data) // 2]
    return half[: half.rfind(b"\n") + 1] or half


DAMAGES = {
    "cut": cut_at_a_line_break,
    "header only": lambda data: data.split(b"\n")[0] + b"\n",
    "empty": lambda data: b"",
    "a flipped bit": lambda data: data[:200] + bytes([data[200] ^ 1]) + data[201:],
}


def assert_load_refused(folder, needle: str) -> str:
    from emasim.errors import DamagedResult
    from emasim.sim.result import Result

    with pytest.raises(DamagedResult) as err:
        Result.load(folder)
    message = str(err.value)
    assert needle in message and "\n" not in message, message
    return message


@pytest.mark.parametrize("damage", DAMAGES)
@pytest.mark.parametrize("fmt", ["parquet", "csv", "mat"])
def test_load_refuses_damaged_traces(saved_runs, tmp_path, fmt, damage):
    folder = damaged_copy(saved_runs, tmp_path, fmt, f"result.{fmt}", DAMAGES[damage])
    message = assert_load_refused(folder, f"result.{fmt}")
    assert "truncated" in message or "SHA-256" in message


@pytest.mark.parametrize("name", ["meta.json", "metrics.json", "scenario.toml"])
def test_load_refuses_damaged_records(saved_runs, tmp_path, name):
    folder = damaged_copy(saved_runs, tmp_path, "parquet", name, lambda d: d[:-3] + b"}}}")
    assert_load_refused(folder, name)


def test_load_reads_what_it_wrote_and_counts_the_rows(saved_runs):
    from emasim.sim.result import Result

    for fmt in ("parquet", "csv", "mat"):
        meta = json.loads((saved_runs / fmt / "meta.json").read_text())
        assert meta["traces"] == {"file": f"result.{fmt}", "rows": 500, "columns": 29}
        marker = json.loads((saved_runs / fmt / ".emasim-result").read_text())
        assert set(marker["sha256"]) == set(marker["files"])
        assert Result.load(saved_runs / fmt).data.shape == (500, 29)


def test_load_refuses_a_foreign_or_missing_folder_and_an_unproven_result(saved_runs, tmp_path):
    assert_load_refused(tmp_path / "nowhere", "nowhere: does not exist")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "result.csv").write_text("t_s\n0.0\n")
    assert_load_refused(tmp_path / "mine", "not an emasim result")
    # a result written before manifests carried checksums: it cannot be proven whole
    folder = damaged_copy(saved_runs, tmp_path, "csv", "meta.json", lambda d: d)
    marker = json.loads((folder / ".emasim-result").read_text())
    del marker["sha256"]
    (folder / ".emasim-result").write_text(json.dumps(marker))
    assert_load_refused(folder, "cannot be proven whole")


# --- every command honours every solver setting, or refuses it in one line -----------------

LUMPED_COSIM = ["--set", "solver.communication_step_s=0.001"]  # position-step: no linkage
FMU = ["--set", "solver.communication_step_s=0.001", "--set", "solver.mechanism_fmu=mech.fmu"]
TINY = ["--set", "duration_s=0.02"]


def command_line(command: str, scenario: str, out: Path) -> list[str]:
    """``command`` on ``scenario`` into ``out``, as short as the command allows."""
    if command == "run":
        return ["run", scenario, "--no-plot", "--out", str(out)]
    if command == "study":
        return ["study", scenario, "--vary", "seed=1", "--workers", "1", "--out", str(out)]
    if command == "tune":
        return ["tune", scenario, "--trials", "1", "--save", str(out / "tuned.toml")]
    return ["acceptance", scenario, "--out", str(out)]


@pytest.mark.parametrize("command", ["run", "study", "tune", "acceptance"])
@pytest.mark.parametrize(
    ("scenario", "settings", "needle"),
    [
        ("position-step", LUMPED_COSIM, "solver.communication_step_s"),
        ("cosim-step", FMU, "solver.mechanism_fmu"),
    ],
    ids=["co-simulation of a lumped plant", "an FMU without --trust-fmu"],
)
def test_a_setting_no_command_can_honour_is_refused_first(
    tmp_path, monkeypatch, command, scenario, settings, needle
):
    """Refused in one line, before anything is compiled or written (reproduce takes no
    scenario: it runs the paper's own)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mech.fmu").write_bytes(b"PK\x05\x06" + bytes(18))
    before = sorted(p.name for p in tmp_path.iterdir())
    args = command_line(command, scenario, tmp_path / "out")
    line = one_error_line(invoke(*args, *TINY, *settings))
    assert needle in line
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


@pytest.mark.parametrize(
    "settings",
    [
        ["--set", "solver.communication_step_s=0.001"],
        ["--set", "solver.record_signals=['iq_A']"],
    ],
    ids=["co-simulation", "record_signals"],
)
def test_acceptance_refuses_what_its_battery_cannot_honour(tmp_path, settings):
    line = one_error_line(
        invoke("acceptance", "cosim-step", *settings, "--out", str(tmp_path / "a"))
    )
    assert "acceptance" in line and "remove solver." in line
    assert not (tmp_path / "a").exists()


SOLVER_SETTINGS = {
    "sample_period_s": "solver.sample_period_s=0.0002",
    "step_s": "solver.step_s=0.000005",
    "record_period_s": "solver.record_period_s=0.002",
    "record_signals": "solver.record_signals=['iq_A']",
    "communication_step_s": "solver.communication_step_s=0.001",
}


def outcome(command: str, out: Path, *settings: str):
    """What ``command`` on cosim-step (PID, 0.02 s) made with ``settings``, to compare: the
    trace of ``run``, the kept trace of the one ``study`` run, and the tuned scenario's
    ``solver`` table and its one trial's (chattering, tracking) for ``tune``."""
    import tomllib

    import pandas as pd

    fixed = ["--set", "duration_s=0.02", *settings]
    if command == "run":
        args = ["run", "cosim-step", "--label", "PID", "--no-plot", "--out", str(out), *fixed]
    elif command == "study":
        args = [*command_line("study", "cosim-step", out), "--label", "PID", "--traces", *fixed]
    else:
        args = [*command_line("tune", "cosim-step", out), "--controller", "pid", *fixed]
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    if command == "tune":
        tuned = tomllib.loads((out / "tuned.toml").read_text())
        point = next(iter(tuned["tuning"]["sets"].values()))["tuned_point"]
        return tuned.get("solver", {}), point
    trace = out / "result.parquet" if command == "run" else next(out.glob("runs/*/result.parquet"))
    return pd.read_parquet(trace)


def same(a, b) -> bool:
    if isinstance(a, tuple):
        return a == b
    return a.shape == b.shape and bool((a.values == b.values).all())


@pytest.mark.parametrize("command", ["run", "study", "tune"])
def test_every_command_honours_every_solver_setting(tmp_path, command):
    """Each solver setting changes what the command makes (acceptance refuses those its
    battery cannot honour, above; reproduce takes no scenario). tune keeps no trace: it
    carries record_signals into the tuned scenario, and every other setting changes its
    trials' cost (the co-simulation's included: its trials co-simulate)."""
    base = outcome(command, tmp_path / "base")
    for name, setting in SOLVER_SETTINGS.items():
        changed = outcome(command, tmp_path / name, "--set", setting)
        if command == "tune" and name == "record_signals":
            assert changed[0]["record_signals"] == ["iq_A"] and changed[1] == base[1]
        else:
            assert not same(changed, base), f"{command}: {setting} did not change its result"


def test_tune_refuses_an_fmu_mechanism_without_offering_an_option_it_lacks(tmp_path):
    """tune has no --trust-fmu: its refusal says what to do instead."""
    (tmp_path / "mech.fmu").write_bytes(b"PK\x05\x06" + bytes(18))
    settings = [s.replace("mech.fmu", str(tmp_path / "mech.fmu")) for s in FMU]
    line = one_error_line(invoke(*command_line("tune", "cosim-step", tmp_path / "o"), *settings))
    assert "tune does not load an FMU" in line and "emasim run --trust-fmu" in line
