"""Studies: grids and Monte Carlo over any scenario key, run on Dask distributed.

A study takes a scenario, the keys it varies (:mod:`.variation`), ``runs`` Monte Carlo runs
of each grid point and the controller sets of the scenario's comparison (all, or the chosen
``labels``). Every sample runs with every controller set, so the sets are compared on the same
plants (paired). Its folder holds

* ``study.json``: what the study is (scenario, variations, runs, seed, labels, settings, the
  emasim version and a hash of every run's fully resolved scenario);
* ``runs/<run_id>/``: one folder per finished run, written by the worker the moment the run
  ends, atomically: ``scenario.toml`` (run it again with ``emasim run``), ``metrics.json``,
  ``meta.json`` (with ``study``: run id, label, sample, values) and, with ``traces``,
  ``result.parquet`` (without, a run records only what its metrics read, and its
  ``scenario.toml`` says so: ``solver.record_signals = []``);
* ``metrics.parquet``: one row per finished run: ``run_id``, ``label``, ``sample``, ``status``
  ('ok', 'diverged: ...' or 'failed: ...', a run that failed for any other reason: a rule
  checked only as it ran, a folder that could not be written), each variation's value (the
  factor for a '*' variation), then every metric; rewritten atomically as runs finish (at
  most every TABLE_EVERY_S, and at the end);
* ``summary/``: ``summary.md`` and ``summary.json`` (each metric's distribution for each
  controller set) and ``distributions.png``, written when the study is complete;
* ``workers.log``: what the worker processes of the LocalCluster a study starts print (warnings,
  and each failed run's traceback), never the user's terminal.

The run folders are the record: a killed client or worker loses no finished run, and the same
command resumes, running only what has no finished folder yet, a failed run, or a damaged one
(a run folder of emasim's that lost a file is replaced; a killed worker's runs are re-run by
Dask on another worker; the runs go to the workers in groups, :func:`.batch.task_groups`, and
a group run again skips the runs it finished before). A folder that holds another study is
refused: a study is never replaced; every run's scenario rules (an FMU's trust, the
co-simulation's) and the scheduler are checked before the folder is made. One client at a
time holds a study (a lock on its study.json). The workers write the run folders themselves:
on a cluster of several machines the folder must be on a file system they share.
"""

import contextlib
import fcntl
import hashlib
import io
import json
import logging
import os
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import EmasimError, InputError, OutputError, SimulationDiverged
from ..jsonio import json_text
from ..naming import slug
from ..output import check_folder, is_emasim_folder, write_file, write_folder, write_new
from ..scenarios.loader import apply_setting, read_scenario_file, set_key, validate_scenario
from .batch import Job
from .variation import Variation, parse_variation, samples

STUDY_FILE = "study.json"
METRICS_FILE = "metrics.parquet"
RUNS_FOLDER = "runs"
SUMMARY_FOLDER = "summary"
ROW_KEYS = ("run_id", "label", "sample", "status")
TABLE_TAG = b"emasim study metrics"  # in metrics.parquet's schema metadata: the file is ours
OK = "ok"
DIVERGED = "diverged"
FAILED = "failed"
LOG_FILE = "workers.log"
FAILURE_LOG = "emasim_worker"  # not under "emasim": the command line's console never shows it
logging.getLogger(FAILURE_LOG).addHandler(logging.NullHandler())  # a LogToFile worker: its file
TABLE_EVERY_S = 1.0  # metrics.parquet is rewritten at most this often while runs finish


@dataclass(frozen=True)
class StudySpec:
    """What a study runs (module docstring): ``vary`` are ``KEY=SPEC`` texts, ``settings``
    fixed ``KEY=VALUE`` overrides (as ``--set``), ``seeds`` a grid over the scenario's seed
    (its own seed and the next seeds-1), ``seed`` the seed of the draws, ``labels`` the
    controller sets to run (empty: every one), ``traces`` whether run folders keep traces."""

    scenario: str
    vary: tuple[str, ...] = ()
    runs: int = 1
    seeds: int = 1
    seed: int = 0
    labels: tuple[str, ...] = ()
    settings: tuple[str, ...] = ()
    traces: bool = False

    def record(self) -> dict:
        return {
            "scenario": self.scenario,
            "vary": list(self.vary),
            "runs": self.runs,
            "seeds": self.seeds,
            "seed": self.seed,
            "labels": list(self.labels),
            "settings": list(self.settings),
            "traces": self.traces,
        }


