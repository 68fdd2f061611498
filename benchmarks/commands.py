"""Fresh ``python -m emasim`` processes, timed end to end: the start-up figures' commands.

Shared by ``bench_engine.py`` (this tree's figures) and ``bench_paired.py`` (this tree against
an earlier revision). Nothing here imports emasim: each timed process imports its own tree
(``PYTHONPATH`` in ``env``).

The timed processes may write Python's bytecode cache, as on a user's machine: a
``PYTHONDONTWRITEBYTECODE`` in this environment (this sandbox sets it) is dropped for them,
so the second and later processes load compiled bytecode instead of compiling emasim's
sources again (about 60 modules, 0.06 s on this machine).
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# key -> (arguments after ``python -m emasim``, exit code); ``{out}`` is a new folder each time
STARTUP = {
    "help": (["--help"], 0),
    "list": (["list"], 0),
    "input_error": (["run", "speed-step", "--set", "duration_ms=2"], 2),
    "run_speed_step_pi": (["run", "speed-step", "-c", "speed=pi", "--out", "{out}/run"], 0),
    "run_speed_step_pi_no_plot": (
        ["run", "speed-step", "-c", "speed=pi", "--no-plot", "--out", "{out}/run"],
        0,
    ),
}


def user_environment(**extra: str) -> dict:
    """This process's environment as a user's shell would have it, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return {**env, **extra}


def process_seconds(args: list[str], expect: int = 0, env: dict | None = None) -> float:
    """Wall time of one fresh ``python -m emasim ARGS`` process, run in a new temporary folder
    (``{out}`` in ARGS names it) with ``env`` (default :func:`user_environment`); raise
    unless it exits with ``expect``."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "emasim", *(a.format(out=out) for a in args)]
        start = time.perf_counter()
        proc = subprocess.run(
            cmd, env=env or user_environment(), cwd=out, capture_output=True, text=True
        )
        elapsed = time.perf_counter() - start
    if proc.returncode != expect:
        raise RuntimeError(
            f"{' '.join(args)}: exit code {proc.returncode}, expected {expect}\n{proc.stderr}"
        )
    return elapsed


def run_meta(args: list[str], env: dict | None = None) -> dict:
    """The meta.json of one fresh ``python -m emasim run ...`` process (ARGS after ``run``,
    ``{out}`` a new folder), run as :func:`process_seconds` runs it."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "emasim", "run", *(a.format(out=out) for a in args)]
        proc = subprocess.run(
            cmd, env=env or user_environment(), cwd=out, capture_output=True, text=True
        )
        if proc.returncode != 0:
            raise RuntimeError(f"run {' '.join(args)}: exit code {proc.returncode}\n{proc.stderr}")
        return json.loads((Path(out) / "run" / "meta.json").read_text())
