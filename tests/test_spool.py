"""Traces streamed to disk (emasim.sim.spool): a run whose trace is larger than SPOOL_BYTES
records it one row group at a time into a Parquet file and holds only that row group.

The oracle is the same run recorded whole in memory: the streamed trace, read back, equals it
bit for bit, for any chunking of the run, any recording period and a last row group left
part-full; and everything read from it (metrics, the saved Parquet and CSV files, a loaded
result) equals what the in-memory trace gives. SPOOL_BYTES is made small here so that a run of
a fraction of a second streams; its real value only sets the size of a row group.
"""

import json
import os
import pickle
import tempfile

import numpy as np
import pyarrow.parquet as pq
import pytest

from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario
from emasim.sim import spool
from emasim.sim.engine import EngineRun, simulate
from emasim.sim.result import Result
from emasim.sim.spool import ParquetTraces

SHORT = "duration_s=0.3"


def _scenario(name="speed-sine", settings=()):
    return load_scenario(name, settings=[SHORT, *settings]).variants()[0][1]


@pytest.fixture
def small_groups(monkeypatch):
    """Row groups of 101 rows of 24 columns (a prime: groups never line up with anything)."""
    monkeypatch.setattr(spool, "SPOOL_BYTES", 8 * 24 * 101)


def _whole(setup):
    """The run recorded whole in memory (one group large enough for all of it)."""
    return simulate(setup)


@pytest.mark.parametrize("record_every", [1, 7])
@pytest.mark.parametrize("steps", [[None], [1, 2, 1234, 1235, 2999, None]])
def test_a_streamed_trace_equals_the_whole_one_bit_for_bit(small_groups, record_every, steps):
    setup = _scenario().setup().with_(record_every=record_every)
    run = EngineRun(setup)
    assert run.spool is not None
    group = run.run.data.trace.shape[1]
    assert group == spool.chunk_rows(len(setup.kept_columns())) < setup.recorded_rows
    for k in steps:  # any chunking of the ticks, across and inside row groups
        run.advance(setup.n_ticks if k is None else k)
    streamed = run.result()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = _whole(setup)
    assert isinstance(streamed.data, ParquetTraces) and isinstance(whole.data, np.ndarray)
    assert streamed.columns == whole.columns and streamed.data.shape == whole.data.shape
    assert setup.recorded_rows % group  # the last row group is part-full
    assert streamed.data._file.num_row_groups == -(-setup.recorded_rows // group)
    assert np.array_equal(np.asarray(streamed.data), whole.data, equal_nan=True)
    for name in whole.columns:
        assert np.array_equal(streamed[name], whole[name], equal_nan=True), name


def test_a_trace_within_one_group_stays_in_memory():
    setup = _scenario().setup()
    assert setup.recorded_rows <= spool.chunk_rows(len(setup.kept_columns()))
    assert isinstance(simulate(setup).data, np.ndarray)


def test_the_spool_has_no_name_a_kill_could_leave_behind(small_groups):
    before = set(os.listdir(tempfile.gettempdir()))
    run = EngineRun(_scenario().setup())
    run.advance(2000)
    assert os.fstat(run.spool.handle.fileno()).st_nlink == 0  # no name in any folder
    assert set(os.listdir(tempfile.gettempdir())) == before


@pytest.mark.parametrize("name", ["speed-sine", "bench-step"])
def test_metrics_and_saved_files_of_a_streamed_run_equal_the_whole_runs(
    small_groups, tmp_path, name
):
    scenario = _scenario(name)
    streamed = run_scenario(scenario)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = run_scenario(scenario)
    assert isinstance(streamed.data, ParquetTraces)
    assert json.dumps(streamed.metrics, sort_keys=True) == json.dumps(whole.metrics, sort_keys=True)
    for fmt in ("parquet", "csv"):
        a = streamed.save(tmp_path / f"streamed-{fmt}", plot=False, trace_format=fmt)
        b = whole.save(tmp_path / f"whole-{fmt}", plot=False, trace_format=fmt)
        if fmt == "csv":
            assert (a / "result.csv").read_bytes() == (b / "result.csv").read_bytes()
        else:  # the same columns and values; the streamed file keeps its row groups
            tables = [pq.read_table(f / "result.parquet") for f in (a, b)]
            assert tables[0].column_names == tables[1].column_names
            for x, y in zip(*(t.columns for t in tables), strict=True):
                assert np.array_equal(x.to_numpy(), y.to_numpy(), equal_nan=True)
            assert pq.ParquetFile(a / "result.parquet").num_row_groups > 1
        back = Result.load(a)  # larger than SPOOL_BYTES: read by column
        assert isinstance(back.data, ParquetTraces) == (fmt == "parquet")
        assert np.array_equal(np.asarray(back.data), whole.data, equal_nan=True)
        assert back.metrics == json.loads((b / "metrics.json").read_text())


def test_a_streamed_result_travels_to_another_process_whole(small_groups):
    streamed = simulate(_scenario().setup())
    copy = pickle.loads(pickle.dumps(streamed))
    assert isinstance(copy.data, np.ndarray)
    assert np.array_equal(copy.data, np.asarray(streamed.data), equal_nan=True)
