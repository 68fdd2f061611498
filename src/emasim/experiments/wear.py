"""Wear: how each controller's headline metrics degrade over the actuator's service life, the
concern of SAE AIR5713. Backlash and hinge clearances grow and friction rises; the gains stay
at their nominal tuning.

WEAR_LEVELS scale the bench's own values, level k = 0 (new, the nominal bench) to 4 (worn):
the screw backlash by 1 + k/2 (to 3x, 0.3 mm), every hinge clearance by 1 + k (to 5x,
0.05 mm) and friction (Coulomb, stiction and viscous together) by 1 + k/4 (to 2x). Each bench
experiment runs at every level with PID and with the hybrid (a study, :mod:`.study`), in
``runs/robustness/wear-<scenario>-<key>/``, found again like the robustness studies.
"""

from ..analysis.judged import HYBRID_LABEL, PID_LABEL
from .robustness import ROOT, SCENARIOS, figures, study_key
from .study import StudySpec, complete_tables, run_study

LEVELS = 5
WEAR_KEYS = (
    "plant.backlash.width_mm",
    "plant.linkage.hinge_clearance_mm",
    "plant.friction.coulomb_Nm",
    "plant.friction.static_Nm",
    "plant.friction.viscous_Nms_per_rad",
)
FACTORS = [[1 + k / 2, 1 + k, 1 + k / 4, 1 + k / 4, 1 + k / 4] for k in range(LEVELS)]
WEAR = ",".join(WEAR_KEYS) + "=*" + str(FACTORS).replace(" ", "")
LEVEL = WEAR.split("=", 1)[0]  # the study table's column: the wear level 0 ... LEVELS-1


def spec_for(scenario: str) -> StudySpec:
    return StudySpec(scenario, vary=(WEAR,), labels=(PID_LABEL, HYBRID_LABEL))


def study_folder(scenario: str, root=ROOT):
    return root / f"wear-{scenario}-{study_key(scenario, (WEAR,))}"


def run_wear(root=ROOT, client=None, scheduler=None) -> dict:
    """Run (or resume) the wear study of every bench experiment; return :func:`degradation`."""
    tables = {
        scenario: run_study(
            spec_for(scenario), study_folder(scenario, root), client=client, scheduler=scheduler
        ).table
        for scenario in SCENARIOS
    }
    return degradation(tables)


def latest(root=ROOT) -> dict | None:
    """The degradation of a complete wear study of today's experiments and version, or None."""
    folders = {scenario: study_folder(scenario, root) for scenario in SCENARIOS}
    tables = complete_tables(folders, rows=2 * LEVELS)
    return None if tables is None else degradation(tables)


def degradation(tables: dict) -> dict:
    """figure -> {scenario, metric, levels: [0..], label: [value at each level]} for each
    headline figure and tuning cost (:func:`emasim.experiments.robustness.figures`)."""
    out = {}
    for name, (scenario, metric) in figures().items():
        if scenario not in tables or metric not in tables[scenario]:
            continue
        table = tables[scenario]
        entry = {"scenario": scenario, "metric": metric, "levels": list(range(LEVELS))}
        for label in (PID_LABEL, HYBRID_LABEL):
            mine = table[table["label"] == label].set_index(LEVEL)[metric]
            entry[label] = [float(mine.get(level, float("nan"))) for level in range(LEVELS)]
        out[name] = entry
    return out
