"""The paper's experiments, run: every shipped paper scenario's comparison, the hinge
clearance sweep, the ablation of the bench's elements, the hybrid part by part
(emasim.experiments.components), the abstract's claims over paired replicas
(emasim.experiments.replicas) and the step test's length (emasim.experiments.run_length);
with ``robustness_runs``, the Monte Carlo, the wear study and the verdict map
(emasim.experiments.verdict_map) too, else their latest studies; rendered by
:mod:`emasim.analysis.paper_report` into one report folder."""

import math
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

from ..analysis.judged import HYBRID_LABEL, PID_LABEL
from ..analysis.paper_report import (
    EXPERIMENTS,
    SWEEP_CLEARANCES_MM,
    ablation_rows,
    build_tables,
    fronts_of,
    notes,
    write_report,
)
from ..config import hard_limits
from ..errors import InputError
from ..naming import RUNS_ROOT, fresh_folder, slug
from ..output import check_target, write_folder, write_new
from ..scenarios.loader import load_scenario
from . import replicas, verdict_map, wear
from .ablation import STAGES, ablation_jobs, ablation_table
from .batch import Job, comparison_of
from .components import component_jobs, component_tables
from .robustness import DEFAULT_SEED, UNCERTAINTY, latest, run_robustness
from .robustness import SCENARIOS as ROBUST
from .run_length import run_length
from .store import METRICS_FILE, RUN_ID, Store, keyed, run_id_of
from .uncertainty import markdown as uncertainty_table

ABLATED = ("bench-step", "bench-sine")  # the experiments the ablation re-runs stage by stage
LABELS = (PID_LABEL, HYBRID_LABEL)  # the sets the ablation compares
STORE_ROOT = RUNS_ROOT / "reproduce"  # beside the reports: each job list's store
RUNS_TABLE = "runs.parquet"  # in the report: the store's table, one row per run


def sweep_jobs() -> list[Job]:
    """The hinge clearance sweep's runs (tag ``clearance_mm``): cosim-step at every hinge
    clearance of SWEEP_CLEARANCES_MM, the whole run long (its limit cycle starts about 2 s
    in), for every controller set."""
    runs = []
    for clearance in SWEEP_CLEARANCES_MM:
        scenario = load_scenario(
            "cosim-step",
            settings=[f"plant.linkage.hinge_clearance_mm=[{', '.join([str(clearance)] * 4)}]"],
        )
        runs += [
            Job(variant, label, {"clearance_mm": clearance})
            for label, variant in scenario.variants()
        ]
    return runs


def sweep_rows(jobs: list[Job], metrics: list[dict]) -> list[dict]:
    """The sweep's table from the ``metrics`` of each of :func:`sweep_jobs`' ``jobs``: steady
    RMS error and vibration amplitude of the rudder, per clearance and controller set."""
    return [
        {
            "clearance_mm": job.tags["clearance_mm"],
            "controller": job.label,
            "steady_error_rms_deg": values["steady_error_rms_deg"],
            "chatter_amplitude_deg": values["chatter_amplitude_deg"],
        }
        for job, values in zip(jobs, metrics, strict=True)
    ]


def _ablated(chosen: dict, with_ablation: bool) -> dict:
    """The chosen experiments the ablation re-runs stage by stage."""
    return {n: chosen[n] for n in ABLATED if n in chosen} if with_ablation else {}


def job_groups(chosen: dict, with_ablation: bool) -> dict[str, list[Job]]:
    """The reproduction's runs by group: each ``chosen`` experiment's controller sets (their
    traces kept, for the figures and the report's run folders), the clearance sweep (when
    cosim-step is among them), the ablation of the bench ones and the hybrid part by part;
    each job's run id names its group, tags and label."""
    ablated = _ablated(chosen, with_ablation)
    groups = {
        "comparisons": [
            Job(variant, label, {"experiment": name}, trace=True)
            for name, sc in chosen.items()
            for label, variant in sc.variants()
        ],
        "sweep": sweep_jobs() if "cosim-step" in chosen else [],
        "ablation": ablation_jobs(ablated, ablated, labels=LABELS),
        "components": component_jobs(chosen),
    }
    return {
        group: [
            replace(
                job,
                tags={
                    RUN_ID: slug("-".join([group, *map(str, job.tags.values()), job.label])),
                    **job.tags,
                },
            )
            for job in jobs
        ]
        for group, jobs in groups.items()
    }


def job_store(chosen: dict, with_ablation: bool) -> tuple[Store, dict[str, list[Job]]]:
    """The reproduction's job store and its runs by group (:func:`job_groups`): under
    ``runs/reproduce/``, named by what it holds (emasim.experiments.store.keyed), so a
    reproduction killed part way resumes from its finished runs when run again."""
    groups = job_groups(chosen, with_ablation)
    jobs = [job for group in groups.values() for job in group]
    record = {"reproduce": {"experiments": list(chosen), "ablation": with_ablation}}
    return keyed(STORE_ROOT, jobs, record), groups


