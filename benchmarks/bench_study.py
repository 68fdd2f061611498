"""Speed of the study facility (emasim.experiments.study) on Dask distributed.

    python benchmarks/bench_study.py [--quick]

Throughput: a metrics-only Monte Carlo of SCALING_PLANTS plants of bench-step, PID and the
hybrid on each (SCALING_RUNS runs at the scenario's own duration; the bench's whole plant
uncertainty drawn per plant, emasim.experiments.robustness: the robustness study's shape)
through ``run_study`` on a LocalCluster of one worker process and on one of two, each started
(and its compiled code loaded) before timing and closed after, so that only one cluster is
alive at a time; repeated REPEATS times, interleaved, each into a fresh folder; the median wall
time of each. Throughput = simulated seconds of all runs / wall seconds; speed-up = 2 workers /
1 worker; PROJECTED_PLANTS plants take their runs' simulated seconds over the 2-worker
throughput (:func:`projected_s`). Each study is timed twice: to its last run's end
(``progress`` told every run is done: the runs, which the workers share) and to its return
(with the summary's table and figure, which the client draws alone after the runs, the same
on any number of workers).
Monte Carlo: the wall time of the robustness study of bench-step (MC_RUNS runs) for each
controller set alone, on a LocalCluster of two workers, cluster start included: what
``emasim reproduce --robustness`` spends on each.

``bench_engine.py`` calls :func:`study_scaling` and :func:`monte_carlo_seconds` for its
results (and docs/speed.md's table); run alone, this prints them. ``--quick`` (what CI
runs): QUICK_PLANTS plants of QUICK_S, one repeat, and a QUICK_MC_RUNS-run Monte Carlo.
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from emasim.experiments.batch import dask_client
from emasim.experiments.robustness import UNCERTAINTY
from emasim.experiments.study import StudySpec, plan_study, run_study

SCENARIO, LABELS = "bench-step", ("PID", "hybrid")
SCALING_PLANTS, REPEATS = 32, 3
SCALING_RUNS = SCALING_PLANTS * len(LABELS)
QUICK_PLANTS, QUICK_S = 2, 0.1
QUICK_RUNS = QUICK_PLANTS * len(LABELS)
MC_RUNS, QUICK_MC_RUNS = 200, 2
PROJECTED_PLANTS = 10_000  # what a robustness or sensitivity analysis of a real design needs


def scaling_spec(
    plants: int, duration_s: float | None = None, labels: tuple[str, ...] = LABELS
) -> StudySpec:
    """The Monte Carlo of the throughput figures: ``plants`` plants of the bench's
    uncertainty, each run with every controller set of ``labels`` (metrics only: no traces),
    each run ``duration_s`` long (None: the scenario's own duration)."""
    settings = (f"duration_s={duration_s}",) if duration_s is not None else ()
    return StudySpec(SCENARIO, vary=UNCERTAINTY, runs=plants, labels=labels, settings=settings)


def projected_s(figures: dict, plants: int = PROJECTED_PLANTS) -> float:
    """Seconds that ``plants`` plants of the throughput's Monte Carlo take on 2 workers: their
    runs' simulated seconds over the measured 2-worker throughput."""
    sets = len(figures.get("labels", LABELS))
    return plants * sets * figures["duration_s"] / figures["two_workers_sim_s_per_s"]


def _timed_phases(spec: StudySpec, folder: Path, **where) -> tuple[float, float]:
    """(seconds to the last run's end, seconds to run_study's return) of one study."""
    runs_done = [float("nan")]

    def progress(done: int, total: int) -> None:
        if done == total:
            runs_done[0] = time.perf_counter()

    start = time.perf_counter()
    run_study(spec, folder, progress=progress, **where)
    return runs_done[0] - start, time.perf_counter() - start


def study_scaling(plants: int, duration_s: float | None, repeats: int) -> dict:
    """Median wall time of the same study on 1 and on 2 worker processes (module docstring).
    One cluster is alive at a time: an idle one's heartbeats would take CPU from the other."""
    spec = scaling_spec(plants, duration_s)
    warm = StudySpec(SCENARIO, vary=("seed=1,2",), labels=spec.labels, settings=spec.settings)
    times, runs_times = {1: [], 2: []}, {1: [], 2: []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(repeats):
            for workers in (1, 2):
                with dask_client(workers=workers) as client:
                    _timed_phases(warm, Path(tmp) / f"warm-{workers}-{k}", client=client)
                    folder = Path(tmp) / f"run-{workers}-{k}"
                    runs_s, study_s = _timed_phases(spec, folder, client=client)
                runs_times[workers].append(runs_s)
                times[workers].append(study_s)
    one_s, two_s = statistics.median(times[1]), statistics.median(times[2])
    one_runs_s, two_runs_s = statistics.median(runs_times[1]), statistics.median(runs_times[2])
    jobs = plan_study(spec).jobs
    run_s = jobs[0].scenario.duration_s
    simulated = len(jobs) * run_s
    return {
        "scenario": SCENARIO,
        "plants": plants,
        "labels": list(spec.labels),
        "runs": len(jobs),
        "duration_s": run_s,
        "repeats": repeats,
        "one_worker_s": one_s,
        "two_workers_s": two_s,
        "one_worker_sim_s_per_s": simulated / one_s,
        "two_workers_sim_s_per_s": simulated / two_s,
        "speedup": one_s / two_s,
        "one_worker_runs_s": one_runs_s,
        "two_workers_runs_s": two_runs_s,
        "runs_speedup": one_runs_s / two_runs_s,
    }


def monte_carlo_seconds(runs: int) -> dict:
    """Wall time of the bench-step robustness Monte Carlo of each controller set alone."""
    out = {"scenario": SCENARIO, "runs": runs, "workers": 2}
    with tempfile.TemporaryDirectory() as tmp:
        for label in LABELS:
            spec = StudySpec(SCENARIO, vary=UNCERTAINTY, runs=runs, labels=(label,))
            out[f"{label}_s"] = _timed_phases(spec, Path(tmp) / label, workers=2)[1]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few seconds (module docstring)")
    args = parser.parse_args()
    if args.quick:
        scaling, mc = study_scaling(QUICK_PLANTS, QUICK_S, 1), monte_carlo_seconds(QUICK_MC_RUNS)
    else:
        scaling, mc = study_scaling(SCALING_PLANTS, None, REPEATS), monte_carlo_seconds(MC_RUNS)
    report(scaling, mc)


def report(scaling: dict, mc: dict) -> None:
    print(
        f"study of {scaling['runs']} x {scaling['duration_s']:g} s of {scaling['scenario']} "
        f"({', '.join(scaling.get('labels', LABELS))}): "
        f"1 worker {scaling['one_worker_s']:.2f} s ({scaling['one_worker_sim_s_per_s']:.2f} "
        f"sim s/s), 2 workers {scaling['two_workers_s']:.2f} s "
        f"({scaling['two_workers_sim_s_per_s']:.2f} sim s/s), speed-up {scaling['speedup']:.2f}; "
        f"the runs alone: {scaling['one_worker_runs_s']:.2f} s against "
        f"{scaling['two_workers_runs_s']:.2f} s, speed-up {scaling['runs_speedup']:.2f}"
    )
    print(
        f"{PROJECTED_PLANTS:,} plants of it, every set on each, on 2 workers: "
        f"{projected_s(scaling) / 3600:.2f} h projected (the goal: 0.5 h)"
    )
    for label in LABELS if mc is not None else ():
        print(
            f"{mc['runs']}-run {mc['scenario']} Monte Carlo, {label}, 2 workers: "
            f"{mc[f'{label}_s']:.1f} s"
        )


if __name__ == "__main__":
    main()