RUN_ID, SAMPLE = "run_id", "sample"  # a study job's tags, beside each variation's value


def run_id_of(job: Job) -> str:
    """A study job's run id (its run folder's name): ``<label>-<sample>``."""
    return job.tags[RUN_ID]


def varied(job: Job) -> dict:
    """A study job's value of each variation (the factor for a '*' one), by its name."""
    return {k: v for k, v in job.tags.items() if k not in (RUN_ID, SAMPLE)}


@dataclass
class Plan:
    """A study's runs, validated before any is started."""

    spec: StudySpec
    variations: list[Variation]
    labels: list[str]
    jobs: list[Job]
    digest: str = ""

    def record(self) -> dict:
        from ..version import __version__

        return {
            "study": self.spec.record(),
            "labels": self.labels,
            "samples": len(self.jobs) // max(len(self.labels), 1),
            "emasim_version": __version__,
            "scenarios_sha256": self.digest,
        }


def plan_study(spec: StudySpec) -> Plan:
    """Every run of ``spec``, its scenario validated; InputError names the first bad one."""
    from ..version import __version__

    if not 1 <= spec.runs <= 100_000 or not 1 <= spec.seeds <= 100_000:
        raise InputError("--runs and --seeds: whole numbers from 1 to 100000")
    raw, source = read_scenario_file(spec.scenario)
    for item in spec.settings:
        apply_setting(raw, item)
    nominal = validate_scenario(raw, source)
    variants = _variant_tables(raw, nominal)
    labels = list(spec.labels) or list(variants)
    unknown = [label for label in labels if label not in variants]
    if unknown:
        raise InputError(
            f"--label: {unknown[0]!r} is no controller set of {nominal.name}; "
            f"choose from: {', '.join(variants)}"
        )
    slugs = [slug(label) for label in labels]
    shared = [name for name in slugs if slugs.count(name) > 1]
    if shared:
        raise InputError(f"--label: two controller sets share the run folder name {shared[0]!r}")
    variations = [parse_variation(text) for text in spec.vary]
    if spec.seeds > 1:
        if any("seed" in v.keys for v in variations):
            raise InputError("--seeds: the seed is varied by --vary already; give one of them")
        seeds = tuple(range(nominal.seed, nominal.seed + spec.seeds))
        variations.append(Variation("seed", ("seed",), seeds, None, False))
    points = samples(variations, spec.runs, spec.seed)
    jobs = []
    for label in labels:
        resolved = validate_scenario(variants[label], source).model_dump(mode="json")
        for point in points:
            scenario = sample_scenario(variants[label], resolved, variations, point.values, source)
            run_id = f"{slug(label)}-{point.index:05d}"
            columns = {v.name: v.column(point.values[v.name]) for v in variations}
            jobs.append(Job(scenario, label, {RUN_ID: run_id, SAMPLE: point.index, **columns}))
    digest = hashlib.sha256()
    for job in jobs:
        text = json.dumps(job.scenario.model_dump(mode="json"), sort_keys=True)
        digest.update(text.encode())
    digest.update(__version__.encode())
    return Plan(spec, variations, labels, jobs, digest.hexdigest())


def _variant_tables(raw: dict, nominal) -> dict[str, dict]:
    """label -> the raw table of each controller set's single-run scenario."""
    if not nominal.compare:
        return {nominal.controllers_label(): raw}
    single = {k: v for k, v in raw.items() if k != "compare"}
    return {
        entry["label"]: {**single, "controllers": entry.get("controllers", {})}
        for entry in raw["compare"]
    }


