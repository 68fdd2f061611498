"""The hybrid proven part by part, its runs: its headline figures with each of its parts
switched off, and with its loops crossed with the PID cascade's, on each bench experiment.

The tuned hybrid is the RBF-network sliding-mode position law (emasim.control.rbf) over the
super-twisting speed law with its GPIO observer (emasim.control.super_twisting). Each
component run changes one thing of the tuned set, everything else as tuned:

* RBF off: adaptation gain 0 (the network's weights stay at W(0) = 0, so f_hat = 0);
* SMC switching off: switching gain eps = 0 (the surface law c de + q s alone);
* GPIO off: the speed law without its observer (``st-improved``, the same gains);
* all three off;
* the hybrid's position law over the PID cascade's speed loop, and the PID's position law over
  the hybrid's speed loop (both as tuned).

emasim.analysis.components reads the table (component_lines).
"""

from typing import TYPE_CHECKING

from ..analysis.components import (
    COMPONENTS,
    HYBRID_OVER_PID,
    PART_NAMES,
    PID_OVER_HYBRID,
    TUNED,
    figures_of,
)
from ..analysis.judged import HEADLINE, HYBRID_LABEL, PID_LABEL
from ..analysis.report import TRUE_PREFIX
from .batch import Job

JUDGED = {experiment.replace("_", "-") for experiment, _, _ in HEADLINE.values()}

if TYPE_CHECKING:
    from ..scenarios.schema import Scenario

PARTS = dict(  # part -> (position loop changes, speed loop changes), in PART_NAMES' order
    zip(
        PART_NAMES,
        (
            ({"adaptation_gain": 0.0}, {}),  # RBF off
            ({"switching_gain_m_s2": 0.0}, {}),  # SMC switching off
            ({}, {"name": "st-improved"}),  # GPIO off
            ({"adaptation_gain": 0.0, "switching_gain_m_s2": 0.0}, {"name": "st-improved"}),
        ),
        strict=True,
    )
)


def component_jobs(chosen: dict[str, "Scenario"]) -> list[Job]:
    """The run of every component of COMPONENTS (its label, tags ``experiment`` and
    ``component``), on each chosen experiment the headline judges (JUDGED) that compares the
    hybrid with PID."""
    runs = []
    for name, scenario in chosen.items():
        sets = dict(scenario.variants())
        if name not in JUDGED or not {PID_LABEL, HYBRID_LABEL} <= set(sets):
            continue
        hybrid, pid = sets[HYBRID_LABEL].controllers, sets[PID_LABEL].controllers
        crossed = {
            TUNED: hybrid,
            HYBRID_OVER_PID: hybrid.model_copy(update={"speed": pid.speed}),
            PID_OVER_HYBRID: hybrid.model_copy(update={"position": pid.position}),
        }
        for part, (position, speed) in PARTS.items():
            crossed[part] = hybrid.model_copy(
                update={
                    "position": hybrid.position.model_copy(update=position),
                    "speed": type(hybrid.speed).model_validate(hybrid.speed.model_dump() | speed),
                }
            )
        for component in COMPONENTS:
            single = sets[HYBRID_LABEL].model_copy(update={"controllers": crossed[component]})
            runs.append(Job(single, component, {"experiment": name, "component": component}))
    return runs


def _row(component: str, metrics: dict, figures: list[str]) -> dict:
    """A table row: the component's name and each figure, measured and of the true angle."""
    row = {"component": component}
    for figure in figures:
        row[figure] = metrics.get(figure)
        row[TRUE_PREFIX + figure] = metrics.get(TRUE_PREFIX + figure)
    return row


def component_tables(jobs: list[Job], measured: list[dict], metrics: dict) -> dict[str, list[dict]]:
    """experiment key ('bench_step') -> rows {component, <figure>: value, true_<figure>:
    value}: the component runs' headline figures (``measured``: each job's metrics, and of
    the true angle), with PID's own (``metrics``: experiment name -> label -> metrics) as the
    last row."""
    tables = {}
    for job, values in zip(jobs, measured, strict=True):
        key = job.tags["experiment"].replace("-", "_")
        row = _row(job.tags["component"], values, figures_of(key))
        tables.setdefault(key, []).append(row)
    for key, rows in tables.items():
        pid = metrics[key.replace("_", "-")][PID_LABEL]
        rows.append(_row(PID_LABEL, pid, figures_of(key)))
    return tables
