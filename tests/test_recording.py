"""What a run records: the kept columns only, stored once, and chosen signals on request.

The engine stores each kept column contiguously and hands that storage to the Result without a
copy (the memory of a long run is its trace, benchmarks/bench_engine.py measures it). A scenario
may name the signals to record (``solver.record_signals``); the run then keeps those, ``t_s``
and the columns its metrics and plots read, each equal bit for bit to the full run's.
"""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from emasim.analysis.report import ANALYSIS_COLUMNS
from emasim.cli import app
from emasim.errors import InputError
from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario
from emasim.sim.engine import simulate
from emasim.sim.result import Result

SHORT = "duration_s=0.2"


def test_the_result_holds_the_engine_trace_without_a_copy():
    setup = load_scenario("speed-step", controllers=["speed=pi"], settings=[SHORT]).setup()
    result = simulate(setup)
    assert result.data.flags["F_CONTIGUOUS"]  # one contiguous block per column
    assert result.data.base is not None and result.data.base.shape == result.data.T.shape
    assert result.columns == setup.kept_columns()
    assert not any(name.startswith(("linkage_", "hinge")) for name in result.columns)


@pytest.mark.parametrize("name", ["speed-step", "position-step", "bench-step"])
def test_chosen_signals_are_the_full_runs_columns(name):
    settings = [SHORT, "solver.record_signals=['uq_V']"]
    full = run_scenario(load_scenario(name, settings=[SHORT]).variants()[0][1])
    chosen = run_scenario(load_scenario(name, settings=settings).variants()[0][1])
    expected = {"t_s", "uq_V", *ANALYSIS_COLUMNS} & set(full.columns)
    assert set(chosen.columns) == expected
    assert len(chosen.columns) < len(full.columns)
    for column in chosen.columns:
        assert np.array_equal(chosen[column], full[column], equal_nan=True), column
    # NaN metrics (undefined ones) compare equal through their JSON text
    assert json.dumps(chosen.metrics, sort_keys=True) == json.dumps(full.metrics, sort_keys=True)


def test_a_saved_result_reads_back_bit_for_bit(tmp_path):
    setup = load_scenario("bench-step", settings=[SHORT]).variants()[0][1].setup()
    result = simulate(setup)
    folder = result.save(tmp_path / "run", plot=False)
    back = Result.load(folder)
    assert back.columns == result.columns
    assert np.array_equal(back.data, result.data, equal_nan=True)


def test_an_unknown_signal_is_one_line_naming_the_field():
    with pytest.raises(InputError, match=r"solver.record_signals.*did you mean 'iq_A'"):
        load_scenario("speed-step", settings=["solver.record_signals=['iq_a']"])
    run = CliRunner().invoke(app, ["run", "speed-step", "--set", "solver.record_signals=['iq_a']"])
    assert run.exit_code == 2
    assert len(run.output.strip().splitlines()) == 1
