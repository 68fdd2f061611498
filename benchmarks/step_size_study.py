"""What the bench's sub-step costs and buys: the evidence for a coarser ``solver.step_s``.

    python benchmarks/step_size_study.py

The bench scenarios (bench-step, bench-sine) integrate the plant at step_s = 1e-5 s, ten RK4
sub-steps a control sample, which puts their real-time factor at about 0.07 against issue 30's
goal of 0.03. For each shipped bench scenario and each controller set it compares, this runs
the set at STEPS and prints:

- the wall time of the simulation alone (meta's simulation_wall_s, the best of REPEATS runs,
  after a warm-up) per simulated second;
- the largest difference of the true rudder angle (deg) and of the current command (A) from
  the run at the finest step, REFERENCE_STEP (RK4 is fourth-order on smooth motion, so the
  finest run stands for the exact one there; the hinges' rattle is not smooth);
- the largest relative change of any metric from the shipped step's run;
- the figures the paper's headline judges (HEADLINE), whose verdicts a step must not flip.

Nothing is written. It is a study, not a benchmark: CI does not run it. What judges a step is
the accuracy contract (docs/model.md): the plant replay (benchmarks/bench_accuracy.py) and the
figures' distributions over paired replicas (benchmarks/bench_equivalence.py).
"""

import numpy as np

from emasim.experiments.runs import run_scenario
from emasim.scenarios.loader import load_scenario

SCENARIOS = ("bench-step", "bench-sine")
HEADLINE = {  # the figures the paper's headline judges (docs/paper.md), printed at every step
    "bench-step": ("steady_error_rms_deg", "chatter_amplitude_deg", "velocity_fluctuation_deg_s"),
    "bench-sine": ("tracking_error_deg", "velocity_fluctuation_deg_s"),
}
SHIPPED_STEP = 1e-5
STEPS = (2.5e-6, 5e-6, 1e-5, 2e-5)
REFERENCE_STEP = STEPS[0]
REPEATS = 2


def run(name: str, label: str, step_s: float):
    """The best of REPEATS runs of one controller set at ``step_s``, after a warm-up."""
    scenario = load_scenario(name, label=label, settings=[f"solver.step_s={step_s:g}"])
    single = scenario.variants()[0][1]
    run_scenario(single)
    runs = [run_scenario(single) for _ in range(REPEATS)]
    return min(runs, key=lambda result: result.meta["simulation_wall_s"])


def largest_change(metrics: dict, shipped: dict) -> tuple[str, float]:
    """The metric that moves most, relatively, from the shipped step's, and by how much."""
    changes = {
        key: abs(value - shipped[key]) / max(abs(shipped[key]), 1e-12)
        for key, value in metrics.items()
        if np.isfinite(value) and np.isfinite(shipped[key])
    }
    key = max(changes, key=changes.get)
    return key, changes[key]


def main() -> None:
    for name in SCENARIOS:
        scenario = load_scenario(name)
        for label in [variant.label for variant in scenario.compare]:
            runs = {step: run(name, label, step) for step in STEPS}
            reference, shipped = runs[REFERENCE_STEP], runs[SHIPPED_STEP]
            for step, result in runs.items():
                rtf = result.meta["simulation_wall_s"] / scenario.duration_s
                angle = np.degrees(
                    np.max(np.abs(result["rudder_angle_rad"] - reference["rudder_angle_rad"]))
                )
                current = np.max(np.abs(result["iq_ref_A"] - reference["iq_ref_A"]))
                key, change = largest_change(result.metrics, shipped.metrics)
                headline = "  ".join(f"{k} {result.metrics[k]:.4g}" for k in HEADLINE[name])
                print(
                    f"{name:10s} {label:15s} step {step:7.1e} s  RTF {rtf:.4f}  "
                    f"|angle - finest| {angle:.2e} deg  |iq* - finest| {current:.2e} A  "
                    f"largest metric change {change:.1e} ({key})  {headline}"
                )


if __name__ == "__main__":
    main()
