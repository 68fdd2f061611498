"""Compare two controller sets under growing backlash: a study over the gap width, PI against
RBF+SMC on the position-step experiment, every set on every gap, on two worker processes.

    python examples/compare_under_backlash.py [FIGURE_FOLDER]

It prints the steady-state error of each set at each gap and draws it against the gap into
FIGURE_FOLDER/backlash-error.png (default: the current folder).
"""

import sys
from pathlib import Path

from matplotlib.figure import Figure  # files only: no window, no pyplot

from emasim.experiments.study import StudySpec, run_study


def main() -> None:
    study = run_study(
        StudySpec(
            "position-step",
            vary=("plant.backlash.width_mm=0.05,0.2,0.4",),
            labels=("PI", "RBF+SMC"),
            settings=("duration_s=2.5",),  # the step and its settling, before the load step
        ),
        "studies/backlash",
        workers=2,
    )
    table = study.table.pivot(
        index="plant.backlash.width_mm", columns="label", values="steady_error_rms_mm"
    )
    print("steady-state error (RMS, mm) against the backlash width (mm):")
    print(table.to_string())

    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.subplots()
    for label in table.columns:
        ax.plot(table.index, table[label], "o-", label=label)
    ax.set_xlabel("backlash width (mm)")
    ax.set_ylabel("steady-state error, RMS (mm)")
    ax.set_title("Position step: steady-state error against backlash")
    ax.set_yscale("log")  # from a tenth of a micrometre to a tenth of a millimetre
    ax.set_xticks(table.index)
    ax.grid(True, alpha=0.3)
    ax.legend(title="controller set")
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    folder.mkdir(parents=True, exist_ok=True)
    fig.savefig(folder / "backlash-error.png", dpi=120)


if __name__ == "__main__":  # the worker processes import this file
    main()