def _run_experiments(chosen: dict, with_ablation: bool, progress) -> tuple[dict, dict, Store]:
    """({name: Comparison}, the report's tables, the job store they were read from) of the
    ``chosen`` experiments (:func:`job_groups`).

    Every run goes into one job list (the store runs the longest first), so both cores stay
    busy to the end instead of waiting at the end of each experiment for its last run. Each
    comparison's ``simulation_wall_s`` is therefore the whole list's wall time. A run that
    did not end ok stops the reproduction, naming it (the finished runs stay in the store)."""
    store, groups = job_store(chosen, with_ablation)
    start = time.perf_counter()
    rows = store.run(progress=progress)
    wall_s = time.perf_counter() - start
    store.require_ok(rows)
    metrics = {key: [store.metrics_of(rows[run_id_of(j)]) for j in g] for key, g in groups.items()}
    by_name = {name: {} for name in chosen}
    for job in groups["comparisons"]:
        by_name[job.tags["experiment"]][job.label] = store.result(job)
    comparisons = {name: comparison_of(chosen[name], by_name[name], wall_s) for name in chosen}
    tables = build_tables({name: c.metrics for name, c in comparisons.items()})
    if groups["sweep"]:
        tables["clearance_sweep"] = sweep_rows(groups["sweep"], metrics["sweep"])
    if groups["components"]:
        tables["components"] = component_tables(
            groups["components"],
            metrics["components"],
            {name: c.metrics for name, c in comparisons.items()},
        )
    ablated = _ablated(chosen, with_ablation)
    if ablated:
        known = {name: comparisons[name].metrics for name in ablated}
        stages = ablation_table(ablated, groups["ablation"], metrics["ablation"], known, LABELS)
        tables["ablation"] = ablation_rows(stages)
    return comparisons, tables, store


def _hand_figures(comparisons: dict, tables: dict, folder: Path, drawer) -> tuple[dict, list]:
    """Hand each experiment's figure (the heavy ones) to ``drawer`` (a FigureProcess, see
    emasim.analysis.figure_process); return ({section: [(title, path in the report
    folder)]}, [(draw, path)] of the light ones: the Pareto fronts, wear and the clearance
    sweep and the verdict map, for this process to draw once it has written the rest)."""
    from ..analysis.plots import (
        plot_bench,
        plot_clearance_sweep,
        plot_comparison,
        plot_pareto,
        plot_verdict_map,
        plot_wear,
    )

    figures, later = {}, []
    for name, comparison in comparisons.items():
        first = next(iter(comparison.results.values())).description.experiment
        plot = plot_bench if first.quantity == "rudder" else plot_comparison
        path = f"figures/{name}.png"
        drawer.save(partial(plot, comparison.results, name), folder / path)
        figures[name] = [(name, path)]
        fronts = fronts_of(comparison.scenario.get("tuning"))
        if len(fronts) > 1:
            path = f"figures/{name}-pareto.png"
            later.append((partial(plot_pareto, fronts), folder / path))
            figures[name].append(("tracking against chattering", path))
    if "wear" in tables:
        later.append((partial(plot_wear, tables["wear"]), folder / "figures/wear.png"))
        figures["wear"] = [("wear", "figures/wear.png")]
    if "verdict_map" in tables:
        path = "figures/verdict-map.png"
        later.append((partial(plot_verdict_map, tables["verdict_map"]), folder / path))
        figures["verdict_map"] = [("where each verdict flips", path)]
    if "clearance_sweep" in tables:
        path = "figures/clearance-sweep.png"
        later.append((partial(plot_clearance_sweep, tables["clearance_sweep"]), folder / path))
        figures["cosim-step"].append(("clearance sweep", path))
    return figures, later


def check_robustness(only: list[str] | None) -> None:
    """Refuse ``--robustness`` with an ``--only`` that leaves out a bench experiment: its Monte
    Carlo and wear study weigh the headline verdicts, which take both (robustness.SCENARIOS)."""
    missing = [name for name in ROBUST if only and name not in only]
    if missing:
        raise InputError(
            f"--robustness: the Monte Carlo of the headline verdicts runs both bench "
            f"experiments ({', '.join(ROBUST)}); --only leaves out {', '.join(missing)} "
            f"(add --only {' --only '.join(missing)}, or leave --robustness out)"
        )


def bounds_at_limit(scenario) -> dict[str, dict[str, str]]:
    """label -> {knob: why} for each tuned set of ``scenario`` whose optimum its ``[tuning]``
    record leaves on a bound that is the law's own limit (the config's validation,
    :func:`hard_limits`): such a bound cannot widen, and the field's description says why it
    is there (a design rule of the law, such as the super-twisting's 0 < mu < 1)."""
    sets = scenario.tuning.get("sets", {})
    out: dict[str, dict[str, str]] = {}
    for label, variant in scenario.variants():
        if label not in sets:
            continue
        record = sets[label]
        for key, side in record.on_bound.items():
            loop, field = key.split(".", 1)
            config = getattr(variant.controllers, loop)
            span = record.widened.get(key) or config.tunable_ranges()[field]
            end = 0 if side == "lower" else 1
            if math.isclose(span[end], hard_limits(config, field)[end], rel_tol=1e-9):
                why = type(config).model_fields[field].description
                out.setdefault(label, {})[key] = why
    return out


