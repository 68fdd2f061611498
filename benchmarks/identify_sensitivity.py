"""How much the actuator's closed-loop traces move under a small change of a parameter, against
a change of the sensors' noise alone: why a sample-by-sample output-error fit cannot identify
the actuator's bench (and what `emasim identify` therefore does not offer for it yet).

    python benchmarks/identify_sensitivity.py

For each experiment, the reference is a 1 Hz sine (2 deg of rudder on bench-step's PID, 5 mm
of rod on position-step with the bench's digital sensors), 2 s or 3 s; the relative change
|y' - y| / |y| of each sensor reading and of the current command is printed for: the sensors'
seed changed, and each of backlash, hinge clearance and friction (Coulomb and stiction)
raised by 5 % and by 0.5 %. A cost is usable for output error where a parameter's change
moves it smoothly and much more than the noise does.
"""

import numpy as np

EXPERIMENTS = {
    "bench-step": (
        "PID",
        [
            "duration_s=3",
            'reference.rudder_deg=[{type="sine", amplitude=2.0, frequency_Hz=1.0}]',
        ],
        ["measured_rudder_rad", "measured_speed_rad_s", "iq_ref_A"],
    ),
    "position-step": (
        None,
        [
            "duration_s=2",
            'reference.position_mm=[{type="sine", amplitude=5.0, frequency_Hz=1.0}]',
            "load.motor_torque_Nm=[]",
            'sensors="bench-digital"',
            "solver.record_period_s=0.001",
        ],
        ["measured_position_m", "measured_speed_rad_s", "iq_ref_A"],
    ),
}


def changes(scenario: str) -> dict[str, dict[str, float]]:
    """change -> reading -> |y' - y| / |y|."""
    from emasim.experiments.runs import run_scenario
    from emasim.scenarios.loader import load_scenario

    label, base, columns = EXPERIMENTS[scenario]
    nominal = load_scenario(scenario, label=label, settings=base)
    plant = nominal.plant

    def run(extra):
        result = run_scenario(load_scenario(scenario, label=label, settings=base + extra))
        return {c: np.asarray(result[c]) for c in columns}

    reference = run([])
    cases = {"sensors' seed 0 -> 5": ["seed=5"]}
    for factor in (1.05, 1.005):
        pct = f"{100 * (factor - 1):g} %"
        cases[f"backlash +{pct}"] = [f"plant.backlash.width_mm={plant.backlash.width_mm * factor}"]
        if plant.linkage is not None:
            clearance = [c * factor for c in plant.linkage.hinge_clearance_mm]
            cases[f"hinge clearance +{pct}"] = [f"plant.linkage.hinge_clearance_mm={clearance}"]
        cases[f"friction +{pct}"] = [
            f"plant.friction.coulomb_Nm={plant.friction.coulomb_Nm * factor}",
            f"plant.friction.static_Nm={plant.friction.static_Nm * factor}",
        ]
    found = {}
    for name, extra in cases.items():
        moved = run(extra)
        found[name] = {
            c: float(np.linalg.norm(moved[c] - reference[c]) / np.linalg.norm(reference[c]))
            for c in columns
        }
    return found


def main() -> None:
    for scenario in EXPERIMENTS:
        print(f"{scenario}: relative change of each reading")
        for name, moved in changes(scenario).items():
            cells = ", ".join(f"{c} {100 * v:.3g} %" for c, v in moved.items())
            print(f"  {name}: {cells}")


if __name__ == "__main__":
    main()
