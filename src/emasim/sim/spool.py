"""Traces too large for memory: written to Parquet in row groups as the run goes, read back by
column.

A run whose trace would take more than SPOOL_BYTES (the kept columns x the recorded rows x 8
bytes) keeps only one row group of it in memory: the engine records into a buffer of
:func:`chunk_rows` rows, and each time the buffer fills, :class:`TraceSpool` appends it to a
Parquet file as one row group. The file is a temporary file without a name
(``tempfile.TemporaryFile``: the system removes it when its last handle closes, so a killed
run leaves nothing behind). The finished file is read through :class:`ParquetTraces`, which a
:class:`emasim.sim.result.Result` holds instead of an array: a column is read one row group at
a time into its own array, so reading one costs that column and one row group, never the
whole trace; saving copies the file's bytes as they are. A saved result folder whose
``result.parquet`` is larger than SPOOL_BYTES is read back the same way.

SPOOL_BYTES is 32 MiB, set by the memory it bounds, not by read speed: a run holds one row
group beside what importing emasim and its compiled core take (docs/speed.md's baseline),
well inside the 600 MB a 1000 s run at 10 kHz must stay under (issue 30). Parquet's own
advice, row groups of 512 MiB to 1 GiB (parquet.apache.org, "Configurations"), is for
sequential reads on HDFS and would hold most of such a run in memory; pyarrow writes 1 Mi
rows per group by default, 8 MiB of each float64 column, the same order as here. A trace of
up to 32 MiB (32 MiB / (8 bytes x its columns) rows: 14 s of speed-sine's 29 columns at
10 kHz) stays in memory as before, so short runs pay no file input and output.
"""

import contextlib
import os
import shutil
import tempfile
import weakref

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import OutputError

SPOOL_BYTES = 32 * 2**20
# how emasim writes every Parquet trace: Snappy-compressed (pyarrow's default) and without
# dictionary encoding, which the samples of a float signal, nearly all distinct, cannot use:
# on speed-sine's trace it made the file no smaller and took most of the write's time
PARQUET_OPTIONS = {"use_dictionary": False}


