"""The abstract's five claims decided over paired replicas (SPEC section 8; the rule in
emasim.analysis.verdict_rule).

**A replica** of a bench experiment differs from another only as two runs on a real bench
differ (:func:`replica_specs`, ``--vary`` specs of :mod:`.variation`):

* the sensors' noise: the scenario's seed, drawn over its whole range;
* the encoder grid's phase: the offset of each quantised channel (the rudder's TTL encoder,
  the motor encoder, the rod's position sensor) uniform over one count, +-q/2: where the
  grid's edges fall on the true angle depends on how the encoder was mounted. The plant starts
  at rest at the neutral, so the rudder encoder's phase also sets where the start lies within
  a count: here the two are one factor.

The bristle's initial state is not varied: the plant starts with the friction's bristles
relaxed, and a pre-deflected bristle is a rest state only with the matching torque stored in
the drive train, which the plant's initial state does not yet hold.

**The runs.** Every controller set of each bench experiment (BASELINES and the hybrid) runs
on the same ``n`` replicas (common random numbers), as a study (emasim.experiments.study) in
``runs/replicas/<scenario>-<key>-<n>/`` (key as emasim.experiments.robustness.study_key): a
study of the same experiments, seed and version is found again, resumed when interrupted.

**The floor.** On each replica, what a perfect follower scores: the rudder exactly on its
command, read through that replica's rudder encoder (:func:`floor_figures`).

**The claims** (:func:`claims`): each headline figure (emasim.analysis.judged.HEADLINE),
the hybrid against each baseline, on the measured column (the rudder encoder's reading: what
the bench sees, with its resolution (judged.RESOLUTION) and floor) and on the true column
(the rudder's angle, which no sensor on the bench reads; no floor, the relative band alone).
"""

from pathlib import Path

import numpy as np

from ..analysis.judged import (
    HEADLINE,
    HYBRID_LABEL,
    INDUSTRIAL_LABEL,
    PID_LABEL,
    RESOLUTION,
    figure_words,
    headline_metric,
    resolution,
)
from ..analysis.report import DEG_PER_RAD, TRUE_PREFIX, command_traces, reading_figures
from ..analysis.verdict_rule import CONFIDENCE, FLOOR_TIE, RELATIVE_BAND, TIE, decide
from ..interface import M_ANGLE, M_POSITION, M_RUDDER
from ..naming import RUNS_ROOT
from ..plant.sensors import S_OFFSET, read_series
from .robustness import study_key
from .store import OK
from .study import SAMPLE, StudySpec, largest_complete, run_studies

SCENARIOS = ("bench-step", "bench-sine")
BASELINES = (PID_LABEL, INDUSTRIAL_LABEL)  # the paper's baseline, and the strongest fair one
LABELS = (*BASELINES, HYBRID_LABEL)
DEFAULT_REPLICAS = 16  # SPEC section 8: N >= 16
DEFAULT_SEED = 0
ROOT = RUNS_ROOT / "replicas"
SEED_SPEC = "seed=integers(0, 4294967295)"  # the scenario seed's whole range
PHASED = {"rudder": M_RUDDER, "angle": M_ANGLE, "position": M_POSITION}  # channel -> row
EXPERIMENT = {"bench_step": "bench-step", "bench_sine": "bench-sine"}  # HEADLINE's -> scenario


def offset_key(channel: str) -> str:
    return f"sensors.{channel}.offset"


def replica_specs(scenario: str) -> tuple[str, ...]:
    """The ``--vary`` specs of a replica of ``scenario`` (module docstring): the seed, and
    each quantised channel's offset uniform over its count, +-q/2."""
    from ..scenarios.loader import load_scenario

    sensors = load_scenario(scenario).sensors
    specs = [SEED_SPEC]
    for channel in PHASED:
        q = getattr(sensors, channel).resolution
        if q > 0.0:
            specs.append(f"{offset_key(channel)}=uniform({-0.5 * q!r}, {0.5 * q!r})")
    return tuple(specs)


def spec_for(
    scenario: str, replicas: int, seed: int = DEFAULT_SEED, settings: tuple[str, ...] = ()
) -> StudySpec:
    """The replica study of ``scenario``: ``replicas`` replicas of every set of LABELS, the
    draws from ``seed``, ``settings`` (``KEY=VALUE``, as ``--set``) changed from the shipped
    scenario (none: as shipped)."""
    return StudySpec(
        scenario,
        vary=replica_specs(scenario),
        runs=replicas,
        seed=seed,
        labels=LABELS,
        settings=settings,
    )


