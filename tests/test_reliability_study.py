"""Studies and tunings that never hang, never stop at one failed run and never leave a refusal
behind (issue 26): a --scheduler that is not a Dask scheduler, a run that fails for any
reason, a damaged run folder, a full disk, two tunings of one job store at once."""

import errno
import http.server
import json
import socket
import subprocess
import sys
import threading

import pytest
from typer.testing import CliRunner

from emasim.cli import _disk_full, app
from emasim.errors import InputError, OutputError
from emasim.experiments import batch, runs
from emasim.experiments.batch import dask_client
from emasim.experiments.store import LOG_FILE, RUNS_FOLDER, read_table
from emasim.experiments.study import StudySpec, run_study
from emasim.experiments.variation import parse_variation
from emasim.output import foreign_files

SHORT = ("duration_s=0.04",)
runner = CliRunner()


@pytest.fixture(scope="module")
def client():
    with dask_client(workers=2, processes=False) as c:
        yield c


def lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip()]


# --- a --scheduler that is not a Dask scheduler ---------------------------------------------


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # not on this process's stderr, the command's
        pass


@pytest.fixture
def listener():
    """``listener(kind)``: the address of a TCP listener that answers a connection with
    garbage bytes, or nothing at all, or is an HTTP server."""
    servers = []

    def start(kind: str) -> str:
        if kind == "http":
            server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), QuietHandler)
            threading.Thread(target=server.serve_forever, daemon=True).start()
            servers.append(server.shutdown)
            return f"tcp://127.0.0.1:{server.server_address[1]}"
        sock = socket.create_server(("127.0.0.1", 0))
        held = []

        def serve():
            while True:
                try:
                    conn, _ = sock.accept()
                except OSError:
                    return
                held.append(conn)
                if kind == "garbage":
                    conn.sendall(b"\xff" * 64)

        threading.Thread(target=serve, daemon=True).start()
        servers.append(sock.close)
        return f"tcp://127.0.0.1:{sock.getsockname()[1]}"

    yield start
    for stop in servers:
        stop()


@pytest.mark.parametrize(
    ("command", "kind"), [("study", "garbage"), ("study", "silent"), ("tune", "http")]
)
def test_a_listener_that_is_no_dask_scheduler_is_refused_in_one_line(
    tmp_path, monkeypatch, listener, command, kind
):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(batch, "HANDSHAKE_TIMEOUT_S", 1.0)  # what bounds the wait, not a clock
    address = listener(kind)
    args = {
        "study": ["study", "speed-step", "--label", "PI", "--out", "s", "--set", SHORT[0]],
        "tune": ["tune", "speed-step", "-c", "speed=pi", "--trials", "1", "--set", SHORT[0]],
    }[command]
    result = runner.invoke(app, [*args, "--scheduler", address])
    assert result.exit_code == 2, result.stderr
    said = lines(result.stderr)
    assert len(said) == 1, result.stderr
    assert said[0].startswith(f"error: --scheduler {address}: no Dask scheduler answers there")
    if kind == "silent":  # the handshake's own timeout ended the wait
        assert said[0].endswith("(no answer within 1 s)")
    assert "MemoryError" not in result.stderr and "internal error" not in result.stderr
    assert list(tmp_path.iterdir()) == []  # no study folder, no tuning storage


def test_a_real_scheduler_passes_the_handshake(client):
    batch.check_scheduler(client.scheduler.address)  # no error


# --- a run that fails is a row; the others go on; resuming re-runs it -----------------------


