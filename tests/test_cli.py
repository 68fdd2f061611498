"""The command line: a run folder with everything needed to repeat it, and one-line errors."""

import json
import subprocess
import sys
import tomllib

import numpy as np
import pandas as pd
import pytest
from helpers import HANG_GUARD_S
from typer.testing import CliRunner

from emasim.cli import app
from emasim.experiments.runs import meta_of, run_scenario
from emasim.scenarios.loader import validate_scenario
from emasim.sim.result import Comparison, Result

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, list(args))


def test_list_shows_scenarios_and_controllers():
    result = invoke("list")
    assert result.exit_code == 0
    for word in ("speed-step", "position-step", "speed", "position", "pid"):
        assert word in result.output


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "speed"
    result = invoke(
        "run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.5", "--out", str(out)
    )
    assert result.exit_code == 0, result.output
    return out, result.output


def test_run_writes_the_whole_folder(run_folder):
    out, output = run_folder
    assert {p.name for p in out.iterdir()} == {
        ".emasim-result",
        "result.parquet",
        "metrics.json",
        "scenario.toml",
        "meta.json",
        "plot.png",
    }
    frame = pd.read_parquet(out / "result.parquet")
    for column in ("t_s", "motor_speed_rad_s", "iq_A", "actuator_position_m", "rudder_angle_rad"):
        assert column in frame.columns
    meta = json.loads((out / "meta.json").read_text())
    assert meta["emasim_version"] and meta["seed"] == 0
    # provenance: every key of meta_of is recorded; only the names are compared, no value (the
    # run's speed is measured in benchmarks/, never here)
    scenario = validate_scenario(tomllib.loads((out / "scenario.toml").read_text()))
    assert set(meta_of(scenario, 1.0)) <= set(meta)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["settling_time_s"] > 0 and "settling time" in output
    assert not list(out.parent.glob(".*tmp*"))  # no temporary folder left behind


def test_a_comparison_writes_one_folder_per_controller_set(tmp_path):
    out = tmp_path / "cmp"
    result = invoke("run", "speed-step", "--set", "duration_s=0.3", "--out", str(out))
    assert result.exit_code == 0, result.output
    labels = ["PI", "SMC", "ST-SMC", "ST-SMC+GPIO"]
    for label in labels:
        assert label in result.output  # a metrics column per controller set
    comparison = Comparison.load(out)
    assert list(comparison.results) == labels
    assert (out / "comparison.png").is_file() and (out / "st-smc-gpio" / "result.parquet").is_file()
    assert comparison.metrics["SMC"]["settling_time_s"] > 0
    names = [comparison.results[label].scenario["controllers"]["speed"]["name"] for label in labels]
    assert names == ["pi", "smc", "st-improved", "st-gpio"]


def test_the_saved_scenario_repeats_the_run_exactly(run_folder):
    out, _ = run_folder
    saved = Result.load(out)
    scenario = validate_scenario(tomllib.loads((out / "scenario.toml").read_text()))
    again = run_scenario(scenario)
    assert np.array_equal(again.data, saved.data, equal_nan=True)
    assert again.metrics == saved.metrics


BAD_INPUTS = [
    (["--set", "plant.motor.inertia_kgm2=-1"], "plant.motor.inertia_kgm2", "greater than or"),
    (["--set", "plant.motor.inertia_kgm2=0"], "plant.motor.inertia_kgm2", "greater than or"),
    (["--set", "plant.motor.resistance_ohm=0"], "plant.motor.resistance_ohm", "greater than 0"),
    (["--set", "solver.step_s=-1e-5"], "solver.step_s", "greater than or equal to 0.00000001"),
    (["--set", "solver.step_s=3e-5"], "step_s", "whole multiple"),
    (["--set", "duration_s=0"], "duration_s", "greater than 0"),
    (["--set", "duration_s=-2"], "duration_s", "greater than 0"),
    (["--set", "duration_s=nan"], "duration_s", "finite"),
    (["--set", "plant.backlash.width_mm=inf"], "plant.backlash.width_mm", "finite"),
    (["--set", "duration_ms=2"], "duration_ms", "did you mean 'duration_s'?; allowed: name"),
    (["--set", "plant.backlash.width_um=0.2"], "plant.backlash.width_um", "allowed: width_mm"),
    (["--set", "plant.motor.colour=1"], "plant.motor.colour", "unknown key"),
    (["--controller", "speed=fancy"], "speed-loop controller 'fancy'", "choose one of: pi"),
    (["--controller", "torque=pi"], "unknown loop 'torque'", "speed, position"),
    (["--controller", "speed=pid"], "position-loop controller", "choose one of: pi"),
    (["--controller", "position=pid"], "controllers.position", "reference is a speed"),
    (["--set", 'plant.preset="nope"'], "plant.preset", "sea805"),
]


