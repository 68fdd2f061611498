"""The ablation of the realistic bench: each bench comparison re-run as its elements are
added one at a time, with the same tuned gains throughout.

The stages, each adding to the one before (:data:`STAGES`):

1. **lumped**: the SEA805 on the lumped rudder stage, the rod sensor in the position loop,
   the bench's sensors read at every tick, no delay, an ideal rudder load;
2. **linkage**: the clearance-joint linkage in place of the lumped stage;
3. **rudder feedback**: the position loop closes on the rudder encoder;
4. **compliance**: the screw's axial stiffness, the anchorage and the rudder shaft's torsion
   (every element whose declared ablation stage is the compliance's);
5. **digital drive**: the one-sample computation delay, the encoder-differenced speed and the
   sensors' own rates (the bench-digital sensors), and the drive's rated limits with the
   rated speed as its speed limit;
6. **load motor**: the bench's load motor, its inertia and torque loop (and a standing
   preload, where the scenario gives one).

A stage is the scenario with the later stages' elements taken out (:func:`stage_scenarios`),
so the last stage is the bench scenario itself and the first is the idealised bench on the
lumped rudder (preset sea805-linkage's drive: its speed limit, the rudder stage's 1.5 kg m^2).
"""

from ..plant.actuator import ELEMENTS
from ..plant.presets import PRESETS, bench_digital_sensors, bench_sensors
from ..scenarios.schema import Scenario
from .batch import Job, run_jobs

STAGES = (
    ("lumped", "the SEA805 on the lumped rudder stage, rod feedback, an ideal digital loop"),
    ("linkage", "+ the clearance-joint linkage"),
    ("rudder feedback", "+ the position loop on the rudder encoder"),
    ("compliance", "+ screw stiffness, anchorage, rudder-shaft torsion"),
    ("digital drive", "+ one-sample delay, encoder speed, sensor rates, rated limits"),
    ("load motor", "+ the load motor: inertia, torque loop, the scenario's preload if any"),
)


def without_stage(plant, stage: str):
    """The plant without the elements of ``stage`` (their declared ablation stage,
    emasim.plant.element.Element.stage), with what each one's removal changes elsewhere."""
    updates = {}
    for element in ELEMENTS:
        if element.stage == stage and getattr(plant, element.section) is not None:
            updates |= element.removed(plant) | {element.section: None}
    return plant.model_copy(update=updates)


def _without_load_motor(sc: Scenario) -> Scenario:
    return sc.revalidated(plant=without_stage(sc.plant, "load motor"))


def _without_digital_drive(sc: Scenario) -> Scenario:
    idealised_speed = PRESETS["sea805-linkage"]().motor.max_speed_rpm
    plant = without_stage(sc.plant, "digital drive")
    plant = plant.model_copy(
        update={"motor": plant.motor.model_copy(update={"max_speed_rpm": idealised_speed})}
    )
    sensors = bench_sensors() if sc.sensors == bench_digital_sensors() else sc.sensors
    loop = sc.loop.model_copy(update={"computation_delay_s": 0.0})
    return sc.revalidated(plant=plant, sensors=sensors, loop=loop)


def _without_compliance(sc: Scenario) -> Scenario:
    return sc.revalidated(plant=without_stage(sc.plant, "compliance"))


def _without_rudder_feedback(sc: Scenario) -> Scenario:
    return sc.revalidated(loop=sc.loop.model_copy(update={"position_feedback": "rod"}))


def _without_linkage(sc: Scenario) -> Scenario:
    return sc.revalidated(plant=without_stage(sc.plant, "linkage"))


_TAKE_OUT = (  # what takes each stage back to the one before it, from the last stage down
    _without_load_motor,
    _without_digital_drive,
    _without_compliance,
    _without_rudder_feedback,
    _without_linkage,
)


def stage_scenarios(scenario: Scenario) -> list[tuple[str, Scenario]]:
    """(stage, scenario) for every stage of :data:`STAGES`, the first stage first."""
    stages = [scenario]
    for take_out in _TAKE_OUT:
        stages.append(take_out(stages[-1]))
    return [(name, sc) for (name, _), sc in zip(STAGES, reversed(stages), strict=True)]


def ablation(
    scenarios: dict[str, Scenario], known: dict | None = None, labels: tuple[str, ...] = ()
) -> dict:
    """{experiment: {stage: {label: metrics}}} of every stage of each scenario, every run in
    parallel (emasim.experiments.batch.run_all). ``known`` ({experiment: {label: metrics}})
    gives the last stage's metrics when the scenario itself has already run; ``labels``, when
    given, the controller sets to run (the ablation's tables compare PID and the hybrid)."""
    known = known or {}
    jobs = ablation_jobs(scenarios, known, labels)
    metrics = [result.metrics for result in run_jobs(jobs)]
    return ablation_table(scenarios, jobs, metrics, known, labels)


def ablation_jobs(
    scenarios: dict[str, Scenario], known=(), labels: tuple[str, ...] = ()
) -> list[Job]:
    """The ablation's runs, each a set's single-set scenario at a stage (tags ``experiment``
    and ``stage``), of every stage of each scenario but the last stage of the experiments in
    ``known`` (already run)."""
    runs = []
    for name, scenario in scenarios.items():
        for stage, staged in stage_scenarios(scenario):
            if stage == STAGES[-1][0] and name in known:
                continue
            runs.extend(
                Job(single, label, {"experiment": name, "stage": stage})
                for label, single in staged.variants()
                if not labels or label in labels
            )
    return runs


def ablation_table(
    scenarios: dict[str, Scenario],
    jobs: list[Job],
    metrics: list[dict],
    known: dict,
    labels: tuple[str, ...] = (),
) -> dict:
    """{experiment: {stage: {label: metrics}}} from the ``metrics`` of each of
    :func:`ablation_jobs`' ``jobs`` and the ``known`` metrics of the last stage (see
    :func:`ablation`)."""
    out = {name: {stage: {} for stage, _ in STAGES} for name in scenarios}
    for job, values in zip(jobs, metrics, strict=True):
        out[job.tags["experiment"]][job.tags["stage"]][job.label] = values
    for name, metrics in known.items():
        if name in out:
            out[name][STAGES[-1][0]] = {
                label: m for label, m in metrics.items() if not labels or label in labels
            }
    return out