def test_a_failed_run_is_a_row_and_a_resume_runs_it_again(tmp_path, client, monkeypatch):
    real = runs.run_scenario

    def flaky(scenario, **kwargs):
        if scenario.seed == 2:
            raise OSError(errno.ENOSPC, "No space left on device", "/data/x")
        if scenario.seed == 3:
            raise KeyError("a bug")
        return real(scenario, **kwargs)

    monkeypatch.setattr(runs, "run_scenario", flaky)
    spec = StudySpec("speed-step", vary=("seed=1,2,3",), labels=("PI",), settings=SHORT)
    study = run_study(spec, tmp_path / "s", client=client)
    status = list(study.table["status"])
    assert status[0] == "ok"
    assert status[1] == "failed: cannot write the run folder: No space left on device (/data/x)"
    assert status[2] == "failed: KeyError: 'a bug'"
    assert list(read_table(tmp_path / "s")["status"]) == status
    meta = json.loads((tmp_path / "s" / RUNS_FOLDER / "pi-00002" / "meta.json").read_text())
    assert meta["status"] == status[2]
    summary = json.loads((tmp_path / "s" / "summary" / "summary.json").read_text())
    assert summary["failed"] == {"PI": 2} and summary["diverged"] == {"PI": 0}
    monkeypatch.setattr(runs, "run_scenario", real)
    again = run_study(spec, tmp_path / "s", client=client)
    assert list(again.table["status"]) == ["ok", "ok", "ok"]
    assert foreign_files(tmp_path / "s" / RUNS_FOLDER / "pi-00002") == []


def test_a_damaged_run_folder_is_run_again_and_a_user_file_stays(tmp_path, client):
    spec = StudySpec("speed-step", vary=("seed=1,2",), labels=("PI",), settings=SHORT)
    first = run_study(spec, tmp_path / "s", client=client).table
    folders = tmp_path / "s" / RUNS_FOLDER
    (folders / "pi-00000" / "metrics.json").unlink()  # damaged: lost a file
    (folders / "pi-00001" / "metrics.json").unlink()
    (folders / "pi-00001" / "notes.txt").write_text("mine")  # and holds a file of the user's
    again = run_study(spec, tmp_path / "s", client=client).table
    assert again["status"][0] == "ok"
    assert again["steady_error_rms_rpm"][0] == first["steady_error_rms_rpm"][0]
    assert again["status"][1].startswith("failed: ") and "notes.txt" in again["status"][1]
    assert (folders / "pi-00001" / "notes.txt").read_text() == "mine"


def test_the_console_counts_the_runs_and_shows_the_first_reasons(tmp_path, client):
    args = ["study", "speed-step", "--label", "PI", "--out", str(tmp_path / "s")]
    args += ["--vary", "plant.backlash.stiffness_N_per_m=1e8,1e12"]
    args += ["--set", "duration_s=0.02", "--set", "solver.step_s=1e-4"]
    result = runner.invoke(app, [*args, "--scheduler", client.scheduler.address])
    assert result.exit_code == 0, result.stderr
    said = " ".join(result.stderr.split())
    assert "2 runs: 1 ok, 1 diverged, 0 failed" in said
    assert "pi-00001 diverged: simulation diverged" in said
    assert "1 ok, 1 diverged, 0 failed" in said.rsplit("2 runs in", 1)[1]
    assert "┃ metric" not in result.stdout  # no empty table


