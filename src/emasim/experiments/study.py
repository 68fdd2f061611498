"""Studies: grids and Monte Carlo over any scenario key, run on Dask distributed.

A study takes a scenario, the keys it varies (:mod:`.variation`), ``runs`` Monte Carlo runs
of each grid point and the controller sets of the scenario's comparison (all, or the chosen
``labels``). Every sample runs with every controller set, so the sets are compared on the same
plants (paired). Its runs are a job list on the job store (:mod:`.store`: the run folders,
``metrics.parquet``, ``workers.log``, resumed by the same command); its folder holds besides

* ``study.json``: what the study is (scenario, variations, runs, seed, labels, settings, the
  emasim version, the digest of its source and a hash of every run's fully resolved
  scenario: another code's study is never resumed);
* in ``metrics.parquet``, the columns ``run_id``, ``label``, ``sample``, ``status``, then each
  variation's value (the factor for a '*' variation), then every metric;
* ``summary/``: ``summary.md`` and ``summary.json`` (each metric's distribution for each
  controller set) and ``distributions.png``, written when the study is complete.

Every run's scenario rules (an FMU's trust, the co-simulation's) and the scheduler are checked
before the folder is made; a folder that holds another study is refused.
"""

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..jsonio import json_text
from ..naming import slug
from ..output import write_folder, write_new
from ..scenarios.loader import apply_setting, read_scenario_file, set_key, validate_scenario
from .batch import Job
from .store import (
    DIVERGED,
    FAILED,
    FAILURE_LOG,
    LOG_FILE,
    RUN_ID,
    Store,
    digest,
    read_table,
    status_counts,
)
from .variation import Variation, parse_variation, samples

STUDY_FILE = "study.json"
SUMMARY_FOLDER = "summary"


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


SAMPLE = "sample"  # a study job's tag, beside its run id (``<label>-<sample>``) and values


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
        from .runs import source_digest

        return {
            "study": self.spec.record(),
            "labels": self.labels,
            "samples": len(self.jobs) // max(len(self.labels), 1),
            "emasim_version": __version__,
            "emasim_source_sha256": source_digest(),
            "scenarios_sha256": self.digest,
        }

    @property
    def fixed_columns(self) -> tuple[str, ...]:
        """The table's columns before the metrics: the run's keys and the varied values."""
        return (RUN_ID, "label", SAMPLE, "status", *(v.name for v in self.variations))

    def store(self, folder: Path) -> Store:
        """The job store of the study's runs in ``folder``."""
        return Store(
            folder,
            self.jobs,
            self.record(),
            record_file=STUDY_FILE,
            columns=self.fixed_columns,
            name=f"--out {folder}",
            refusal="holds another study (its scenario, --vary, --runs, --seeds, --label, "
            "--set, or the emasim version or source differ); a study is never replaced: the "
            "same command of the same emasim resumes it, choose another --out for this one",
        )


def plan_study(spec: StudySpec) -> Plan:
    """Every run of ``spec``, its scenario validated; InputError names the first bad one."""
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
            tags = {RUN_ID: run_id, SAMPLE: point.index, **columns}
            jobs.append(Job(scenario, label, tags, trace=spec.traces))
    return Plan(spec, variations, labels, jobs, digest(jobs))


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
    from ..sim.cosim import check_runnable
    from .batch import check_scheduler, dask_client

    plan = plan_study(spec)
    for job in plan.jobs:  # every rule a run checks, before anything is made
        check_runnable(job.scenario, trust_fmu)
    if client is None and scheduler is not None:
        check_scheduler(scheduler)
    folder = Path(out)
    store = plan.store(folder)
    log_file = (folder / LOG_FILE, FAILURE_LOG)
    rows = store.run(
        client,
        progress=progress,
        trust_fmu=trust_fmu,
        cluster=lambda: dask_client(scheduler, workers, log_file=log_file),
    )
    study = Study(folder, store.frame(rows), plan)
    if study.complete:
        write_summary(folder, study)
    return study


def run_studies(
    studies: dict[str, tuple[StudySpec, Path]],
    progress=None,
    client=None,
    scheduler=None,
) -> dict:
    """Run (or resume) each study of ``studies`` (name -> (spec, folder)) one after the other
    (:func:`run_study`) and return name -> its table. ``progress(done, total)`` counts the
    runs of all of them together (each spec names its labels: ``runs`` runs of each)."""
    totals = {name: spec.runs * len(spec.labels) for name, (spec, _) in studies.items()}
    done = dict.fromkeys(studies, 0)
    tables = {}
    for name, (spec, folder) in studies.items():

        def told(count, _, name=name):
            done[name] = count
            if progress is not None:
                progress(sum(done.values()), sum(totals.values()))

        study = run_study(spec, folder, progress=told, client=client, scheduler=scheduler)
        tables[name] = study.table
    return tables


def largest_complete(root: Path, prefix: str, rows_per_run: int) -> tuple[int, object] | None:
    """(runs, table) of the largest complete study among the folders ``<prefix>-<runs>`` under
    ``root`` (``rows_per_run`` rows a run: one per controller set), or None when there is none;
    a folder that cannot be read is passed over."""
    found = None
    for folder in root.glob(f"{prefix}-*"):
        runs = folder.name.rsplit("-", 1)[-1]
        if not runs.isdigit():
            continue
        try:
            table = read_table(folder)
        except (OSError, ValueError):
            continue
        if len(table) == rows_per_run * int(runs) and (found is None or int(runs) > found[0]):
            found = (int(runs), table)
    return found


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
    fixed = set(plan.fixed_columns)
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
