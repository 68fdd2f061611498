"""The job store: a list of runs (:class:`.batch.Job`) in one resumable folder, with one tidy
table. Studies (robustness, wear, verdict maps), the reproduction (the paper's comparisons,
the clearance sweep, the ablation, the hybrid part by part), the acceptance battery and the
tuning's trials (a job list that grows batch by batch: :meth:`Store.add`) run their jobs on
it. Its folder holds

* the record file (``study.json`` for a study, ``tuning.json`` for a tuning, ``jobs.json``
  for the others): what the store holds, the facility's description of its job list with the
  emasim version and a SHA-256 of every run's fully resolved scenario (:func:`digest`);
* ``runs/<run_id>/``: one folder per finished run, written by the worker the moment the run
  ends, atomically: ``scenario.toml`` (run it again with ``emasim run``), ``metrics.json``,
  ``meta.json`` (with ``job``: the run id, the label and the tags) and, for a job that keeps
  its trace (``Job.trace``), ``result.parquet`` (read back by :meth:`Store.result`). Without
  a trace a run records only what its metrics read, and its ``scenario.toml`` says so
  (``solver.record_signals = []``). A store given a ``measure`` (the acceptance battery's)
  runs it on each job instead: its :class:`Measured` metrics go into ``metrics.json`` and its
  files beside them (read back by :meth:`Store.read`);
* ``metrics.parquet``: the tidy table, one row per finished run: ``run_id``, ``label``, every
  tag, ``status`` ('ok', 'diverged: ...' or 'failed: ...', a run that failed for any other
  reason: a rule checked only as it ran, a folder that could not be written) and every
  metric; rewritten atomically as runs finish (at most every TABLE_EVERY_S, less often where
  a rewrite, whose cost grows with the rows, would take more than TABLE_SHARE of the client's
  time; and at the end);
* ``workers.log``: what the worker processes of a LocalCluster print (warnings, and each
  failed run's traceback), never the user's terminal.

The run folders are the record: a killed client or worker loses no finished run, and the same
job list in the same folder resumes, running only what has no finished folder yet, a failed
run, or a damaged one (a run folder of emasim's that lost a file is replaced; a killed worker's
runs are re-run by Dask on another worker; a group of runs sent again skips the runs it
finished before). A folder holding another record is refused: a store is never replaced. One
client at a time holds a store (a lock on its record file). The workers write the run folders
themselves: on a cluster of several machines the folder must be on a file system they share.
"""

import contextlib
import fcntl
import hashlib
import io
import json
import logging
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import DamagedResult, EmasimError, OutputError, SimulationDiverged
from ..jsonio import json_text
from ..manifest import list_file, manifest_stamps, verify_files
from ..output import check_target, is_emasim_folder, write_file, write_folder, write_new
from .batch import Job

METRICS_FILE = "metrics.parquet"
RUNS_FOLDER = "runs"
LOG_FILE = "workers.log"
RUN_ID = "run_id"  # every job's tag: its run folder's name
ROW_KEYS = (RUN_ID, "label", "status")
TABLE_TAG = b"emasim study metrics"  # in metrics.parquet's schema metadata: the file is ours
OK = "ok"
DIVERGED = "diverged"
FAILED = "failed"
FAILURE_LOG = "emasim_worker"  # not under "emasim": the command line's console never shows it
logging.getLogger(FAILURE_LOG).addHandler(logging.NullHandler())  # a LogToFile worker: its file
TABLE_EVERY_S = 1.0  # metrics.parquet is rewritten at most this often while runs finish
TABLE_SHARE = 0.05  # and at most this share of the client's time goes to rewriting it


@dataclass(frozen=True)
class Measured:
    """What a store's ``measure`` makes of a job: ``metrics`` (name -> a number, a flag,
    None or text: the table's columns) and ``files`` (name -> text) for its run folder."""

    metrics: dict
    files: dict[str, str]


def run_id_of(job: Job) -> str:
    """A job's run id (its run folder's name, its row's key)."""
    return job.tags[RUN_ID]