def _counted(progress):
    """A ``progress(done, total)`` for a progress that takes a fraction (or None)."""
    return None if progress is None else (lambda done, total: progress(done / total))


def check_replicas(only: list[str] | None) -> None:
    """Refuse ``--replicas`` with an ``--only`` that leaves out a bench experiment: the claims
    it decides are the headline's, which takes both (replicas.SCENARIOS)."""
    missing = [name for name in replicas.SCENARIOS if only and name not in only]
    if missing:
        raise InputError(
            f"--replicas: the abstract's claims are decided on both bench experiments "
            f"({', '.join(replicas.SCENARIOS)}); --only leaves out {', '.join(missing)} "
            f"(add --only {' --only '.join(missing)}, or leave --replicas out)"
        )


def reproduce(
    out: str | Path | None = None,
    only: list[str] | None = None,
    progress=None,
    force: bool = False,
    with_ablation: bool = True,
    robustness_runs: int | None = None,
    robustness_seed: int = DEFAULT_SEED,
    replica_count: int = replicas.DEFAULT_REPLICAS,
) -> Path:
    """Run the paper's experiments (or ``only`` those) and write the report folder; with
    ``with_ablation``, also the ablation of the bench's elements (emasim.experiments.ablation)
    for the bench experiments among them. ``robustness_runs``: run (or resume) the Monte Carlo
    of emasim.experiments.robustness with that many runs per controller set, the wear study
    (emasim.experiments.wear) and the verdict map (emasim.experiments.verdict_map): refused
    unless both bench experiments are chosen (:func:`check_robustness`); without it, the
    report shows the latest complete ones of these experiments and version, if any (the
    largest Monte Carlo of that seed). ``robustness_seed``: the seed of the Monte Carlo's
    draws (each seed its own study, run or shown). ``replica_count``: the replicas over which
    the abstract's claims are decided (emasim.experiments.replicas) and the step test's
    length is checked (emasim.experiments.run_length), run or resumed with the headline; 0
    shows the latest complete replica study's claims instead, if any.

    Without ``out``, a fresh ``runs/reproduce/all-<time>`` (or ``only-<names>-<time>``);
    ``force`` replaces an earlier report at ``out`` (never anything emasim did not write).
    The folder appears complete or not at all. Every run goes through the reproduction's job
    store (:func:`job_store`), whose tidy table the report copies as ``runs.parquet``: an
    interrupted reproduction, run again, runs only what its store has not finished.
    """
    from ..analysis.figure_process import DrawHere, figure_writer

    if robustness_runs is not None:
        check_robustness(only)
    if out is not None:
        check_target(Path(out), force)

    chosen = {
        e.scenario: load_scenario(e.scenario) for e in EXPERIMENTS if not only or e.scenario in only
    }
    comparisons, tables, store = _run_experiments(chosen, with_ablation, _counted(progress))
    if "headline" in tables:
        if replica_count:
            tables["claims"] = replicas.run_replicas(replica_count, progress=_counted(progress))
            tables["run_length"] = run_length(replica_count, progress=_counted(progress))
        else:
            tables["claims"] = replicas.latest()
        if robustness_runs is not None:
            tables["robustness"] = run_robustness(
                robustness_runs, progress=_counted(progress), seed=robustness_seed
            )
            tables["wear"] = wear.run_wear()
            tables["verdict_map"] = verdict_map.run_verdict_map(progress=_counted(progress))
        else:
            tables["robustness"], tables["wear"] = latest(seed=robustness_seed), wear.latest()
            tables["verdict_map"] = verdict_map.latest()
        for key in ("claims", "run_length", "robustness", "wear", "verdict_map"):
            if not tables.get(key, True):
                del tables[key]

    def write(folder: Path) -> None:
        (folder / "figures").mkdir()
        (folder / "runs").mkdir()
        write_new(folder / RUNS_TABLE, (store.folder / METRICS_FILE).read_bytes())
        # the figure process draws the heavy figures while this one writes the runs and the
        # text, then draws the light ones
        with figure_writer() as drawer:
            figures, later = _hand_figures(comparisons, tables, folder, drawer)
            for name, comparison in comparisons.items():
                run_folder = folder / "runs" / name
                run_folder.mkdir()
                comparison.write_files(run_folder, plot=False)
            write_report(
                folder,
                tables,
                {n: c.scenario for n, c in comparisons.items()},
                figures,
                notes(),
                stages=STAGES,
                uncertainty=uncertainty_table(UNCERTAINTY),
                at_limit={name: bounds_at_limit(sc) for name, sc in chosen.items()},
            )
            here = DrawHere()
            for draw, path in later:
                here.save(draw, path)
            drawer.wait()

    if out is None:
        what = "only-" + "-".join(only) if only else "all"
        return write_folder(
            fresh_folder(RUNS_ROOT / "reproduce", what), write, unique=True, kind="report"
        )
    return write_folder(Path(out), write, force=force, kind="report")