def sample_scenario(
    raw: dict,
    resolved: dict,
    variations: list[Variation],
    values: dict,
    source: str,
    what: str = "--vary",
):
    """The validated scenario of one sample: each variation's value set on a copy of ``raw``.
    A '*' variation multiplies the ``resolved`` scenario's value; a number given for a key
    that holds a list of numbers (the linkage's four hinge clearances) sets every element.
    ``what`` names the option in an error's line."""
    table = sampled_table(raw, resolved, variations, values, what)
    try:
        return validate_scenario(table, source)
    except InputError as err:
        shown = ", ".join(f"{k}={v!r}" for k, v in values.items())
        raise InputError(f"{what}: the sample {shown} is not a valid scenario: {err}") from None


def sampled_table(
    raw: dict, resolved: dict, variations: list[Variation], values: dict, what: str = "--vary"
) -> dict:
    """A copy of ``raw`` with each variation's value set (:func:`sample_scenario`)."""
    table = json.loads(json.dumps(raw))  # a deep copy of plain TOML data
    for variation in variations:
        for i, key in enumerate(variation.keys):
            value = variation.value_of(values[variation.name], i)
            nominal = resolved_value(resolved, key)
            if isinstance(nominal, list) and _is_number(value):
                value_of = [value * x if variation.relative else value for x in nominal]
            elif variation.relative:
                if not _is_number(nominal):
                    raise InputError(f"{what} {key}: the scenario has no number there to scale")
                value_of = value * nominal
            else:
                value_of = value
            set_key(table, key, value_of, what)
    return table


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def resolved_value(resolved: dict, key: str):
    """The value at a dotted key of a resolved scenario, None where it has none (a key the
    scenario leaves out, set by the variation itself)."""
    value = resolved
    for part in key.split("."):
        if isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        elif isinstance(value, dict) and part in value:
            value = value[part]
        else:
            return None
    if isinstance(value, list) and not all(_is_number(x) for x in value):
        return None
    return value


def run_and_write(job: Job, folder: Path, traces: bool, trust_fmu: bool = False) -> dict:
    """A worker's task: simulate one run, write its run folder, return its metrics row. A run
    whose folder is finished already (a task Dask runs again after a worker was lost) is read,
    not run again. A run that diverges or fails for any other reason is a row that says so
    (``status``: 'diverged: ...' or 'failed: ...', one line), in a folder marked so where it
    can be written: it never stops the study. A failed or damaged folder of emasim's there
    is replaced (never one holding a file emasim did not write)."""
    from .runs import run_scenario

    finished = _finished_row(folder)
    if finished is not None and finished["run_id"] == run_id_of(job) and not is_failed(finished):
        return finished
    replace = os.path.lexists(folder)  # failed or damaged: write_folder refuses what is not ours
    record = {"run_id": run_id_of(job), "label": job.label, "sample": job.tags[SAMPLE]}
    record["values"] = varied(job)
    scenario = job.scenario if traces else metrics_only(job.scenario)
    try:
        result = run_scenario(scenario, trust_fmu=trust_fmu, label=job.label)
        result.meta["study"] = record
        write = lambda tmp: result.write_files(tmp, plot=False, traces=traces)  # noqa: E731
        write_folder(folder, write, force=replace)
        return _row(record, OK, result.metrics)
    except SimulationDiverged as err:
        status = f"{DIVERGED}: {one_line(err)}"
    except Exception as err:  # any other failure is this run's, not the study's
        status = f"{FAILED}: {reason(err)}"
        logging.getLogger(FAILURE_LOG).error(f"{run_id_of(job)} {status}\n{traceback.format_exc()}")
    with contextlib.suppress(Exception):  # a folder that cannot be written: the row says why
        _write_failed(folder, job, record, status, replace)
    return _row(record, status, {})


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
    """A row of a run that failed (not diverged): run again when the study resumes."""
    return str(row.get("status", "")).startswith(FAILED)


def _write_failed(folder: Path, job: Job, record: dict, status: str, replace: bool) -> None:
    """The folder of a run that diverged or failed: its meta (with ``status``) and scenario."""
    from ..sim.result import write_records
    from .runs import meta_of

    meta = meta_of(job.scenario, float("nan")) | {"label": job.label, "study": record}
    meta["status"] = status
    resolved = job.scenario.model_dump(mode="json", exclude_none=True)
    write_folder(folder, lambda tmp: write_records(tmp, {}, meta, resolved), force=replace)


