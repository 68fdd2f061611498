"""The paper's experiments, run: every shipped paper scenario's comparison, the hinge
clearance sweep and the ablation of the bench's elements, rendered by
:mod:`emasim.analysis.paper_report` into one report folder."""

from pathlib import Path

from ..analysis.paper_report import (
    EXPERIMENTS,
    HYBRID_LABEL,
    PID_LABEL,
    SWEEP_CLEARANCES_MM,
    ablation_rows,
    build_tables,
    fronts_of,
    notes,
    write_report,
)
from ..output import RUNS_ROOT, check_folder, fresh_folder, write_folder
from ..scenarios.loader import load_scenario
from . import wear
from .ablation import STAGES, ablation
from .batch import run_all, run_comparison
from .robustness import UNCERTAINTY, latest, run_robustness

ABLATED = ("bench-step", "bench-sine")  # the experiments the ablation re-runs stage by stage


def clearance_sweep() -> list[dict]:
    """cosim-step at every hinge clearance of SWEEP_CLEARANCES_MM, the whole run long (its
    limit cycle starts about 2 s in): steady RMS error and vibration amplitude of the rudder,
    per controller set; every run of the sweep at once (run_all)."""
    runs = []
    for clearance in SWEEP_CLEARANCES_MM:
        scenario = load_scenario(
            "cosim-step",
            settings=[f"plant.linkage.hinge_clearance_mm=[{', '.join([str(clearance)] * 4)}]"],
        )
        runs += [(clearance, label, variant) for label, variant in scenario.variants()]
    results = run_all([run[2] for run in runs], labels=[run[1] for run in runs])
    return [
        {
            "clearance_mm": clearance,
            "controller": label,
            "steady_error_rms_deg": result.metrics["steady_error_rms_deg"],
            "chatter_amplitude_deg": result.metrics["chatter_amplitude_deg"],
        }
        for (clearance, label, _), result in zip(runs, results, strict=True)
    ]


def _counted(progress):
    """A ``progress(done, total)`` for a progress that takes a fraction (or None)."""
    return None if progress is None else (lambda done, total: progress(done / total))


def reproduce(
    out: str | Path | None = None,
    only: list[str] | None = None,
    progress=None,
    force: bool = False,
    with_ablation: bool = True,
    robustness_runs: int | None = None,
) -> Path:
    """Run the paper's experiments (or ``only`` those) and write the report folder; with
    ``with_ablation``, also the ablation of the bench's elements (emasim.experiments.ablation)
    for the bench experiments among them. ``robustness_runs``: run (or resume) the Monte Carlo
    of emasim.experiments.robustness with that many runs per controller set, and the wear
    study (emasim.experiments.wear); without it, the report shows the largest complete ones of
    these experiments and version, if any.

    Without ``out``, a fresh ``runs/reproduce/all-<time>`` (or ``only-<names>-<time>``);
    ``force`` replaces an earlier report at ``out`` (never anything emasim did not write).
    The folder appears complete or not at all, so an interrupted reproduction is simply rerun.
    """
    from ..analysis.plots import (
        plot_bench,
        plot_clearance_sweep,
        plot_comparison,
        plot_pareto,
        plot_wear,
        save_figure,
    )

    if out is not None:
        check_folder(Path(out), force)

    chosen = [e for e in EXPERIMENTS if not only or e.scenario in only]
    comparisons = {}
    for i, exp in enumerate(chosen):
        comparisons[exp.scenario] = run_comparison(load_scenario(exp.scenario))
        if progress is not None:
            progress((i + 1) / len(chosen))
    metrics = {name: c.metrics for name, c in comparisons.items()}
    tables = build_tables(metrics)
    if "cosim-step" in comparisons:
        tables["clearance_sweep"] = clearance_sweep()
    ablated = {name: comparisons[name] for name in ABLATED if name in comparisons}
    if with_ablation and ablated:
        known = {name: c.metrics for name, c in ablated.items()}
        scenarios = {name: load_scenario(name) for name in ablated}
        runs = ablation(scenarios, known, labels=(PID_LABEL, HYBRID_LABEL))
        tables["ablation"] = ablation_rows(runs)

    if "headline" in tables:
        if robustness_runs is not None:
            tables["robustness"] = run_robustness(robustness_runs, progress=_counted(progress))
            tables["wear"] = wear.run_wear()
        else:
            tables["robustness"], tables["wear"] = latest(), wear.latest()
        for key in ("robustness", "wear"):
            if not tables[key]:
                del tables[key]

    def write(folder: Path) -> None:
        (folder / "figures").mkdir()
        (folder / "runs").mkdir()
        figures = {}
        for name, comparison in comparisons.items():
            run_folder = folder / "runs" / name
            run_folder.mkdir()
            comparison.write_files(run_folder, plot=False)
            if name.startswith("bench") or name == "cosim-step":
                fig = plot_bench(comparison.results, name)
            else:
                fig = plot_comparison(comparison.results, name)
            path = f"figures/{name}.png"
            save_figure(fig, folder / path)
            figures[name] = [(name, path)]
            fronts = fronts_of(comparison.scenario.get("tuning"))
            if len(fronts) > 1:
                path = f"figures/{name}-pareto.png"
                save_figure(plot_pareto(fronts), folder / path)
                figures[name].append(("tracking against chattering", path))
        if "wear" in tables:
            save_figure(plot_wear(tables["wear"]), folder / "figures/wear.png")
            figures["wear"] = [("wear", "figures/wear.png")]
        if "clearance_sweep" in tables:
            path = "figures/clearance-sweep.png"
            save_figure(plot_clearance_sweep(tables["clearance_sweep"]), folder / path)
            figures["cosim-step"].append(("clearance sweep", path))
        write_report(
            folder,
            tables,
            {n: c.scenario for n, c in comparisons.items()},
            figures,
            notes(),
            stages=STAGES,
            uncertainty=UNCERTAINTY,
        )

    if out is None:
        what = "only-" + "-".join(only) if only else "all"
        return write_folder(
            fresh_folder(RUNS_ROOT / "reproduce", what), write, unique=True, kind="report"
        )
    return write_folder(Path(out), write, force=force, kind="report")
