"""Whether a headline verdict is the controllers' or the integrator's: each bench experiment's
controller sets run again at half and at twice the plant's integration step
(``solver.step_s``), every gain and everything else as shipped.

The plant is integrated between control ticks by fixed RK4 sub-steps (emasim.sim.engine). On
the bench the hinges rattle in their clearances, a non-smooth motion whose trace does not
converge as the step shrinks (``benchmarks/step_size_study.py``): a figure read from it moves
with the step, and a verdict whose margin is smaller than that movement says nothing about the
controllers. Halving and doubling the step is the usual check of a fixed-step result (Hairer,
Norsett & Wanner, *Solving Ordinary Differential Equations I*, II.4: the error estimate by
step doubling); both steps stay far inside RK4's stability on every declared mode of the bench
(emasim.sim.diagnosis.fastest_modes: the fastest, the screw's compliance, allows 2e-4 s) and
divide the control period and the computation delay whole, as the scenario's rules require.

The shipped step's runs are the reproduction's own comparison; :func:`step_table` puts the
three together and emasim.analysis.integration_step reads them.
"""

from typing import TYPE_CHECKING

from ..analysis.judged import HEADLINE, headline_metric
from .batch import Job
from .components import JUDGED

if TYPE_CHECKING:
    from ..scenarios.schema import Scenario

STEP_FACTORS = (0.5, 2.0)  # of the scenario's own solver.step_s


def step_jobs(chosen: dict[str, "Scenario"]) -> list[Job]:
    """Every controller set of each chosen experiment the headline judges (JUDGED), at each
    STEP_FACTORS multiple of its step (tags ``experiment`` and ``step_s``)."""
    runs = []
    for name, scenario in chosen.items():
        if name not in JUDGED:
            continue
        for factor in STEP_FACTORS:
            step = factor * scenario.solver.step_s
            solver = scenario.solver.model_copy(update={"step_s": step})
            for label, single in scenario.revalidated(solver=solver).variants():
                runs.append(Job(single, label, {"experiment": name, "step_s": step}))
    return runs


def step_table(
    chosen: dict[str, "Scenario"], jobs: list[Job], measured: list[dict], metrics: dict
) -> dict[str, dict]:
    """headline key -> {experiment, metric, unit, step_s: [the steps, rising], shipped_step_s,
    values: {label: [the figure at each step]}} for each headline figure of an experiment the
    :func:`step_jobs` ``jobs`` ran, from their ``measured`` metrics and the ``chosen``
    experiments' own runs at their shipped step (``metrics``: name -> label -> metrics)."""
    at_step: dict[str, dict[float, dict[str, dict]]] = {}
    for job, values in zip(jobs, measured, strict=True):
        runs = at_step.setdefault(job.tags["experiment"], {})
        runs.setdefault(job.tags["step_s"], {})[job.label] = values
    table = {}
    for key, (experiment, _, _) in HEADLINE.items():
        name = experiment.replace("_", "-")
        if name not in at_step:
            continue
        metric, unit = headline_metric(key)
        shipped_step = chosen[name].solver.step_s
        runs = at_step[name] | {shipped_step: metrics[name]}
        steps = sorted(runs)
        table[key] = {
            "experiment": name,
            "metric": metric,
            "unit": unit,
            "step_s": steps,
            "shipped_step_s": shipped_step,
            "values": {label: [runs[s][label][metric] for s in steps] for label in metrics[name]},
        }
    return table
