"""Traces streamed to disk (emasim.sim.spool): a run whose trace is larger than SPOOL_BYTES
records it one row group at a time into a Parquet file and holds only that row group.

The oracle is the same run recorded whole in memory: the streamed trace, read back, equals it
bit for bit, for any chunking of the run, any recording period and a last row group left
part-full; and everything read from it (metrics, the saved Parquet and CSV files, a loaded
result) equals what the in-memory trace gives. SPOOL_BYTES is made small here so that a run of
a fraction of a second streams; its real value only sets the size of a row group.
"""

import contextlib
import errno
import io
import json
import os
import pickle
import tempfile
import tracemalloc

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from emasim import output
from emasim.analysis import figure_process
from emasim.analysis.report import step_metrics
from emasim.cli import app
from emasim.errors import InputError, OutputError
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


def test_a_streamed_run_ends_with_its_result_and_one_read_as_it_goes_stays_in_memory(
    small_groups,
):
    setup = _scenario().setup()
    run = EngineRun(setup)
    run.advance(500)
    run.result()
    with pytest.raises(RuntimeError, match=r"EngineRun.result\(\) ends a streamed run"):
        run.advance(1000)
    kept = EngineRun(setup, stream=False)  # a caller that reads the trace as the run goes
    kept.advance(500)
    assert kept.spool is None and kept.run.data.trace.shape[1] == setup.recorded_rows
    assert isinstance(kept.result().data, np.ndarray)


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


@pytest.mark.parametrize(
    ("name", "settings", "loaded"),
    [
        ("speed-step", ("duration_s=0.6",), True),  # the load at 0.4 s: its response, many blocks
        ("speed-step", ("load.motor_torque_Nm=[]",), False),  # the whole run is the step's
        ("position-step", (), False),  # the dead zone, and the rod's step
    ],
)
def test_step_metrics_of_a_streamed_run_are_the_whole_runs_exactly(
    small_groups, name, settings, loaded
):
    """The step's figures take no sum across blocks (emasim.analysis.passes): a crossing or an
    exit is found in one block, an extreme is an extreme, and the windows whose figures are
    sums are joined whole first. So they equal the whole run's bit for bit."""
    scenario = _scenario(name, settings)
    streamed = run_scenario(scenario)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = run_scenario(scenario)
    assert isinstance(streamed.data, ParquetTraces) and not isinstance(whole.data, ParquetTraces)
    quantity = scenario.experiment().quantity
    a, b = (step_metrics(result, quantity) for result in (streamed, whole))
    assert a.keys() == b.keys()
    assert ("load_recovery_time_s" in a) == loaded
    for key, value in b.items():
        assert a[key] == value or (np.isnan(a[key]) and np.isnan(value)), key


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
    _same_metrics(streamed.metrics, whole.metrics)
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
        _same_metrics(back.metrics, json.loads((b / "metrics.json").read_text()))


def test_a_streamed_runs_csv_is_written_a_row_group_at_a_time(small_groups, tmp_path, monkeypatch):
    """Result.to_csv of a spooled trace holds one row group's text at a time, never the whole
    file's, and writes the bytes the in-memory run writes."""
    scenario = _scenario()
    streamed = run_scenario(scenario)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = run_scenario(scenario)
    expected = whole.to_csv(tmp_path / "whole.csv").read_bytes()
    writes, real = [], output.new_file

    class Counted:  # the file's handle, counting what each write hands it
        def __init__(self, handle):
            self.handle = handle

        def write(self, block: bytes) -> int:
            writes.append(len(block))
            return self.handle.write(block)

    @contextlib.contextmanager
    def counted(path):
        with real(path) as handle:
            yield Counted(handle)

    monkeypatch.setattr(output, "new_file", counted)
    assert streamed.to_csv(tmp_path / "streamed.csv").read_bytes() == expected
    groups = pq.ParquetFile(streamed.data.handle).num_row_groups
    assert len(writes) == 1 + groups > 10  # the header, then each row group
    assert sum(writes) == len(expected) and max(writes) < len(expected) / 10


