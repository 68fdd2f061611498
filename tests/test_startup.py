"""Checking a scenario, listing and the help never load the compiled core.

numba and scipy take about a second to import; a command that only validates its input must
answer before that (emasim.jit defers every compiled function to its first use). Each check
runs in a fresh interpreter, since this test process has loaded numba long ago.
"""

import subprocess
import sys

import pytest

PROBE = """
import sys
{body}
heavy = sorted(m for m in ("numba", "scipy", "matplotlib", "pandas") if m in sys.modules)
print(",".join(heavy))
"""


def loaded_after(body: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(body=body)], capture_output=True, text=True, check=True
    )
    return done.stdout.strip()


@pytest.mark.parametrize(
    "body",
    [
        "from emasim.scenarios.loader import builtin_scenarios, load_scenario\n"
        "for name in builtin_scenarios():\n"
        "    load_scenario(name).variants()",
        "from emasim.cli import app\n"
        "from typer.testing import CliRunner\n"
        "assert CliRunner().invoke(app, ['list']).exit_code == 0",
        "from emasim.cli import app\n"
        "from typer.testing import CliRunner\n"
        "assert CliRunner().invoke(app, ['run', 'speed-step', '--set', 'duration_ms=2']).exit_code"
        " == 2",
    ],
    ids=["validate every shipped scenario", "emasim list", "an input error"],
)
def test_no_heavy_import_before_the_simulation(body):
    assert loaded_after(body) == ""


def test_the_first_simulation_loads_numba():
    """The other side: the probe can see numba, so an empty answer above means something."""
    body = (
        "from emasim.scenarios.loader import load_scenario\n"
        "from emasim.sim.engine import simulate\n"
        "simulate(load_scenario('speed-step', controllers=['speed=pi']).setup()"
        ".with_(duration_s=1e-3))"
    )
    assert "numba" in loaded_after(body).split(",")


def test_the_first_simulation_spares_scipy_linalg():
    """numba's BLAS check at its first cache load or compile finds scipy's BLAS on disk
    (emasim.jit._spare_scipy_linalg) instead of importing scipy.linalg; numba's own check is
    back for what follows, and a compiled np.dot still works (it imports BLAS itself)."""
    body = (
        "from emasim.scenarios.loader import load_scenario\n"
        "from emasim.sim.engine import simulate\n"
        "simulate(load_scenario('speed-step', controllers=['speed=pi']).setup()"
        ".with_(duration_s=1e-3))\n"
        "assert 'scipy.linalg' not in sys.modules\n"
        "from numba.np import arraymath, linalg\n"
        "assert arraymath._HAVE_BLAS and linalg.ensure_blas.__module__ == 'numba.np.linalg'\n"
        "import numba, numpy as np\n"
        "assert numba.njit(lambda x: x @ x)(np.arange(3.0)) == 5.0\n"
    )
    assert "numba" in loaded_after(body).split(",")


def test_without_scipys_blas_on_disk_numba_checks_as_before():
    """Where the file is not found, numba's own check runs (and imports scipy.linalg)."""
    body = (
        "import emasim.jit\n"
        "emasim.jit._scipy_ships_cython_blas = lambda: False\n"
        "from emasim.scenarios.loader import load_scenario\n"
        "from emasim.sim.engine import simulate\n"
        "simulate(load_scenario('speed-step', controllers=['speed=pi']).setup()"
        ".with_(duration_s=1e-3))\n"
        "assert 'scipy.linalg' in sys.modules\n"
    )
    assert "numba" in loaded_after(body).split(",")


def test_the_program_freezes_the_collector_when_its_command_is_done(monkeypatch):
    """``emasim`` (cli.program) ends its process with the collector frozen, so the shutdown's
    final collections skip numba's objects; the command's exit code passes through unchanged."""
    import gc

    from emasim.cli import program

    monkeypatch.setattr(sys, "argv", ["emasim", "run", "speed-step", "--set", "duration_ms=2"])
    gc.unfreeze()
    try:
        with pytest.raises(SystemExit) as ended:
            program()
        assert ended.value.code == 2
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