def _row(record: dict, status: str, metrics: dict) -> dict:
    row = {k: record[k] for k in ("run_id", "label", "sample")}
    row["status"] = status
    return row | dict(record["values"]) | dict(metrics)


def finished_rows(folder: Path) -> dict[str, dict]:
    """run_id -> row of every finished run folder of a study (its record, not the table)."""
    runs = folder / RUNS_FOLDER
    found = (_finished_row(run) for run in runs.iterdir()) if runs.is_dir() else ()
    return {row["run_id"]: row for row in found if row is not None}


def _finished_row(run: Path) -> dict | None:
    """The row of a finished run folder, from its record; None for anything else (no folder,
    a killed run's temporary, or not ours)."""
    if not is_emasim_folder(run):
        return None
    try:
        meta = json.loads((run / "meta.json").read_text())
        metrics = json.loads((run / "metrics.json").read_text())
        record = meta["study"]
    except (OSError, ValueError, KeyError):
        return None
    return _row(record, meta.get("status", OK), metrics)


@dataclass
class Study:
    """A study's folder and its table (a pandas DataFrame, one row per run)."""

    folder: Path
    table: object
    plan: Plan = field(repr=False)

    @property
    def complete(self) -> bool:
        return len(self.table) == len(self.plan.jobs)

    def summary(self) -> dict:
        """label -> metric -> distribution (:func:`distribution`) over the finished runs."""
        return summarize(self.table, self.plan)


def run_study(
    spec: StudySpec,
    out: str | Path,
    scheduler: str | None = None,
    workers: int | None = None,
    progress=None,
    trust_fmu: bool = False,
    client=None,
) -> Study:
    """Run (or resume) the study ``spec`` in folder ``out`` on Dask and return it.

    ``client``: a ``dask.distributed.Client`` to run on; else one to the scheduler at
    ``scheduler``, else to a LocalCluster of ``workers`` processes (default one per core).
    ``progress(done, total)`` is called as runs finish.
    """
    from .. import numba_cache
    from ..sim.cosim import check_runnable
    from .batch import check_scheduler, dask_client, map_runs

    plan = plan_study(spec)
    for job in plan.jobs:  # every rule a run checks, before anything is made
        check_runnable(job.scenario, trust_fmu)
    if client is None and scheduler is not None:
        check_scheduler(scheduler)
    folder = Path(out)
    open_folder(folder, plan)
    with _holding(folder):
        rows = finished_rows(folder)
        known = {run_id_of(job) for job in plan.jobs}
        rows = {run_id: row for run_id, row in rows.items() if run_id in known}
        rows = {run_id: row for run_id, row in rows.items() if not is_failed(row)}
        pending = [job for job in plan.jobs if run_id_of(job) not in rows]
        total = len(plan.jobs)
        if progress is not None:
            progress(len(rows), total)
        write_table(folder, rows, plan)

        written = [time.monotonic()]

        def on_done(_, row):
            rows[row["run_id"]] = row
            if time.monotonic() - written[0] >= TABLE_EVERY_S:
                write_table(folder, rows, plan)
                written[0] = time.monotonic()
            if progress is not None:
                progress(len(rows), total)

        if pending:
            jobs = [
                (job, (folder / RUNS_FOLDER / run_id_of(job)).absolute(), spec.traces, trust_fmu)
                for job in pending
            ]
            with (
                contextlib.nullcontext(client)
                if client
                else dask_client(
                    scheduler, workers, log_file=(folder / LOG_FILE, FAILURE_LOG)
                ) as used
            ):
                try:  # one run first only to compile: with a warm cache, all at once
                    cold = numba_cache.is_cold()
                    map_runs(run_and_write, jobs, used, on_done, first_alone=cold, grouped=True)
                finally:
                    write_table(folder, rows, plan)  # every run that finished
        table = as_frame(rows, plan)
        study = Study(folder, table, plan)
        if study.complete:
            write_summary(folder, study)
    return study