@pytest.mark.parametrize("extra,field,allowed", BAD_INPUTS)
def test_bad_input_is_one_clear_line_exit_2_and_nothing_written(tmp_path, extra, field, allowed):
    out = tmp_path / "run"
    result = invoke("run", "speed-step", *extra, "--out", str(out))
    assert result.exit_code == 2
    message = result.output.strip()
    assert message.startswith("error:") and "Traceback" not in message
    assert field in message and allowed in message
    assert not out.exists()


def test_unknown_scenario_and_nan_in_a_file(tmp_path):
    result = invoke("run", "no-such-scenario", "--out", str(tmp_path / "x"))
    assert result.exit_code == 2 and "choose one of" in result.output
    bad = tmp_path / "bad.toml"
    text = (
        'name = "x"\nduration_s = nan\n'
        '[reference]\nspeed_rpm = [{ type = "step", final = 100.0 }]\n'
    )
    bad.write_text(text)
    result = invoke("run", str(bad), "--out", str(tmp_path / "y"))
    field = "duration_s"
    assert result.exit_code == 2 and field in result.output and "finite" in result.output
    assert not (tmp_path / "y").exists()


def test_a_diverging_run_stops_with_the_time_and_state(tmp_path):
    result = invoke(
        "run",
        "speed-step",
        "--set",
        "duration_s=0.05",
        "--set",
        "solver.step_s=1e-4",
        "--set",
        "plant.backlash.stiffness_N_per_m=1e12",
        "--out",
        str(tmp_path / "d"),
    )
    assert result.exit_code == 2
    assert "diverged at t =" in result.output and "solver.step_s = 0.0001 s is too" in result.output
    assert not (tmp_path / "d").exists()


def test_a_controllers_design_check_is_one_warning_line(tmp_path):
    """The super-twisting law's check of the paper's eq. 37 warns through Python's warnings: the
    command line shows it as one 'warning:' line, with no source line and no category."""
    args = ["run", "speed-step", "-c", "speed=st-gpio", "--set", "duration_s=0.002"]
    args += ["--set", "controllers.speed.eq37_bound=1e5", "--no-plot", "--out", str(tmp_path / "r")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if "eq. 37" in line]
    assert lines and all(line.startswith("warning: st-gpio: paper eq. 37") for line in lines)
    assert "UserWarning" not in result.output and "warnings.warn" not in result.output


def test_a_comparison_loads_the_engine_and_every_law_before_its_timed_runs(monkeypatch):
    """A comparison's simulation time is its runs' (``run_all``, inside its timer); the engine
    and every set's laws are loaded before the timer starts (``load_compiled``, the meta's
    compile_s), so the runs find nothing left to load, and no compile is ever counted as
    simulation time. Checked on emptied caches: what the runs would load is recorded, no
    clock is read."""
    from emasim.experiments import batch
    from emasim.scenarios.loader import load_scenario
    from emasim.sim import engine
    from emasim.sim.core import LawAddress

    monkeypatch.setattr(LawAddress, "_cache", {})
    monkeypatch.setattr(engine.run_ticks, "_dispatcher", None)
    when_timed = []
    real_run_all = batch.run_all

    def timed_runs(*args, **kwargs):
        when_timed.append((engine.run_ticks._dispatcher is not None, set(LawAddress._cache)))
        return real_run_all(*args, **kwargs)

    monkeypatch.setattr(batch, "run_all", timed_runs)
    comparison = batch.run_comparison(load_scenario("speed-step", settings=["duration_s=0.01"]))
    [(engine_loaded, laws_loaded)] = when_timed
    assert engine_loaded and laws_loaded  # loaded before the timed runs began
    assert set(LawAddress._cache) == laws_loaded  # and the runs loaded no law of their own
    assert len(comparison.results) == 4