def test_a_streamed_runs_mat_file_is_written_a_column_at_a_time(small_groups, tmp_path):
    """Result.to_mat of a spooled trace hands scipy.io.savemat one column at a time, straight
    into the file: the bytes are the in-memory run's (after the 116-byte text header, which
    holds the time of writing), and the memory held at once is a column's few times and the
    1 MiB block the manifest's checksum reads (emasim.manifest.sha256_of): on this 7 MB trace,
    well under a third of it (the old way held the trace twice, every column and the file's
    bytes). Python's tracemalloc counts numpy's arrays."""
    scenario = _scenario(settings=("duration_s=3",))
    streamed = run_scenario(scenario)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = run_scenario(scenario)
    expected = whole.to_mat(tmp_path / "whole.mat").read_bytes()
    trace_bytes = 8 * streamed.data.shape[0] * streamed.data.shape[1]
    tracemalloc.start()
    try:
        streamed.to_mat(tmp_path / "streamed.mat")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert (tmp_path / "streamed.mat").read_bytes()[116:] == expected[116:]
    assert trace_bytes > 6e6 and peak < trace_bytes / 3, (peak, trace_bytes)


def _same_metrics(streamed: dict, whole: dict) -> None:
    """Equal up to the round-off of summing block by block and of the sine fit's QR of the
    blocks (emasim.analysis.metrics.SineFit; on these 0.3 s runs, a tenth of the sine's
    period, the fit's basis is ill-conditioned: 1e-13 relative is seen); NaN equals NaN."""
    assert streamed.keys() == whole.keys()
    for key, value in whole.items():
        assert value == pytest.approx(streamed[key], rel=1e-10, abs=1e-300, nan_ok=True), key


def test_a_streamed_result_travels_to_another_process_whole(small_groups):
    streamed = simulate(_scenario().setup())
    copy = pickle.loads(pickle.dumps(streamed))
    assert isinstance(copy.data, np.ndarray)
    assert np.array_equal(copy.data, np.asarray(streamed.data), equal_nan=True)


def test_a_full_disk_under_the_spool_is_one_line(small_groups, monkeypatch):
    class Full(io.BytesIO):
        def write(self, data):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(spool.tempfile, "TemporaryFile", lambda **_: Full())
    with pytest.raises(OutputError, match=r"^the run's trace, streamed to a temporary file in "
                       r".*: cannot write \(No space left on device\); set TMPDIR"):  # fmt: skip
        simulate(_scenario().setup())


def test_a_day_long_run_is_allowed_and_longer_is_one_line():
    day = ["duration_s=86400", "solver.record_period_s=0.001"]  # 8.6e7 rows
    assert load_scenario("speed-step", settings=day).duration_s == 86400
    with pytest.raises(InputError, match=r"duration_s: Input should be less than or equal to 864"):
        load_scenario("speed-step", settings=["duration_s=86401"])


def test_the_command_line_streams_a_long_run_and_draws_its_figure(
    small_groups, tmp_path, monkeypatch
):
    """``emasim run`` of a run longer than a row group: the folder's traces are the streamed file
    (several row groups) and equal the in-memory run's; its figure goes to the figure process
    as a result in memory that holds the rows the figure draws (Result.drawn), never the file."""
    handed = []
    save = figure_process.FigureProcess.save

    def handed_over(self, draw, path):
        handed.append(draw.__self__)
        save(self, draw, path)

    monkeypatch.setattr(figure_process.FigureProcess, "save", handed_over)
    args = ["run", "speed-sine", "-c", "speed=pi", "--set", SHORT, "--out", str(tmp_path / "run")]
    done = CliRunner().invoke(app, args)
    assert done.exit_code == 0, done.output
    folder = tmp_path / "run"
    assert (folder / "plot.png").stat().st_size > 0
    assert pq.ParquetFile(folder / "result.parquet").num_row_groups > 1
    assert len(handed) == 1 and isinstance(handed[0].data, np.ndarray)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(spool, "SPOOL_BYTES", 2**40)
        whole = simulate(
            load_scenario("speed-sine", controllers=["speed=pi"], settings=[SHORT]).setup()
        )
    back = Result.load(folder)
    assert np.array_equal(np.asarray(back.data), whole.data, equal_nan=True)