def test_worker_output_goes_to_the_log_file(tmp_path):
    """LogToFile in a process of its own (it takes over the process's stdout and stderr)."""
    log = tmp_path / LOG_FILE
    code = (
        "import logging, sys, warnings\n"
        "from emasim.experiments.store import FAILURE_LOG\n"
        "from emasim.experiments.worker_setup import LogToFile, OneLineWarnings\n"
        f"LogToFile({str(log)!r}, FAILURE_LOG).setup(None); OneLineWarnings().setup(None)\n"
        "print('printed'); warnings.warn('warned')\n"
        "logging.getLogger(FAILURE_LOG).error('pi-00001 failed: Traceback (most recent...')\n"
        "raise SystemExit(sys.stderr.write('stderr\\n') and 0)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0 and done.stdout == "" and done.stderr == ""
    text = log.read_text()
    assert all(s in text for s in ("printed", "warning: warned", "pi-00001 failed", "stderr"))


# --- a full disk, a bad distribution ----------------------------------------------------------


def test_a_full_disk_while_writing_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    from emasim import output

    monkeypatch.chdir(tmp_path)
    marker = output.write_marker

    def full(folder, kind, files=None):
        if files is not None:
            raise OSError(errno.ENOSPC, "No space left on device")
        marker(folder, kind, files)

    monkeypatch.setattr(output, "write_marker", full)
    args = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.02", "--no-plot"]
    result = runner.invoke(app, [*args, "--out", "r"])
    assert result.exit_code == 2
    assert lines(result.stderr) == ["error: --out r: cannot write (No space left on device)"]
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_anywhere_else_is_one_line_too():
    class DatabaseError(Exception):
        pass

    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device", "runs/x.db")
        except OSError as err:
            raise DatabaseError("(sqlite3.OperationalError) disk I/O error") from err
    except DatabaseError as err:
        assert _disk_full(err) == "cannot write: runs/x.db (No space left on device)"
    assert _disk_full(RuntimeError("database or disk is full")).startswith("cannot write")
    assert _disk_full(ValueError("no")) is None


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("seed=integers(0, 1e30)", "from -9223372036854775808 to 9223372036854775807"),
        ("a=uniform(-1e308, 1e308)", "b - a at most"),
    ],
)
def test_a_distribution_numpy_cannot_draw_is_refused(text, says):
    with pytest.raises(InputError, match=says):
        parse_variation(text)
    assert parse_variation("seed=integers(0, 9223372036854775807)").distribution[1][1] == 2**63 - 1


# --- two tunings of one job store at once -----------------------------------------------------


def test_a_tuning_whose_store_another_holds_is_refused_in_one_line(tmp_path):
    """Two tunings of the same scenario and seed share a job store: while one holds it, the
    other is refused before it runs a trial, and the store is left as it was."""
    from emasim.scenarios.loader import load_scenario
    from emasim.tuning import tune_variant, tuning_store

    scenario = load_scenario("speed-step", controllers=["speed=pi"], settings=["duration_s=0.05"])
    holder = tuning_store(tmp_path, scenario, seed=0)
    with holder.opened():
        before = _snapshot(tmp_path)
        second = tuning_store(tmp_path, scenario, seed=0)
        assert second.folder == holder.folder
        with pytest.raises(OutputError, match="another emasim process is running it"):
            tune_variant(scenario, "PI", scenario.controllers, 2, second)
        assert _snapshot(tmp_path) == before


def test_a_study_from_a_script_without_a_main_guard_says_what_to_add(tmp_path):
    """A script that starts a study at its top level runs again in every Dask worker process
    (Python imports it there as ``__mp_main__``): each worker's copy finds the study's lock
    held and says what the script lacks, not that another emasim process runs it."""
    script = tmp_path / "study.py"
    script.write_text(
        "from emasim.experiments.study import StudySpec, run_study\n"
        "spec = StudySpec('speed-step', vary=('seed=1,2',), labels=('PI',),"
        " settings=('duration_s=0.01',))\n"
        f"run_study(spec, {str(tmp_path / 'out')!r}, workers=1)\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )
    assert done.returncode != 0
    assert 'put the lines that start it under `if __name__ == "__main__":`' in done.stderr
    assert "another emasim process is running it" not in done.stderr
    last = done.stderr.strip().splitlines()[-1]  # the script's own error names the guard too
    assert last.startswith("emasim.errors.EmasimError: Dask could not start its worker")
    assert '`if __name__ == "__main__":`' in last


def _snapshot(root):
    return {p: p.read_bytes() if p.is_file() else None for p in sorted(root.rglob("*"))}


def test_a_cosimulation_rule_is_refused_before_the_compile_notice(tmp_path, monkeypatch):
    from emasim import numba_cache

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(numba_cache, "is_cold", lambda *args, **kwargs: True)
    args = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.02", "--no-plot"]
    result = runner.invoke(app, [*args, "--set", "solver.communication_step_s=1e-3"])
    assert result.exit_code == 2
    assert lines(result.stderr) == [
        "error: solver.communication_step_s: co-simulation needs a plant with a linkage"
    ]
    assert list(tmp_path.iterdir()) == []