def study_folder(
    scenario: str,
    replicas: int,
    root: Path = ROOT,
    seed: int = DEFAULT_SEED,
    settings: tuple[str, ...] = (),
) -> Path:
    """Where :func:`spec_for`'s study lives: named by the scenario, a key of what it runs
    (emasim.experiments.robustness.study_key of its specs and settings) and its size."""
    key = study_key(scenario, replica_specs(scenario) + settings, seed)
    return root / f"{scenario}-{key}-{replicas}"


def floor_figures(scenario, rudder_offset_rad: float) -> dict:
    """The measured figures a perfect follower scores on a replica of ``scenario`` (a
    Scenario) whose rudder encoder's offset is ``rudder_offset_rad``: the rudder exactly on
    its command at every recorded time, read through that encoder (emasim.plant.sensors:
    quantum, accuracy error, offset), its rate differenced as the bench's
    (emasim.analysis.report.reading_figures)."""
    return floor_reader(scenario)(rudder_offset_rad)


def floor_reader(scenario):
    """:func:`floor_figures` of ``scenario`` as a function of the rudder encoder's offset: the
    scenario's times, sensor table and command made once for all its replicas."""
    setup = scenario.setup()
    t = np.arange(setup.recorded_rows) * (setup.record_every * setup.sample_period_s)
    experiment = scenario.experiment()
    command = command_traces(experiment, t)[0] / DEG_PER_RAD

    def figures(rudder_offset_rad: float) -> dict:
        table = setup.sensors.copy()
        table[M_RUDDER, S_OFFSET] = rudder_offset_rad
        reading = DEG_PER_RAD * read_series(command, table, M_RUDDER)
        return reading_figures(experiment, t, reading)

    return figures


def run_tables(
    replicas: int = DEFAULT_REPLICAS,
    root: Path = ROOT,
    progress=None,
    client=None,
    seed: int = DEFAULT_SEED,
    settings: dict[str, tuple[str, ...]] | None = None,
) -> dict:
    """Run (or resume) the replica study of every bench experiment (draws from ``seed``,
    ``settings``: scenario -> its settings) and return scenario -> its study table.
    ``progress(done, total)`` counts the runs of both together."""
    changed = settings or {}
    studies = {
        s: (
            spec_for(s, replicas, seed, changed.get(s, ())),
            study_folder(s, replicas, root, seed, changed.get(s, ())),
        )
        for s in SCENARIOS
    }
    return run_studies(studies, progress, client)


def run_replicas(
    replicas: int = DEFAULT_REPLICAS,
    root: Path = ROOT,
    progress=None,
    client=None,
    seed: int = DEFAULT_SEED,
) -> dict:
    """Run (or resume) the replicas of every bench experiment as shipped (:func:`run_tables`)
    and return :func:`claims`."""
    return claims(run_tables(replicas, root, progress, client, seed), replicas, seed)


def latest(root: Path = ROOT, seed: int = DEFAULT_SEED) -> dict | None:
    """The claims of the largest complete replica study of today's experiments as shipped,
    draws' ``seed`` and version, or None when there is none (both experiments' of one size)."""
    tables, counts = {}, set()
    for scenario in SCENARIOS:
        prefix = f"{scenario}-{study_key(scenario, replica_specs(scenario), seed)}"
        found = largest_complete(root, prefix, len(LABELS))
        if found is None:
            return None
        counts.add(found[0])
        tables[scenario] = found[1]
    if len(counts) != 1:
        return None
    return claims(tables, counts.pop(), seed)


def floors(tables: dict, settings: dict[str, tuple[str, ...]] | None = None) -> dict:
    """scenario -> the measurement floor's figures on each replica of its study table, in the
    order of the samples (:func:`floor_figures`, the scenario with its ``settings``)."""
    from ..scenarios.loader import load_scenario

    out = {}
    for scenario, table in tables.items():
        nominal = load_scenario(scenario, settings=list((settings or {}).get(scenario, ())))
        mine = table[table["label"] == HYBRID_LABEL].sort_values(SAMPLE)
        offsets = mine[offset_key("rudder")].to_numpy(dtype=float)
        read = floor_reader(nominal)
        out[scenario] = [read(float(o)) for o in offsets]
    return out