def chunk_rows(columns: int) -> int:
    """Rows of one row group of ``columns`` float64 columns: SPOOL_BYTES of them."""
    return max(1, SPOOL_BYTES // (8 * max(columns, 1)))


def arrow_table(names, columns) -> pa.Table:
    """One float64 Arrow column per 1-D array of ``columns``, made from the arrays' own buffers:
    no copy for a contiguous array (the engine's trace rows are), and none of pyarrow's
    conversion from numpy, which imports pandas (a third of a second of a run's start-up)."""
    arrays = []
    for column in columns:
        column = np.ascontiguousarray(column, dtype=np.float64)
        arrays.append(
            pa.Array.from_buffers(pa.float64(), column.size, [None, pa.py_buffer(column)])
        )
    return pa.Table.from_arrays(arrays, names=list(names))


class TraceSpool:
    """A temporary Parquet file that a run's trace is appended to, one row group at a time.
    A write that fails (a full disk) is one line naming the folder and what to change."""

    def __init__(self, names: tuple[str, ...]):
        self.names = names
        self.handle = tempfile.TemporaryFile(prefix="emasim-trace-")
        schema = pa.schema([(name, pa.float64()) for name in names])
        with _writing():
            self._writer = pq.ParquetWriter(self.handle, schema, **PARQUET_OPTIONS)

    def append(self, block: np.ndarray) -> None:
        """Append ``block`` (one row per column, as the engine records it) as a row group."""
        if not self._writer.is_open:
            raise RuntimeError("the trace's file is closed: EngineRun.result() ends a streamed run")
        if block.shape[1]:
            table = arrow_table(self.names, block)
            with _writing():
                self._writer.write_table(table, row_group_size=block.shape[1])

    def finish(self) -> "ParquetTraces":
        """Close the Parquet file (its footer written) and return it to be read."""
        with _writing():
            self._writer.close()
        return ParquetTraces(self.handle)


@contextlib.contextmanager
def _writing():
    try:
        yield
    except OSError as err:
        raise OutputError(
            f"the run's trace, streamed to a temporary file in {tempfile.gettempdir()}: "
            f"cannot write ({err.strerror or err}); set TMPDIR to a folder with room, or "
            "record less (solver.record_period_s, solver.record_signals)"
        ) from None


class ParquetTraces:
    """The traces of a Parquet file, read by column: ``column(i)`` reads column i one row group
    at a time into a new float64 array; ``shape`` is (rows, columns), as an in-memory trace's;
    ``np.asarray`` of it reads every column (the whole trace in memory). ``handle``: the file,
    open for binary reading (a spool's temporary file, or a saved result's file)."""

    def __init__(self, handle):
        self.handle = handle
        weakref.finalize(self, handle.close)  # the file goes with the traces that read it
        self._file = pq.ParquetFile(handle)
        self.columns = tuple(self._file.schema_arrow.names)
        self.shape = (self._file.metadata.num_rows, len(self.columns))

    @classmethod
    def open(cls, path: os.PathLike) -> "ParquetTraces":
        """The traces of the Parquet file at ``path`` (opened now: it is read from this handle)."""
        return cls(open(path, "rb"))

    def column(self, index: int) -> np.ndarray:
        out = np.empty(self.shape[0])
        start = 0
        for (values,) in self.column_groups([index]):
            out[start : start + len(values)] = values
            start += len(values)
        return out

    def column_groups(self, indices: list[int]):
        """Each row group as a list of float64 arrays, one per column at ``indices``, in order."""
        names = [self.columns[i] for i in indices]
        for group in range(self._file.num_row_groups):
            yield [c.to_numpy() for c in self._file.read_row_group(group, columns=names).columns]

    def row_groups(self):
        """Each row group as a (rows, columns) float64 array, in order (a CSV is written so)."""
        for columns in self.column_groups(list(range(self.shape[1]))):
            yield np.column_stack(columns)

    def envelope(self, runs: int, indices: list[int]) -> np.ndarray:
        """The rows a figure of the columns at ``indices`` needs, read a row group at a time, as
        a (rows, len(indices)) array in order: in each of ``runs`` equal runs of rows (each cut
        where a row group ends), its first and last row and the rows of every column's smallest
        and largest value (NaN skipped). A line drawn through them keeps the amplitude of every
        oscillation, as emasim.analysis.plots thins a whole trace."""
        size = max(1, -(-self.shape[0] // runs))
        kept, start = [], 0
        for columns in self.column_groups(indices):
            block = np.column_stack(columns)
            edges = np.arange(-(start % size), block.shape[0], size)
            ends = np.minimum(edges + size, block.shape[0])
            for first, last in zip(np.maximum(edges, 0), ends, strict=True):
                part = block[first:last]
                nan = np.isnan(part)
                rows = np.unique(
                    np.concatenate(
                        [
                            [0, part.shape[0] - 1],
                            np.where(nan, np.inf, part).argmin(axis=0),
                            np.where(nan, -np.inf, part).argmax(axis=0),
                        ]
                    )
                )
                kept.append(part[rows])
            start += block.shape[0]
        return np.concatenate(kept) if kept else np.empty((0, len(indices)))

    def span(self) -> tuple[float, float]:
        """The first and the last value of the first column (a trace's first column is its
        time, t_s): two row groups read, not the file."""
        index = self._file.num_row_groups - 1
        first = self._file.read_row_group(0, columns=[self.columns[0]]).column(0)
        last = self._file.read_row_group(index, columns=[self.columns[0]]).column(0)
        return float(first[0].as_py()), float(last[-1].as_py())

    def copy_to(self, handle) -> None:
        """Write the Parquet file's bytes, as they are, to the binary ``handle``: in the kernel
        (``os.copy_file_range``, no pass through this process), and what it did not copy (not
        Linux, or files it cannot copy between) through this process."""
        handle.flush()
        at, done = handle.tell(), 0
        with contextlib.suppress(AttributeError, OSError):  # io.UnsupportedOperation included
            source, target = self.handle.fileno(), handle.fileno()
            size = os.fstat(source).st_size
            while done < size and (
                n := os.copy_file_range(source, target, size - done, done, at + done)
            ):
                done += n
        self.handle.seek(done)
        handle.seek(at + done)
        shutil.copyfileobj(self.handle, handle, 2**20)

    def __array__(self, dtype=None, copy=None):
        data = np.empty(self.shape)
        for i in range(self.shape[1]):
            data[:, i] = self.column(i)
        return data if dtype is None else data.astype(dtype)

    def __reduce__(self):
        # another process gets the traces themselves: this file is this process's
        return np.asarray, (np.asarray(self),)
