"""Wear: how each controller's headline metrics degrade over the actuator's service life, the
concern of SAE AIR5713. Backlash and hinge clearances grow and friction rises; the gains stay
at their nominal tuning.

WEAR_LEVELS scale the bench's own values, level k = 0 (new, the nominal bench) to 4 (worn):
the screw backlash by 1 + k/2 (to 3x, 0.3 mm), every hinge clearance by 1 + k (to 5x,
0.05 mm) and friction (Coulomb, stiction and viscous together) by 1 + k/4 (to 2x). Each bench
experiment runs at every level with PID and with the hybrid (a study, :mod:`.study`), in
``runs/robustness/wear-<scenario>-<key>/``, found again like the robustness studies.

:func:`run_wear_series` runs the same study at values identified over an actuator's life
instead of the levels: the values ``emasim identify --data ... --at ...`` found at each date
(emasim.identification.identify.identify_series), each identified key as a factor on the
bench's own value, in ``runs/robustness/wear-series-<scenario>-<key>/``.
"""

import json

import numpy as np

from ..analysis.judged import HYBRID_LABEL, PID_LABEL
from ..errors import InputError
from ..scenarios.loader import load_scenario
from .robustness import ROOT, SCENARIOS, figures, study_key
from .study import StudySpec, complete_tables, resolved_value, run_study
from .variation import FACTOR

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


def degradation(tables: dict, level: str = LEVEL, levels: int = LEVELS, at=None) -> dict:
    """figure -> {scenario, metric, levels: [0..], label: [value at each level]} for each
    headline figure and tuning cost (:func:`emasim.experiments.robustness.figures`), the
    study tables' column ``level`` holding the level; ``at``: each level's date or cycle
    count, kept as the entry's ``at``."""
    out = {}
    for name, (scenario, metric) in figures().items():
        if scenario not in tables or metric not in tables[scenario]:
            continue
        table = tables[scenario]
        entry = {"scenario": scenario, "metric": metric, "levels": list(range(levels))}
        if at is not None:
            entry["at"] = [str(a) for a in at]
        for label in (PID_LABEL, HYBRID_LABEL):
            mine = table[table["label"] == label].set_index(level)[metric]
            entry[label] = [float(mine.get(k, float("nan"))) for k in range(levels)]
        out[name] = entry
    return out


def series_variation(values: dict, scenario: str) -> str:
    """The ``--vary`` text that sets ``scenario`` at each of a series of identified values
    (``values``: key -> its value at each date, as emasim identify names the keys): every
    key's paths zipped, as factors on the scenario's own values (a factor key's value as it
    is; a value over the scenario's, one for every element of a list whose elements are
    alike). One InputError line for a key the scenario has no number at, or a zero it cannot
    scale."""
    resolved = load_scenario(scenario).model_dump(mode="json")
    if not values:
        raise InputError("--wear: the series holds no identified key")
    paths, factors = [], []
    for key, series in values.items():
        series = np.asarray(series, dtype=float)
        if key.endswith(FACTOR):
            for path in key.removesuffix(FACTOR).split(","):
                paths.append(path)
                factors.append(series)
            continue
        own = resolved_value(resolved, key)
        alike = own if not isinstance(own, list) else (own[0] if len(set(own)) == 1 else None)
        if not isinstance(alike, int | float) or alike == 0:
            raise InputError(
                f"--wear {key}: {scenario} has no single non-zero number there to scale"
            )
        paths.append(key)
        factors.append(series / alike)
    rows = np.column_stack(factors).tolist()
    return ",".join(paths) + "=*" + json.dumps(rows).replace(" ", "")


def run_wear_series(
    values: dict, at: list, root=ROOT, client=None, scheduler=None, scenarios=SCENARIOS, settings=()
) -> dict:
    """Run (or resume) each bench experiment with PID and the hybrid at each date's identified
    values (``values``: key -> its value at each of the dates ``at``; :func:`series_variation`);
    ``settings`` fixed ``KEY=VALUE`` overrides. Returns :func:`degradation` against ``at``."""
    tables = {}
    for scenario in scenarios:
        vary = (series_variation(values, scenario),)
        spec = StudySpec(
            scenario, vary=vary, labels=(PID_LABEL, HYBRID_LABEL), settings=tuple(settings)
        )
        folder = root / f"wear-series-{scenario}-{study_key(scenario, vary + tuple(settings))}"
        tables[scenario] = run_study(spec, folder, client=client, scheduler=scheduler).table
    level = vary[0].split("=", 1)[0]
    return degradation(tables, level, len(at), list(at))