def per_sample(table, label: str, metric: str) -> np.ndarray:
    """|metric| of set ``label`` on each sample in order (inf where the run did not end ok,
    nan where the figure is undefined)."""
    mine = table[table["label"] == label].sort_values(SAMPLE)
    value = np.abs(mine[metric].to_numpy(dtype=float)) if metric in mine else np.nan
    return np.where(mine["status"].to_numpy() == OK, value, np.inf)


def claims(
    tables: dict,
    replicas: int,
    seed: int = DEFAULT_SEED,
    settings: dict[str, tuple[str, ...]] | None = None,
) -> dict:
    """Each headline claim's decisions (emasim.analysis.verdict_rule.Decision.to_json, with the
    claim's word) from the replica studies' ``tables`` (scenario -> study table, its scenario
    changed by ``settings``): per baseline, the measured and the true column; the claims of
    the experiments in ``tables`` only."""
    from ..analysis.paper_report import paper_results
    from ..scenarios.loader import load_scenario

    claimed = paper_results()["headline"]
    at_floor = floors(tables, settings)
    out = []
    for key, (experiment, _, definition) in HEADLINE.items():
        scenario = EXPERIMENT[experiment]
        if scenario not in tables:
            continue
        table, nominal = tables[scenario], load_scenario(scenario)
        metric, unit = headline_metric(key)
        count_deg = DEG_PER_RAD * nominal.sensors.rudder.resolution
        floor = np.abs([f[metric] for f in at_floor[scenario]])
        against = {}
        for baseline in BASELINES:
            columns = {}
            for column, name, res, bottom in (
                ("measured", metric, resolution(key, count_deg), floor),
                ("true", TRUE_PREFIX + metric, 0.0, None),
            ):
                decision = decide(
                    per_sample(table, baseline, name),
                    per_sample(table, HYBRID_LABEL, name),
                    res,
                    bottom,
                )
                columns[column] = decision.to_json() | {"claim": decision.claim(claimed[key])}
            against[baseline] = columns
        out.append(
            {
                "figure": key,
                "words": figure_words(key),
                "experiment": scenario,
                "metric": metric,
                "unit": unit,
                "definition": definition,
                "paper_reduction": claimed[key],
                "resolution_reason": RESOLUTION[key][2],
                "against": against,
            }
        )
    return record(replicas, seed) | {"claims": out}


def record(replicas: int, seed: int) -> dict:
    """What every decision table over replicas states of itself: their number, the draws'
    seed, the interval's confidence and kind, and the tie band's relative floor."""
    return {
        "replicas": replicas,
        "seed": seed,
        "confidence": CONFIDENCE,
        "interval": "Student t",
        "relative_band": RELATIVE_BAND,
    }


def compared(
    before: dict, after: dict, settings: dict[str, tuple[str, ...]] | None = None
) -> list[dict]:
    """Each headline figure of the experiments in both ``before`` and ``after`` (scenario ->
    study table, the same replicas under two conditions, such as two integration steps): per
    controller set and column, the decision of its ensemble in ``after`` against ``before``
    (emasim.analysis.verdict_rule.decide; the floor of ``before``'s scenarios, changed by
    ``settings``)."""
    from ..scenarios.loader import load_scenario

    at_floor = floors(before, settings)
    figures = []
    for key, (experiment, _, _) in HEADLINE.items():
        scenario = EXPERIMENT[experiment]
        if scenario not in before or scenario not in after:
            continue
        metric, unit = headline_metric(key)
        count_deg = DEG_PER_RAD * load_scenario(scenario).sensors.rudder.resolution
        floor = np.abs([f[metric] for f in at_floor[scenario]])
        sets = {}
        for label in LABELS:
            sets[label] = {
                column: decide(
                    per_sample(before[scenario], label, name),
                    per_sample(after[scenario], label, name),
                    res,
                    bottom,
                ).to_json()
                for column, name, res, bottom in (
                    ("measured", metric, resolution(key, count_deg), floor),
                    ("true", TRUE_PREFIX + metric, 0.0, None),
                )
            }
        figures.append({"figure": key, "words": figure_words(key), "unit": unit, "sets": sets})
    return figures


def all_tied(figures: list[dict]) -> bool:
    """Whether every decision of :func:`compared`'s ``figures`` is a tie (or one at the
    measurement floor): the two conditions' ensembles agree within every band."""
    return all(
        d["word"] in (TIE, FLOOR_TIE)
        for f in figures
        for columns in f["sets"].values()
        for d in columns.values()
    )