@pytest.mark.parametrize("runs", [1, 7, 40, 5000])
def test_a_figure_reads_the_envelope_of_a_spooled_trace(runs):
    """ParquetTraces.envelope, read a row group at a time: rows of the trace in order, the first
    and the last among them, and in each run of rows every column's smallest and largest value
    (NaN skipped), so that a figure drawn from it keeps every peak."""
    rng = np.random.default_rng(3)
    rows = 1009
    data = np.column_stack([np.arange(rows) * 1e-3, rng.normal(size=(rows, 3))])
    data[rng.choice(rows, 40), 2] = np.nan
    data[500:700, 3] = np.nan  # a stretch of NaN longer than some runs
    store = spool.TraceSpool(("t_s", "a", "b", "c"))
    for first in range(0, rows, 101):  # row groups of 101 rows: never aligned with the runs
        store.append(data[first : first + 101].T.copy())
    kept = store.finish().envelope(runs, [0, 1, 2, 3])
    index = np.searchsorted(data[:, 0], kept[:, 0])
    assert np.all(np.diff(index) > 0) and index[0] == 0 and index[-1] == rows - 1
    assert np.array_equal(kept, data[index], equal_nan=True)
    size = -(-rows // runs)
    for first in range(0, rows, size):
        part, mine = data[first : first + size], kept[(index >= first) & (index < first + size)]
        for column in range(1, 4):
            if np.all(np.isnan(part[:, column])):
                continue
            assert np.nanmax(part[:, column]) == np.nanmax(mine[:, column])
            assert np.nanmin(part[:, column]) == np.nanmin(mine[:, column])


@pytest.mark.parametrize("name", ["speed-step", "position-step", "bench-step"])
def test_a_runs_figures_read_only_the_figure_columns(name):
    """What Result.drawn keeps of a spooled trace, FIGURE_COLUMNS, is every column the run's
    figure and the comparison's overlay read: both draw from a result holding only those."""
    from dataclasses import replace

    from emasim.analysis.report import FIGURE_COLUMNS

    result = run_scenario(_scenario(name))
    names = tuple(n for n in result.columns if n in FIGURE_COLUMNS)
    only = replace(
        result, columns=names, data=result.data[:, [result.columns.index(n) for n in names]]
    )
    assert len(names) < len(result.columns)
    only.plot()
    from emasim.analysis.plots import plot_comparison

    plot_comparison({"one": only})


def test_a_spooled_file_is_copied_byte_for_byte_in_the_kernel_or_not(small_groups, tmp_path):
    """ParquetTraces.copy_to: into a file after bytes already written there (the kernel's
    copy_file_range, at the handle's position), and into a handle without a file descriptor
    (this process's copy): the Parquet file's bytes either way."""
    traces = EngineRun(_scenario().setup(), stream=True)
    traces.advance(traces.setup.n_ticks)
    data = traces.result().data
    data.handle.seek(0)
    original = data.handle.read()
    with open(tmp_path / "copy", "wb") as handle:
        handle.write(b"head")
        data.copy_to(handle)
    assert (tmp_path / "copy").read_bytes() == b"head" + original
    memory = io.BytesIO()
    data.copy_to(memory)
    assert memory.getvalue() == original


def test_a_streamed_runs_figure_rows_are_read_once(small_groups, monkeypatch):
    """Result.drawn reads the envelope once: a comparison's overlay and the run's own figure
    (Comparison.write_files draws both) share it."""
    reads = []
    envelope = ParquetTraces.envelope
    monkeypatch.setattr(ParquetTraces, "envelope", lambda *a: reads.append(1) or envelope(*a))
    result = run_scenario(_scenario())
    assert isinstance(result.data, ParquetTraces)
    assert result.drawn() is result.drawn() and len(reads) == 1
