"""numba's cache lives in a folder keyed by the whole package's source (emasim.numba_cache).

An edit to any source file must give another cache folder, since numba itself checks only
the file that defines a function, not the files whose functions and constants it compiles in.
"""

import os
import shutil
import subprocess
import sys

import emasim
from emasim.numba_cache import PACKAGE, keyed_folder, source_hash


def test_an_edit_anywhere_in_the_package_changes_the_cache_folder(tmp_path):
    copy = tmp_path / "emasim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = source_hash(copy)
    assert before == source_hash(PACKAGE)
    actuator = copy / "plant" / "actuator.py"  # read by the engine, defined elsewhere
    actuator.write_text(actuator.read_text() + "\n# an edit\n")
    assert source_hash(copy) != before


def test_this_process_and_its_children_use_the_keyed_folder():
    import numba.core.config

    folder = emasim.NUMBA_CACHE_DIR
    assert folder.name == f"emasim-{source_hash()}"
    assert numba.core.config.CACHE_DIR == str(folder) == os.environ["NUMBA_CACHE_DIR"]
    child = subprocess.run(
        [sys.executable, "-c", "import emasim; print(emasim.NUMBA_CACHE_DIR)"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert child.stdout.strip() == str(folder)  # inherited, not nested


def test_a_users_cache_base_is_kept_as_the_parent(tmp_path):
    assert keyed_folder(tmp_path, "abc") == tmp_path / "emasim-abc"
    assert keyed_folder(tmp_path / "emasim-abc", "abc") == tmp_path / "emasim-abc"


def test_a_cache_without_the_engine_loop_is_cold(tmp_path):
    from emasim.numba_cache import engine_subfolder, is_cold

    assert is_cold(tmp_path)
    other = tmp_path / "sim_0123"  # another installation's copy of the engine
    other.mkdir()
    (other / "engine.run_ticks-325.py311.nbi").write_bytes(b"")
    assert is_cold(tmp_path)
    mine = engine_subfolder(tmp_path)
    mine.mkdir()
    (mine / "engine.record-242.py311.nbi").write_bytes(b"")
    assert is_cold(tmp_path)  # another function's index: the loop still compiles
    (mine / "engine.run_ticks-325.py311.nbi").write_bytes(b"")
    assert not is_cold(tmp_path)


def test_after_a_run_the_cache_this_process_uses_is_warm():
    """The sub-folder rule is numba's: once this process has run the engine, it is there."""
    from emasim import NUMBA_CACHE_DIR
    from emasim.numba_cache import is_cold
    from emasim.scenarios.loader import load_scenario
    from emasim.sim.engine import simulate

    simulate(load_scenario("speed-step", controllers=["speed=pi"]).setup().with_(duration_s=1e-3))
    assert not is_cold(NUMBA_CACHE_DIR)
    assert not is_cold()  # the default: the folder emasim configured, the same one


def test_the_command_line_says_when_it_compiles(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from emasim import numba_cache
    from emasim.cli import app

    monkeypatch.setattr(numba_cache, "is_cold", lambda folder=None: True)
    command = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.01", "--no-plot"]
    result = CliRunner().invoke(app, [*command, "--out", str(tmp_path / "r")])
    assert result.exit_code == 0
    assert "compiling the simulation core: first run only" in result.output
    bad = CliRunner().invoke(app, ["run", "speed-step", "--set", "duration_s=-1"])
    assert bad.exit_code == 2 and "compiling" not in bad.output  # bad input: its one line only