def test_quiet_and_verbose_work_before_or_after_the_subcommand(tmp_path):
    from emasim.cli import _global_flags_first

    assert _global_flags_first(["run", "x", "-q"]) == ["-q", "run", "x"]
    assert _global_flags_first(["run", "x", "--", "-v"]) == ["run", "x", "--", "-v"]
    run = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.01", "--no-plot"]
    quiet = invoke(*run, "--out", str(tmp_path / "q"), "-q")
    assert quiet.exit_code == 0, quiet.output
    assert "simulated" not in quiet.output and "metrics" not in quiet.output
    verbose = invoke(*run, "--out", str(tmp_path / "v"), "--verbose")
    assert verbose.exit_code == 0, verbose.output
    assert "simulated in" in verbose.output and "engine loaded in" in verbose.output
    both = invoke(*run, "-q", "-v")
    assert both.exit_code == 2 and "give one of them" in both.output


def test_the_metrics_table_fits_80_columns_and_says_why_a_metric_is_nan(tmp_path, monkeypatch):
    from emasim import cli

    monkeypatch.setattr(cli.console, "width", 80)
    result = invoke("run", "speed-step", "--set", "duration_s=0.6", "--out", str(tmp_path / "r"),
                    "--no-plot")  # fmt: skip
    assert result.exit_code == 0, result.output
    table = result.stdout.splitlines()
    assert max(len(line) for line in table) <= 80 and "…" not in result.stdout
    assert any("load recovery" in line and "│ s " in line for line in table)
    comparison = Comparison.load(tmp_path / "r")
    for label, run in comparison.results.items():
        for key, reason in run.meta.get("undefined_metrics", {}).items():
            assert f"nan: {label}, {key}: {' '.join(reason.split()[:4])}" in " ".join(table)


def test_the_source_digest_names_the_code_for_any_install(tmp_path):
    """meta.json's emasim_source_sha256 is the digest of the package's source, which an
    installed copy has as much as a checkout: the same files give the same digest, one changed
    byte another."""
    import shutil
    from pathlib import Path

    import emasim
    from emasim.experiments.runs import meta_of
    from emasim.numba_cache import source_hash
    from emasim.scenarios.loader import load_scenario

    meta = meta_of(load_scenario("speed-step"), 1.0)
    package = Path(emasim.__file__).parent
    assert meta["emasim_source_sha256"] == source_hash(package)
    copy = Path(shutil.copytree(package, tmp_path / "emasim"))
    assert source_hash(copy) == meta["emasim_source_sha256"]
    (copy / "version.py").write_text((copy / "version.py").read_text() + "\n")
    assert source_hash(copy) != meta["emasim_source_sha256"]


BROKEN_METRICS = """
import sys
from emasim.cli import app
from emasim.experiments import runs

def broken(result):
    raise ValueError("a metric broke")

runs.run_metrics = broken
sys.argv = ["emasim", "run", "speed-step", "--set", "duration_s=0.002", "--no-plot",
            "--out", sys.argv[1]]
app()
"""


