"""Compare two controller sets under growing backlash: a study over the gap width, PI against
RBF+SMC on the position-step experiment, every set on every gap, on two worker processes.

    python examples/compare_under_backlash.py
"""

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


if __name__ == "__main__":  # the worker processes import this file
    main()
