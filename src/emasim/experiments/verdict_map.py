"""Where each headline verdict flips: the bench experiments over a grid of the conditions the
verdicts hang on, PID, the industrial PID and the hybrid run at every cell with the gains at
their nominal tuning.

The grid (AXES), each axis a ``--vary`` spec of :mod:`.variation`:

* the load motor's standing preload, 0 to the LAFERT B132I's 94.5 N m rating in thirds (the
  paper states no load profile; the nominal bench carries none);
* the rudder encoder: the paper's HEIDENHAIN TTL encoder (emasim.plant.presets
  .ttl_rudder_encoder, the nominal) or a 20-bit absolute one (.absolute_rudder_encoder);
* every hinge's clearance: none, the bench's 0.01 mm and 0.05 mm (a loose H7/g6 running fit of
  the 20 mm pins is 0.041 mm at most; emasim.experiments.uncertainty).

The nominal bench is one cell (preload 0, TTL, 0.01 mm): its figures are the headline's.
Each experiment is a grid study (:mod:`.study`) in
``runs/robustness/map-<scenario>-<key>/``, ``key`` as the robustness studies' (the resolved
scenario, the grid and the emasim version), resumed when interrupted and shown by a plain
``emasim reproduce``. :func:`verdict_map` reads the tables; emasim.analysis.verdict_map says
where each verdict flips.
"""

import math

from ..analysis.judged import HYBRID_LABEL
from ..analysis.verdict_map import margin
from ..plant.presets import LOADER_RATED_TORQUE_NM, absolute_rudder_encoder, ttl_rudder_encoder
from .robustness import BASELINES, ROOT, SCENARIOS, figures, study_key
from .store import OK
from .study import StudySpec, complete_tables, run_study

PRELOAD = "plant.load_motor.preload_Nm"
CLEARANCE = "plant.linkage.hinge_clearance_mm"
ENCODER_KEYS = ("sensors.rudder.resolution", "sensors.rudder.accuracy_error")
ENCODER = ",".join(ENCODER_KEYS)  # the study table's column: the encoder's place in ENCODERS
ENCODERS = {  # name -> the rudder channel, in the grid's order; the first is the bench's
    "TTL": ttl_rudder_encoder(),
    "20-bit absolute": absolute_rudder_encoder(),
}
PRELOADS_NM = tuple(LOADER_RATED_TORQUE_NM * k / 3 for k in range(4))
CLEARANCES_MM = (0.0, 0.01, 0.05)
AXES = {  # the map's axis -> (study column, its values as the map names them)
    "preload_Nm": (PRELOAD, PRELOADS_NM),
    "encoder": (ENCODER, tuple(ENCODERS)),
    "hinge_clearance_mm": (CLEARANCE, CLEARANCES_MM),
}
NOMINAL = {"preload_Nm": 0.0, "encoder": "TTL", "hinge_clearance_mm": 0.01}
GRID = (
    f"{PRELOAD}={','.join(map(repr, PRELOADS_NM))}",
    ENCODER
    + "="
    + str([[c.resolution, c.accuracy_error] for c in ENCODERS.values()]).replace(" ", ""),
    f"{CLEARANCE}={','.join(map(repr, CLEARANCES_MM))}",
)
LABELS = (*BASELINES, HYBRID_LABEL)


def spec_for(scenario: str) -> StudySpec:
    return StudySpec(scenario, vary=GRID, labels=LABELS)


def study_folder(scenario: str, root=ROOT):
    return root / f"map-{scenario}-{study_key(scenario, GRID)}"


def cells() -> int:
    """The number of cells of the grid."""
    return math.prod(len(values) for _, values in AXES.values())


def run_verdict_map(root=ROOT, progress=None, client=None, scheduler=None) -> dict:
    """Run (or resume) the grid study of every bench experiment; return :func:`verdict_map`.
    ``progress(done, total)`` counts the runs of both experiments together."""
    per_scenario = len(LABELS) * cells()
    tables = {}
    for i, scenario in enumerate(SCENARIOS):

        def told(count, _, before=i * per_scenario):
            if progress is not None:
                progress(before + count, len(SCENARIOS) * per_scenario)

        study = run_study(
            spec_for(scenario),
            study_folder(scenario, root),
            progress=told,
            client=client,
            scheduler=scheduler,
        )
        tables[scenario] = study.table
    return verdict_map(tables)


def latest(root=ROOT) -> dict | None:
    """The map of complete grid studies of today's experiments and version, or None."""
    folders = {scenario: study_folder(scenario, root) for scenario in SCENARIOS}
    tables = complete_tables(folders, rows=len(LABELS) * cells())
    return None if tables is None else verdict_map(tables)


def _cell_of(row) -> dict:
    """A study table row's place on the map, by the axes' names."""
    place = {}
    for axis, (column, values) in AXES.items():
        value = row[column]
        place[axis] = values[int(value)] if axis == "encoder" else float(value)
    return place


def verdict_map(tables: dict) -> dict:
    """``axes`` (axis -> its values), ``nominal`` (the nominal bench's cell) and ``figures``:
    headline figure -> {scenario, metric, against: baseline -> [cell]}, each cell the axes'
    values, the baseline's and the hybrid's |metric| (inf: the run diverged) and the margin,
    100 (|baseline| - |hybrid|) / |baseline| (positive: the hybrid wins), for each of
    BASELINES."""
    out = {
        "axes": {axis: list(values) for axis, (_, values) in AXES.items()},
        "nominal": dict(NOMINAL),
        "figures": {},
    }
    for name, (scenario, metric) in figures().items():
        if scenario not in tables or not name.endswith("_reduction"):
            continue
        table = tables[scenario]
        value = {}
        for _, row in table.iterrows():
            key = (row["label"], row["sample"])
            magnitude = abs(float(row[metric])) if row["status"] == OK else math.inf
            value[key] = (magnitude, _cell_of(row))
        against = {}
        for baseline in BASELINES:
            rows = []
            for sample in sorted({s for label, s in value if label == HYBRID_LABEL}):
                hybrid, place = value[(HYBRID_LABEL, sample)]
                base, _ = value[(baseline, sample)]
                rows.append(
                    place | {"baseline": base, "hybrid": hybrid, "margin_pct": margin(base, hybrid)}
                )
            against[baseline] = rows
        out["figures"][name] = {"scenario": scenario, "metric": metric, "against": against}
    return out