def test_an_unexpected_failure_in_a_run_is_one_line(tmp_path):
    """A failure inside a comparison's run (on a Dask worker thread) ends in one line naming
    it, exit code 1: no traceback, Dask's "Compute Failed" report included. In a process of
    its own, as a user runs it (pytest's capture would hide what Dask's logger prints)."""
    done = subprocess.run(
        [sys.executable, "-c", BROKEN_METRICS, str(tmp_path / "r")],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    printed = done.stdout + done.stderr
    assert done.returncode == 1, printed
    assert "internal error: ValueError: a metric broke" in printed
    assert "Traceback" not in printed and "Compute Failed" not in printed


SIGNALLED_RUN = """
import os, signal, sys, time
from emasim.cli import app
from emasim.experiments import batch

SIGNAL = getattr(signal, sys.argv[2])

def signalled(*args, **kwargs):
    os.kill(os.getpid(), SIGNAL)
    time.sleep(60)

batch.run_scenario = signalled
sys.argv = ["emasim", "run", "speed-step", "-c", "speed=pi", "--no-plot", "--out", sys.argv[1]]
app()
"""


@pytest.mark.parametrize(("name", "code"), [("SIGINT", 130), ("SIGTERM", 143)])
@pytest.mark.parametrize("into", ["pipe", "file"])
def test_a_signal_during_a_run_says_interrupted_on_a_pipe_or_a_file(tmp_path, name, code, into):
    """A Ctrl-C (SIGINT) or a SIGTERM while a run simulates ends with the one line
    ``error: interrupted`` on stderr, whether it is a terminal, a pipe or a file, exit 130 or
    143 (128 + the signal), and leaves no result folder behind. In a process of its own, the
    signal sent by the run itself once it has started."""
    out = tmp_path / "r"
    command = [sys.executable, "-c", SIGNALLED_RUN, str(out), name]
    if into == "pipe":
        done = subprocess.run(command, capture_output=True, text=True, timeout=HANG_GUARD_S)
        printed = done.stderr
    else:
        with open(tmp_path / "stderr.txt", "w") as stderr:
            done = subprocess.run(command, stderr=stderr, timeout=HANG_GUARD_S)
        printed = (tmp_path / "stderr.txt").read_text()
    assert done.returncode == code, printed
    assert printed.strip().splitlines()[-1] == "error: interrupted", printed
    assert "Traceback" not in printed
    assert not out.exists()


SIGNALLED_IMPORT = """
import os, signal, sys, time

SIGNAL = getattr(signal, sys.argv[1])


class SignalOnTyper:
    def find_spec(self, name, path, target=None):
        if name == "typer":
            os.kill(os.getpid(), SIGNAL)
            time.sleep(60)
        return None


sys.meta_path.insert(0, SignalOnTyper())
sys.argv = ["emasim", "list"]
from emasim.__main__ import main
main()
"""


@pytest.mark.parametrize(("name", "code"), [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_while_the_command_line_imports_says_interrupted(name, code):
    """The command's imports take a second or more: a Ctrl-C or a SIGTERM then (here sent
    when typer is imported) ends with the same one line as during a command, no traceback."""
    done = subprocess.run(
        [sys.executable, "-c", SIGNALLED_IMPORT, name],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert done.returncode == code, done.stderr
    assert done.stderr == "error: interrupted\n"


SIGNALLED_CLUSTER_START = """
import asyncio, os, signal, sys

if __name__ == "__main__":  # the cluster's worker processes import this file again
    import distributed.nanny

    started = distributed.nanny.Nanny.start_unsafe

    async def signalled(self):
        os.kill(os.getpid(), signal.SIGTERM)
        await asyncio.sleep(0.5)
        return await started(self)

    distributed.nanny.Nanny.start_unsafe = signalled
    sys.argv = ["emasim", "study", "speed-step", "--vary",
                "plant.motor.inertia_kgm2=*uniform(0.9, 1.1)", "--runs", "2",
                "--set", "duration_s=0.01", "--out", sys.argv[1]]
    from emasim.__main__ import main
    main()
"""


def test_a_signal_while_the_cluster_starts_says_interrupted_and_nothing_more(tmp_path):
    """A SIGTERM (or Ctrl-C) while a study's Dask cluster starts its workers: the one line
    ``interrupted``, exit 143, and not Dask's traceback from closing, at exit, a cluster whose
    workers never started (AssertionError: Status.init)."""
    script = tmp_path / "interrupted_study.py"
    script.write_text(SIGNALLED_CLUSTER_START)
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "study")],
        capture_output=True,
        text=True,
        timeout=HANG_GUARD_S,
    )
    assert done.returncode == 143, done.stderr
    assert done.stderr.strip() == "error: interrupted"


def test_run_leaves_the_cycle_collector_as_it_found_it(tmp_path, monkeypatch):
    """`run` turns Python's cycle collector off while it runs (a bounded job) and on again
    after, as it was: a program or a test that runs it in its own process keeps its collector,
    and a run that fails does too."""
    import gc

    from emasim.experiments import batch

    seen = []
    assert gc.isenabled()
    args = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.01", "--no-plot"]

    def watched(*a, **k):
        seen.append(gc.isenabled())
        return run_scenario(*a, **k)

    monkeypatch.setattr(batch, "run_scenario", watched)
    assert invoke(*args, "--out", str(tmp_path / "a")).exit_code == 0
    assert seen == [False] and gc.isenabled()
    assert invoke(*args, "--set", "duration_s=-1").exit_code == 2
    assert gc.isenabled()