def open_folder(folder: Path, plan: Plan) -> None:
    """Make the study folder, or check that the one there holds this very study."""
    record = plan.record()
    if is_emasim_folder(folder) and (folder / STUDY_FILE).is_file():
        try:
            there = json.loads((folder / STUDY_FILE).read_text())
        except (OSError, ValueError):
            there = None
        if there == json.loads(json_text(record)):
            return
        raise OutputError(
            f"--out {folder}: holds another study (its scenario, --vary, --runs, --seeds, "
            "--label, --set or the emasim version differ); a study is never replaced: "
            "the same command resumes it, choose another --out for this one"
        )
    check_folder(folder, force=False)

    def write(tmp: Path) -> None:
        write_new(tmp / STUDY_FILE, json_text(record))
        write_new(tmp / LOG_FILE, "")
        (tmp / RUNS_FOLDER).mkdir()

    write_folder(folder, write, kind="study")


@contextlib.contextmanager
def _holding(folder: Path):
    """Hold the study's lock (flock on its study.json: writing into the folder locks the folder
    itself) or refuse: one client at a time."""
    fd = os.open(folder / STUDY_FILE, os.O_RDONLY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise OutputError(
                f"--out {folder}: another emasim process is running this study"
            ) from None
        yield
    finally:
        os.close(fd)


def _columns(rows: list[dict], plan: Plan) -> list[str]:
    names = [*ROW_KEYS, *(v.name for v in plan.variations)]
    metrics = dict.fromkeys(k for row in rows for k in row if k not in names)
    return names + list(metrics)


def as_frame(rows: dict[str, dict], plan: Plan):
    """The rows as a DataFrame in the plan's order, one column per key (missing: NaN)."""
    import pandas as pd

    order = {run_id_of(job): i for i, job in enumerate(plan.jobs)}
    ordered = sorted(rows.values(), key=lambda row: order[row["run_id"]])
    return pd.DataFrame(ordered, columns=_columns(ordered, plan))


def write_table(folder: Path, rows: dict[str, dict], plan: Plan) -> None:
    """Write metrics.parquet atomically (pyarrow; the schema metadata tags it as ours)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    frame = as_frame(rows, plan)
    table = pa.Table.from_pandas(frame, preserve_index=False)
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), b"emasim": TABLE_TAG})
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    write_file(
        folder / METRICS_FILE,
        buffer.getvalue(),
        force=True,
        is_ours=_is_study_table,
        what="--out",
    )


def _is_study_table(path: Path) -> bool:
    import pyarrow.parquet as pq

    try:
        return (pq.read_schema(path).metadata or {}).get(b"emasim") == TABLE_TAG
    except (OSError, ValueError, TypeError):
        return False


def read_table(folder: str | Path):
    """A study's metrics.parquet as a pandas DataFrame."""
    import pandas as pd

    return pd.read_parquet(Path(folder) / METRICS_FILE)


def complete_tables(folders: dict, rows: int) -> dict | None:
    """key -> the table (:func:`read_table`) of each study folder of ``folders`` (key ->
    folder), or None when any is missing, unreadable or not yet ``rows`` rows long."""
    tables = {}
    for key, folder in folders.items():
        try:
            table = read_table(folder)
        except (OSError, ValueError):
            return None
        if len(table) != rows:
            return None
        tables[key] = table
    return tables


QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def distribution(values) -> dict:
    """runs (finite values), mean, std, min, the 5/25/50/75/95 % quantiles and max."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"runs": 0}
    q = np.quantile(x, QUANTILES)
    return {
        "runs": int(x.size),
        "mean": float(x.mean()),
        "std": float(x.std(ddof=1)) if x.size > 1 else 0.0,
        "min": float(x.min()),
        **{f"p{round(100 * p):02d}": float(v) for p, v in zip(QUANTILES, q, strict=True)},
        "max": float(x.max()),
    }


def metric_columns(table, plan: Plan) -> list[str]:
    """The metric columns of a study table (numeric, not a key nor a variation)."""
    fixed = {*ROW_KEYS, *(v.name for v in plan.variations)}
    return [c for c in table.columns if c not in fixed and table[c].dtype.kind in "fiu"]


def summarize(table, plan: Plan) -> dict:
    """label -> metric -> distribution over that controller set's runs."""
    return {
        label: {metric: distribution(group[metric]) for metric in metric_columns(table, plan)}
        for label, group in ((lb, table[table["label"] == lb]) for lb in plan.labels)
    }


MAX_GROUPS = 12  # a varied key with more values than this (a continuous draw) is not grouped


def grouping_keys(table, plan: Plan) -> list[str]:
    """The varied keys a summary is grouped by: each whose column takes 2 to MAX_GROUPS
    values over the runs (a grid, a discrete draw), but the scenario seed (--seeds: its
    values are replicates, not a setting)."""
    names = [v.name for v in plan.variations if v.keys != ("seed",)]
    return [n for n in names if 1 < table[n].nunique(dropna=True) <= MAX_GROUPS]


def summarize_by(table, plan: Plan, key: str) -> dict:
    """value of ``key`` -> label -> metric -> distribution over the runs at that value (the
    other varied keys pooled), the values ascending."""
    return {value: summarize(group, plan) for value, group in table.groupby(key, sort=True)}


def status_counts(table) -> dict[str, int]:
    """How many runs of a study table are ok, diverged and failed."""
    kinds = [str(s).split(":", 1)[0] for s in table["status"]] if len(table) else []
    return {kind: kinds.count(kind) for kind in (OK, DIVERGED, FAILED)}


def first_reasons(table, n: int = 3) -> list[str]:
    """``run_id status`` of the first ``n`` runs that are not ok, in the study's order."""
    bad = table[table["status"] != OK] if len(table) else table
    return [f"{row.run_id} {row.status}" for row in bad.head(n).itertuples()]


def summary_markdown(
    summary: dict, plan: Plan, diverged: dict[str, int], failed: dict[str, int] | None = None
) -> str:
    """The summary as Markdown: one table per metric, a row per controller set."""
    from ..analysis.tables import markdown_table

    spec = plan.spec
    lines = [
        f"# Study of {spec.scenario}",
        "",
        f"{len(plan.jobs) // len(plan.labels)} samples x {len(plan.labels)} controller sets; "
        f"varied: {', '.join(spec.vary) or 'nothing'}"
        + (f"; --seeds {spec.seeds}" if spec.seeds > 1 else "")
        + f"; draws seeded {spec.seed}.",
        "",
    ]
    for label, count in diverged.items():
        if count:
            lines += [f"**{label}: {count} runs diverged** (status in metrics.parquet).", ""]
    for label, count in (failed or {}).items():
        if count:
            lines += [f"**{label}: {count} runs failed** (status in metrics.parquet).", ""]
    header = ["controller set", "runs", "median", "5 %", "95 %", "mean", "std"]
    metrics = list(dict.fromkeys(m for per in summary.values() for m in per))
    for metric in metrics:
        rows = []
        for label, per in summary.items():
            d = per.get(metric, {"runs": 0})
            cells = [d.get(k) for k in ("p50", "p05", "p95", "mean", "std")]
            rows.append([label, d["runs"], *cells])
        lines += [f"## {metric}", "", markdown_table(header, rows), ""]
    return "\n".join(lines)


def write_summary(folder: Path, study: Study) -> Path:
    """Write ``summary/`` (replacing the one emasim wrote before): Markdown, JSON, figure."""
    from ..analysis.plots import plot_study, save_figure

    summary = study.summary()
    table = study.table
    counts = {label: status_counts(table[table["label"] == label]) for label in study.plan.labels}
    diverged = {label: count[DIVERGED] for label, count in counts.items()}
    failed = {label: count[FAILED] for label, count in counts.items()}

    def write(tmp: Path) -> None:
        record = {"diverged": diverged, "failed": failed, "metrics": summary}
        write_new(tmp / "summary.json", json_text(record))
        write_new(tmp / "summary.md", summary_markdown(summary, study.plan, diverged, failed))
        metrics = metric_columns(table, study.plan)
        grids = [v.name for v in study.plan.variations if v.grid is not None]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # all-NaN columns of diverged runs
            figure = plot_study(table, metrics, study.plan.labels, grids[0] if grids else None)
        save_figure(figure, tmp / "distributions.png")

    return write_folder(folder / SUMMARY_FOLDER, write, force=True, kind="summary")
