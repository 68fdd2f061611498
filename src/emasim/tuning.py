"""Fair tuning: every controller of a comparison gets the same search, cost and budget.

Each controller config names its design knobs and their ranges (``tunable_ranges``); a study
samples them log-uniformly with Optuna's TPE sampler (seeded), starting from the scenario's own
gains as the first trial, so tuning never returns something worse than what it was given. Both
loops of a cascade are tuned together. The cost of a run is

    J = IAE / (T * R)  +  CHATTER_WEIGHT * TV(iq*) / I_max

where IAE is the integral of |reference - output| of the loop the scenario closes (speed,
rod position or rudder), T the duration, R the largest |reference|, TV(iq*) the total variation
per second of the current command and I_max the drive's current limit: tracking error, plus a
price on control chattering that wears the drive. A run that diverges costs DIVERGED_COST.
Studies live in SQLite by default (any SQLAlchemy URL works), one per scenario and label, so an
interrupted tuning resumes where it stopped and several machines can share a study.
"""

import warnings

import numpy as np
import optuna

from .analysis.metrics import integral_absolute_error, total_variation_rate
from .errors import SimulationDiverged
from .sim.engine import simulate

CHATTER_WEIGHT = 2e-3
DIVERGED_COST = 1e3
LOOPS = ("position", "speed")


def tuning_cost(result, max_current_A: float) -> float:
    """J of the module docstring for a simulated run."""
    t = result.t
    if np.isfinite(result["position_ref_m"]).any():
        reference, output = result["position_ref_m"], result["actuator_position_m"]
    else:
        reference, output = result["speed_ref_rad_s"], result["motor_speed_rad_s"]
    scale = (t[-1] - t[0]) * max(float(np.max(np.abs(reference))), 1e-12)
    tracking = integral_absolute_error(t, reference - output) / scale
    chatter = total_variation_rate(t, result["iq_ref_A"]) / max_current_A
    return tracking + CHATTER_WEIGHT * chatter


def _controllers_with(controllers, values: dict[str, float]):
    """A copy of a Controllers model with 'loop.field' values set (validated)."""
    data = controllers.model_dump()
    for key, value in values.items():
        loop, field = key.split(".", 1)
        data[loop][field] = value
    return type(controllers).model_validate(data)


def search_space(controllers) -> dict[str, tuple[float, float]]:
    """'loop.field' -> range, for every loop of the cascade that has a controller."""
    return {
        f"{loop}.{field}": bounds
        for loop in LOOPS
        if getattr(controllers, loop) is not None
        for field, bounds in getattr(controllers, loop).tunable_ranges().items()
    }


def tune_variant(scenario, label: str, controllers, trials: int, storage: str, seed: int = 0):
    """Tune one controller set on ``scenario``; returns (tuned Controllers, best cost, study)."""
    space = search_space(controllers)
    max_current = scenario.plant.motor.max_current_A

    def objective(trial: optuna.Trial) -> float:
        values = {k: trial.suggest_float(k, lo, hi, log=True) for k, (lo, hi) in space.items()}
        candidate = scenario.model_copy(
            update={"controllers": _controllers_with(controllers, values), "compare": []}
        )
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # eq. 37 notices, irrelevant while searching
                result = simulate(candidate.setup())
        except SimulationDiverged:
            return DIVERGED_COST
        return tuning_cost(result, max_current)

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(
        study_name=f"{scenario.name}:{label}",
        storage=storage,
        load_if_exists=True,
        direction="minimize",
        sampler=optuna.samplers.TPESampler(seed=seed),
    )
    if not study.trials:
        start = {}
        for key in space:
            loop, field = key.split(".", 1)
            value = getattr(getattr(controllers, loop), field)
            if value is not None:
                start[key] = float(value)
        study.enqueue_trial(start, skip_if_exists=True)
    done = sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials)
    study.optimize(objective, n_trials=max(0, trials - done))
    return _controllers_with(controllers, study.best_params), study.best_value, study


def tune_scenario(raw: dict, scenario, trials: int, storage: str, seed: int = 0, report=None):
    """Tune every controller set of a scenario with the same budget; return the raw scenario
    table with the tuned gains written in, and label -> (cost before, cost after).

    ``raw`` is the scenario file's table (as read, before validation); the tuned values are
    written as overrides of each controller set, and a ``tuning`` record says how.
    """
    tuned_raw = dict(raw)
    costs = {}
    entries = list(tuned_raw["compare"]) if scenario.compare else None
    for i, (label, variant) in enumerate(scenario.variants()):
        tuned, best, study = tune_variant(
            variant, label, variant.controllers, trials, storage, seed
        )
        costs[label] = (study.trials[0].value, best)
        if report is not None:
            report(label, *costs[label])
        overrides = {
            loop: {"name": getattr(tuned, loop).name}
            | {
                field: getattr(getattr(tuned, loop), field)
                for field in getattr(tuned, loop).tunable_ranges()
            }
            for loop in LOOPS
            if getattr(tuned, loop) is not None
        }
        if entries is not None:
            entry = dict(entries[i])
            entry["controllers"] = _with_overrides(entry.get("controllers", {}), overrides)
            entries[i] = entry
        else:
            tuned_raw["controllers"] = _with_overrides(tuned_raw.get("controllers", {}), overrides)
    if entries is not None:
        tuned_raw["compare"] = entries
    tuned_raw["tuning"] = {
        "method": "optuna TPE, log-uniform over each controller's tunable_ranges, "
        "first trial = the gains given",
        "trials_per_controller_set": trials,
        "seed": seed,
        "cost": "IAE/(T*max|ref|) + 2e-3 * TV(iq*)/I_max (emasim.tuning.tuning_cost)",
    }
    return tuned_raw, costs


def _with_overrides(section, overrides: dict) -> dict:
    """A controllers table (or cascade name) with per-loop overrides laid over it."""
    section = {"cascade": section} if isinstance(section, str) else dict(section)
    for loop, values in overrides.items():
        section[loop] = {**section.get(loop, {}), **values}
    return section