def digest(jobs: Sequence[Job]) -> str:
    """SHA-256 of every job's fully resolved scenario, in order, and the emasim version."""
    from ..version import __version__

    sha = hashlib.sha256()
    for job in jobs:
        sha.update(json.dumps(job.scenario.model_dump(mode="json"), sort_keys=True).encode())
    sha.update(__version__.encode())
    return sha.hexdigest()


def _held_by() -> str:
    """Why a store's lock is held. In a process that imported the starting script again as
    ``__mp_main__`` (a Dask worker process, as Python's multiprocessing starts one), it is that
    script's own run: a script without a ``__main__`` guard starts the study again in every
    worker."""
    again = sys.modules.get("__mp_main__")  # runpy holds the script there while it runs it
    if again is not None and again is not sys.modules.get("__main__"):
        return (
            "a worker process this study started is running your script again: put the "
            'lines that start it under `if __name__ == "__main__":` (Python runs a script '
            "again in each process it starts)"
        )
    return "another emasim process is running it"


@dataclass
class Store:
    """A job list's folder (module docstring). ``record`` says what it holds (the record
    file's content, ``record_file`` its name); ``columns`` are the table's leading columns
    (default: ROW_KEYS, then the tags in the jobs' order); ``name`` is what its refusals
    call it (``--out FOLDER`` for a study), ``refusal`` what they say of another record;
    ``measure(job)``, when given, replaces the simulation of each job (module docstring)."""

    folder: Path
    jobs: list[Job]
    record: dict
    record_file: str = "jobs.json"
    columns: tuple[str, ...] = ()
    name: str = ""
    refusal: str = "holds other runs; it is never replaced: choose another folder"
    measure: Callable[[Job], Measured] | None = None

    def __post_init__(self):
        self.folder = Path(self.folder)
        self.name = self.name or str(self.folder)
        self._tag_columns = not self.columns  # the columns follow the jobs' tags
        self._rows: dict[str, dict] = {}  # the finished rows read or run so far
        self._table_current = False  # metrics.parquet holds every finished row, as written
        jobs, self.jobs, self._order = list(self.jobs), [], {}
        self.add(jobs)

    def add(self, jobs: Sequence[Job]) -> None:
        """Append ``jobs`` to the job list (one that grows as it runs: a tuning's trials)."""
        for job in jobs:
            if run_id_of(job) in self._order:
                raise ValueError(f"two jobs of a store share a run id ({run_id_of(job)})")
            self._order[run_id_of(job)] = len(self.jobs)
            self.jobs.append(job)
        if self._tag_columns:
            tags = dict.fromkeys(k for job in self.jobs for k in job.tags if k != RUN_ID)
            self.columns = (*ROW_KEYS, *tags)

    def open(self) -> None:
        """Make the folder, or check that the one there holds this very record."""
        record = json.loads(json_text(self.record))
        path = self.folder / self.record_file
        if is_emasim_folder(self.folder) and path.is_file():
            try:
                there = json.loads(path.read_text())
            except (OSError, ValueError):
                there = None
            if there == record:
                return
            raise OutputError(f"{self.name}: {self.refusal}")
        check_target(self.folder, force=False)

        def write(tmp: Path) -> None:
            write_new(tmp / self.record_file, json_text(record))
            write_new(tmp / LOG_FILE, "")
            (tmp / RUNS_FOLDER).mkdir()

        write_folder(self.folder, write, kind="jobs")

    @contextlib.contextmanager
    def holding(self):
        """Hold the store's lock (flock on its record file: writing into the folder locks the
        folder itself) or refuse: one client at a time."""
        fd = os.open(self.folder / self.record_file, os.O_RDONLY)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputError(f"{self.name}: {_held_by()}") from None
            yield
        finally:
            os.close(fd)

    def run_folder(self, job: Job) -> Path:
        return (self.folder / RUNS_FOLDER / run_id_of(job)).absolute()

    def finished(self) -> dict[str, dict]:
        """run_id -> row of each of the jobs' finished run folders (not a failed one); one
        read or written already while the store is held (:meth:`opened`) is not read again."""
        for job in self.jobs:
            if run_id_of(job) not in self._rows:
                self._keep(_finished_row(self.run_folder(job)))
        return dict(self._rows)

    def _keep(self, row: dict | None) -> None:
        if row is not None and not is_failed(row):
            self._rows[row[RUN_ID]] = row
            self._table_current = False

    def run(self, client=None, **options) -> dict[str, dict]:
        """Open the store, run every job it has no finished run of (:meth:`run_pending`, whose
        ``options`` these are), and return run_id -> row of every job."""
        with self.opened():
            return self.run_pending(client, **options)

    @contextlib.contextmanager
    def opened(self):
        """Open the store and hold it (:meth:`holding`) for one or more :meth:`run_pending`
        (each run folder is read and checked once while it is held); then list the workers'
        log, whose writers are done, in its manifest."""
        self.open()
        with self.holding():
            self._rows, self._table_current = {}, False
            yield self
            list_file(self.folder, LOG_FILE)

    def run_pending(
        self,
        client=None,
        progress: Callable[[int, int], None] | None = None,
        trust_fmu: bool = False,
        cluster: Callable | None = None,
        inline: bool = False,
    ) -> dict[str, dict]:
        """Run every job the store held by :meth:`opened` has no finished run of, and return
        run_id -> row of every job. ``client``: a ``dask.distributed.Client`` to run on, else
        the one ``cluster()`` opens (a context manager; default: threads in this process);
        ``inline``: the jobs one after another in this process, without Dask (a few short
        runs, where a cluster would cost more than they do). ``progress(done, total)`` is
        called as runs finish."""
        from .. import numba_cache
        from .batch import dask_client, map_runs

        rows = self.finished()
        pending = [job for job in self.jobs if run_id_of(job) not in rows]
        pending.sort(key=lambda job: -job.scenario.duration_s)  # the last to end is short
        total = len(self.jobs)
        if progress is not None:
            progress(len(rows), total)
        if not self._table_current:  # not again at each batch of a growing job list
            self.write_table(rows)  # (its first write: its cost is pyarrow's import too)
        if not pending:
            return rows
        due = [time.monotonic() + TABLE_EVERY_S]  # when the table may be rewritten next

        def on_done(_, row):
            rows[row[RUN_ID]] = row
            self._keep(row)
            if time.monotonic() >= due[0]:
                due[0] = self._timed_write(rows)
            if progress is not None:
                progress(len(rows), total)

        calls = [(job, self.run_folder(job), trust_fmu, self.measure) for job in pending]
        try:
            if inline:
                for i, call in enumerate(calls):
                    on_done(i, run_and_write(*call))
                return rows
            opened = cluster() if cluster else dask_client(processes=False)
            with contextlib.nullcontext(client) if client else opened as used:
                # one run first only to compile: with a warm cache, all at once
                cold = numba_cache.is_cold()
                map_runs(run_and_write, calls, used, on_done, first_alone=cold, grouped=True)
        finally:
            self.write_table(rows)  # every run that finished
        return rows

    def require_ok(self, rows: dict[str, dict]) -> None:
        """Raise EmasimError naming the first job whose run did not end ok, if any."""
        for job in self.jobs:
            status = rows[run_id_of(job)]["status"]
            if status != OK:
                raise EmasimError(
                    f"{run_id_of(job)}: {status} (its folder: {self.run_folder(job)}; the "
                    f"runs that finished stay in {self.folder})"
                )

    def read(self, job: Job, name: str) -> str:
        """The text of a file a ``measure`` wrote for ``job``, checked against the run
        folder's manifest (emasim.manifest.verify_files)."""
        verify_files(self.run_folder(job), [name])
        return (self.run_folder(job) / name).read_text()

    def metrics_of(self, row: dict) -> dict:
        """A row's metrics: every value but the run's keys and tags."""
        return {k: v for k, v in row.items() if k not in self.columns}

    def frame(self, rows: dict[str, dict]):
        """The rows as a DataFrame in the jobs' order, one column per key (missing: NaN)."""
        import pandas as pd

        ordered = sorted(rows.values(), key=lambda row: self._order[row[RUN_ID]])
        metrics = dict.fromkeys(k for row in ordered for k in row if k not in self.columns)
        return pd.DataFrame(ordered, columns=[*self.columns, *metrics])

    def _timed_write(self, rows: dict[str, dict]) -> float:
        """Write the table; return when it may be rewritten next (TABLE_EVERY_S after, or
        later where the rewrite itself took more than TABLE_SHARE of that: a table of many
        thousand rows is rewritten less often, so its cost stays a small share of the client's
        time, which the workers need on a machine with no core to spare)."""
        start = time.monotonic()
        self.write_table(rows)
        end = time.monotonic()
        return end + max(TABLE_EVERY_S, (end - start) / TABLE_SHARE)

    def write_table(self, rows: dict[str, dict]) -> None:
        """Write metrics.parquet atomically (pyarrow; the schema metadata tags it as ours)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(self.frame(rows), preserve_index=False)
        table = table.replace_schema_metadata(
            {**(table.schema.metadata or {}), b"emasim": TABLE_TAG}
        )
        buffer = io.BytesIO()
        pq.write_table(table, buffer)
        write_file(
            self.folder / METRICS_FILE,
            buffer.getvalue(),
            force=True,
            is_ours=_is_table,
            what="--out",
            listed=True,
        )
        self._table_current = True

    def result(self, job: Job):
        """The Result of a finished job that kept its trace (emasim.sim.result.Result.load)."""
        from ..sim.result import Result

        return Result.load(self.run_folder(job))


def keyed(root: Path, jobs: list[Job], record: dict, **options) -> Store:
    """The store of ``jobs`` under ``root``, named ``jobs-<key>`` by what it holds: ``record``
    with the emasim version, the digest of emasim's source and of every job's scenario (none
    for a job list that grows as it runs, a tuning's: its record says what it holds). The
    same job list finds its store again (and resumes it); a changed scenario or source makes
    one of its own, so no result of other code is ever taken for this code's."""
    from ..version import __version__
    from .runs import source_digest

    record = record | {"emasim_version": __version__, "emasim_source_sha256": source_digest()}
    if jobs:
        record |= {"runs": len(jobs), "scenarios_sha256": digest(jobs)}
    key = hashlib.sha256(json_text(record).encode()).hexdigest()[:12]
    return Store(Path(root) / f"jobs-{key}", jobs, record, **options)


def run_and_write(job: Job, folder: Path, trust_fmu: bool = False, measure=None) -> dict:
    """A worker's task: simulate one run (or ``measure`` it: :class:`Store`), write its run
    folder, return its row. A run whose folder is finished already (a task Dask runs again
    after a worker was lost) is read, not run again. A run that diverges or fails for any
    other reason is a row that says so (``status``: 'diverged: ...' or 'failed: ...', one
    line), in a folder marked so where it can be written: it never stops the others. A
    failed or damaged folder of emasim's there is replaced (never one holding a file emasim
    did not write)."""
    from .runs import run_scenario

    finished = _finished_row(folder)
    if finished is not None and finished[RUN_ID] == run_id_of(job) and not is_failed(finished):
        return finished
    replace = os.path.lexists(folder)  # failed or damaged: write_folder refuses what is not ours
    record = {RUN_ID: run_id_of(job), "label": job.label, "tags": _tags(job)}
    start = time.perf_counter()
    try:
        if measure is not None:
            measured = measure(job)
            wall_s = time.perf_counter() - start
            _write_record(folder, job, record, OK, measured, wall_s, replace)
            return _row(record, OK, measured.metrics)
        scenario = job.scenario if job.trace else metrics_only(job.scenario)
        result = run_scenario(scenario, trust_fmu=trust_fmu, label=job.label)
        result.meta["job"] = record
        write = lambda tmp: result.write_files(tmp, plot=False, traces=job.trace)  # noqa: E731
        write_folder(folder, write, force=replace)
        return _row(record, OK, result.metrics)
    except SimulationDiverged as err:
        status = f"{DIVERGED}: {one_line(err)}"
    except Exception as err:  # any other failure is this run's, not the store's
        status = f"{FAILED}: {reason(err)}"
        logging.getLogger(FAILURE_LOG).error(f"{run_id_of(job)} {status}\n{traceback.format_exc()}")
    with contextlib.suppress(Exception):  # a folder that cannot be written: the row says why
        _write_record(folder, job, record, status, Measured({}, {}), float("nan"), replace)
    return _row(record, status, {})


def _tags(job: Job) -> dict:
    return {k: v for k, v in job.tags.items() if k != RUN_ID}


def metrics_only(scenario):
    """``scenario`` recording only what its metrics read (solver.record_signals empty): a run
    whose traces are not kept holds none of the others in memory either."""
    return scenario.model_copy(
        update={"solver": scenario.solver.model_copy(update={"record_signals": []})}
    )


def one_line(err: BaseException, limit: int = 300) -> str:
    """An error's message as one line of at most ``limit`` characters."""
    text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def reason(err: BaseException) -> str:
    """Why a run failed, in one line: an emasim error's message, an OSError's cause and
    file, else the exception's type and message."""
    if isinstance(err, OSError) and not isinstance(err, OutputError) and err.strerror:
        where = f" ({err.filename})" if err.filename else ""
        return one_line(f"cannot write the run folder: {err.strerror}{where}")
    if isinstance(err, EmasimError):
        return one_line(err)
    return one_line(f"{type(err).__name__}: {one_line(err)}")


def is_failed(row: dict) -> bool:
    """A row of a run that failed (not diverged): run again when the store resumes."""
    return str(row.get("status", "")).startswith(FAILED)


def _write_record(
    folder: Path,
    job: Job,
    record: dict,
    status: str,
    measured: Measured,
    wall_s: float,
    replace: bool,
) -> None:
    """The folder of a run that was measured, diverged or failed: its meta (with ``status``),
    scenario, metrics and the measure's files."""
    from ..sim.result import write_records
    from .runs import meta_of

    meta = meta_of(job.scenario, wall_s) | {"label": job.label, "job": record, "status": status}
    resolved = job.scenario.model_dump(mode="json", exclude_none=True)

    def write(tmp: Path) -> None:
        write_records(tmp, measured.metrics, meta, resolved)
        for name, text in measured.files.items():
            write_new(tmp / name, text)

    write_folder(folder, write, force=replace)


def _row(record: dict, status: str, metrics: dict) -> dict:
    row = {RUN_ID: record[RUN_ID], "label": record["label"], **record["tags"], "status": status}
    return row | dict(metrics)


def finished_rows(folder: Path) -> dict[str, dict]:
    """run_id -> row of every finished run folder of a store (its record, not the table)."""
    runs = Path(folder) / RUNS_FOLDER
    found = (_finished_row(run) for run in runs.iterdir()) if runs.is_dir() else ()
    return {row[RUN_ID]: row for row in found if row is not None}


def _finished_row(run: Path) -> dict | None:
    """The row of a finished run folder, from its record; None for anything else: no folder,
    one not ours, a damaged one (a file of its manifest lost or changed: its trace, its
    measurement), or a killed run's temporary (``.<run_id>.tmp-...``, whose records may be
    written already: only a folder named by its run id is published)."""
    if not is_emasim_folder(run):
        return None
    try:
        verify_files(run, list(manifest_stamps(run)))
        meta = json.loads((run / "meta.json").read_text())
        metrics = json.loads((run / "metrics.json").read_text())
        row = _row(meta["job"], meta.get("status", OK), metrics)
    except (OSError, ValueError, KeyError, TypeError, DamagedResult):
        return None
    return row if row[RUN_ID] == run.name else None


def _is_table(path: Path) -> bool:
    import pyarrow.parquet as pq

    try:
        return (pq.read_schema(path).metadata or {}).get(b"emasim") == TABLE_TAG
    except (OSError, ValueError, TypeError):
        return False


def status_counts(table) -> dict[str, int]:
    """How many runs of a store's table are ok, diverged and failed."""
    kinds = [str(s).split(":", 1)[0] for s in table["status"]] if len(table) else []
    return {kind: kinds.count(kind) for kind in (OK, DIVERGED, FAILED)}


def first_reasons(table, n: int = 3) -> list[str]:
    """``run_id status`` of the first ``n`` runs that are not ok, in the jobs' order."""
    bad = table[table["status"] != OK] if len(table) else table
    return [f"{row.run_id} {row.status}" for row in bad.head(n).itertuples()]


def read_table(folder: str | Path):
    """A store's metrics.parquet as a pandas DataFrame."""
    import pandas as pd

    return pd.read_parquet(Path(folder) / METRICS_FILE)
