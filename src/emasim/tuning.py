"""Fair tuning: every controller of a comparison gets the same search, cost and budget.

Each controller config names its design knobs and their ranges (``tunable_ranges``); a study
samples them log-uniformly with Optuna's TPE sampler (seeded), starting from the scenario's own
gains as the first trial, so tuning never returns something worse than what it was given. Both
loops of a cascade are tuned together. The cost of a run is

    J = IAE / (T * R)  +  CHATTER_WEIGHT * TV(iq*) / I_max

where IAE is the integral of |reference - output| of the loop the scenario closes (speed,
rod position or rudder), T the duration, R the largest |reference|, TV(iq*) the total variation
per second of the current command and I_max the drive's current limit: tracking error, plus a
price on control chattering that wears the drive (:func:`emasim.analysis.report.tuning_cost`,
which every run reports as its ``tuning_cost`` metric). A run that diverges costs
DIVERGED_COST.

How long a set is searched is a :class:`emasim.search_rules.Budget`: trials in proportion to
its knobs (a fixed count for every set favours the one with fewer), an early stop once the best
cost has stopped improving, and a range widened where the optimum sits on its bound. The tuned
file's ``[tuning]`` record states the rule and, per set, the trials it used, why it stopped,
the ranges widened and any optimum still on a bound.

Every trial is a job of a job store (:mod:`emasim.experiments.store`, :func:`tuning_store`):
``runs/tune/jobs-<key>``, keyed by the fully resolved scenario, the seed, the trials run at
once, emasim's version and source. Each batch of trials is added to it and run on the Dask
client (as many at once as it has worker threads); its table, ``metrics.parquet``, holds one
row per trial: the set, the trial's number and kind, its gains, its status and every metric
of the run, with the cost's two terms. The sampler is told the costs in trial order, so a seed
and a batch size fix the search. The search itself lives in memory: run again, the same
command asks the same trials, finds the runs it finished before in the store and runs only
the rest, so a kill at any moment costs at most the runs it had in flight, and a larger budget
goes on from where the smaller one ended.
"""

import hashlib
import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import optuna

from .analysis.pareto import pareto_front, thinned
from .analysis.report import CHECK_TOLERANCE, COST_FORMULA, tuning_terms
from .config import hard_limits
from .errors import EmasimError, InputError
from .experiments.batch import Job
from .experiments.runs import run_scenario
from .experiments.store import DIVERGED, OK, RUN_ID, Measured, Store, keyed, metrics_only
from .naming import RUNS_ROOT, slug
from .search_rules import Budget, bound_side, converged, widened
from .sim.cosim import check_runnable
from .toml_text import laid_over

DIVERGED_COST = 1e3
LOOPS = ("position", "speed")
GIVEN = "given_gains"  # user attribute of the first trial: the scenario's own gains
NEIGHBOUR = "neighbour"  # user attribute of a neighbourhood-check point: its index
CHECK_STRIDE = 100_000  # neighbour indices of successive checks of one study start this apart
CHECK_ROUNDS = 3  # checks about each new optimum a better neighbour gives, at most
NEIGHBOUR_SPAN = 1.5  # ... each knob within x1.5 either way (+-50 %, in log space)
TRACKING, CHATTER = "tracking", "chatter"  # user attributes: a trial's two cost terms
COST_METRIC = "tuning_cost"  # a trial's cost: its run's metric (analysis.report.tuning_cost)
TERMS = {TRACKING: "tuning_tracking", CHATTER: "tuning_chatter"}  # ... and its terms' metrics
STORE_ROOT = RUNS_ROOT / "tune"  # the tunings' job stores (tuning_store)
TUNED_HEADER = "# emasim tune:"  # first line of every tuned scenario file emasim writes


def _controllers_with(controllers, values: dict[str, float]):
    """A copy of a Controllers model with 'loop.field' values set (validated)."""
    data = controllers.model_dump()
    for key, value in values.items():
        loop, field = key.split(".", 1)
        data[loop][field] = value
    return type(controllers).model_validate(data)


def with_explicit_gains(controllers, scenario):
    """The Controllers with each loop's gains written out (ControllerConfig.with_explicit_gains)
    for the scenario's plant: the knobs a tuning searches."""
    from .sim.setup import plant_facts

    facts = plant_facts(scenario.plant)
    return controllers.model_copy(
        update={
            loop: getattr(controllers, loop).with_explicit_gains(facts)
            for loop in LOOPS
            if getattr(controllers, loop) is not None
        }
    )


def search_space(controllers) -> dict[str, tuple[float, float]]:
    """'loop.field' -> range, for every loop of the cascade that has a controller."""
    return {
        f"{loop}.{field}": bounds
        for loop in LOOPS
        if getattr(controllers, loop) is not None
        for field, bounds in getattr(controllers, loop).tunable_ranges().items()
    }


def tuning_store(root: Path, scenario, seed: int, client=None) -> Store:
    """The job store of a tuning of ``scenario`` (its fully resolved table: every set of a
    comparison) with sampler ``seed``, run on ``client``, under ``root`` (module docstring):
    the same tuning finds it again and resumes; another scenario, seed, batch size or emasim
    source gets one of its own."""
    record = {
        "facility": "tune",
        "scenario": scenario.name,
        "scenario_sha256": study_key(scenario, full=True),
        "seed": seed,
        "batch": trials_at_once(client),
    }
    return keyed(root, [], record, record_file="tuning.json", measure=measure_trial)


def study_key(scenario, full: bool = False) -> str:
    """A hash of the fully resolved scenario (its tuning record left out): 16 hex digits, or
    all 64 with ``full``."""
    resolved = scenario.model_dump(mode="json", exclude={"tuning"})
    text = json.dumps(resolved, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[: None if full else 16]


def is_tuned_scenario(path: Path) -> bool:
    """True for a file that emasim tune wrote (it starts with TUNED_HEADER)."""
    try:
        with open(path, encoding="utf-8") as handle:
            return handle.readline().startswith(TUNED_HEADER)
    except (OSError, UnicodeDecodeError):
        return False


def tuned_toml(tuned_raw: dict, name: str, original: str = "") -> str:
    """The text of a tuned scenario file: emasim's header line, then the scenario file's own
    text (``original``) with the tuned table laid over it, so that its comments and layout
    stay (emasim.toml_text); only the values that changed are rewritten."""
    if original.startswith(TUNED_HEADER):  # re-tuning a tuned file: one header
        original = original.partition("\n")[2]
    return f"{TUNED_HEADER} {name} with tuned gains (see [tuning])\n" + laid_over(
        original, tuned_raw
    )


@dataclass
class Tuned:
    """One controller set's tuning: the tuned Controllers, the best cost, the cost of the gains
    given (None while their trial is unfinished), the Optuna study, the trials completed, why
    the last round stopped ("converged" or "budget"), the ranges widened (key -> (low, high))
    the knobs whose optimum still sits on a bound (key -> "lower" or "upper") and the check of
    the optimum's neighbourhood (:func:`check_neighbourhood`)."""

    controllers: object
    best: float
    given: float | None
    study: optuna.Study
    trials: int
    stopped: str
    widened: dict[str, tuple[float, float]]
    on_bound: dict[str, str]
    neighbourhood: dict | None = None

    def front(self) -> list[tuple[float, float]]:
        """The (chattering, tracking) Pareto front of the completed trials (analysis.pareto)."""
        complete = optuna.trial.TrialState.COMPLETE
        return pareto_front(
            [
                (t.user_attrs[CHATTER], t.user_attrs[TRACKING])
                for t in self.study.trials
                if t.state == complete and CHATTER in t.user_attrs
            ]
        )

    def record(self) -> dict:
        """The tuned file's record of this set ([tuning.sets.LABEL]): its search, its tuned
        point's two cost terms and its front (thinned to MAX_FRONT_POINTS)."""
        out = {"trials": self.trials, "knobs": len(self.study.best_params), "stopped": self.stopped}
        best = self.study.best_trial.user_attrs
        if CHATTER in best:
            out["tuned_point"] = [best[CHATTER], best[TRACKING]]
            out["front"] = [list(point) for point in thinned(self.front())]
        if self.widened:
            out["widened"] = {key: list(span) for key, span in self.widened.items()}
        if self.on_bound:
            out["on_bound"] = dict(self.on_bound)
        if self.neighbourhood is not None:
            out["neighbourhood"] = dict(self.neighbourhood)
        return out


def check_tunable(scenario) -> None:
    """Every rule a tune of ``scenario`` checks before its first trial: a run's
    (:func:`emasim.sim.cosim.check_runnable`), and no FMU mechanism: a search runs the
    scenario thousands of times, and an FMU's code runs in every one. InputError names it."""
    if scenario.solver.mechanism_fmu is not None:
        raise InputError(
            "solver.mechanism_fmu: tune does not load an FMU (every trial would run its code); "
            "tune with the built-in mechanism, then run the FMU with `emasim run --trust-fmu`"
        )
    check_runnable(scenario, trust_fmu=False)


def measure_trial(job: Job) -> Measured:
    """A tuning store's measure of one trial (a single-set scenario): the run's metrics,
    ``tuning_cost`` among them, and the cost's two terms (emasim.analysis.report.tuning_terms),
    recording only what they read. A run that diverges raises, and its row says so. Module
    level, so that a Dask worker process can run it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # eq. 37 notices, irrelevant while searching
        result = run_scenario(metrics_only(job.scenario), label=job.label)
    terms = tuning_terms(result, job.scenario.experiment().max_current_A)
    return Measured(result.metrics | dict(zip(TERMS.values(), terms, strict=True)), {})


def trial_id(label: str, kind: str, number: int, params: dict) -> str:
    """A trial's run id: its set, its kind and number, and a digest of the set's label and
    its gains (a trial asked with other gains is another run)."""
    key = json.dumps([label, params], sort_keys=True).encode()
    return f"{slug(label)}-{kind}{number:06d}-{hashlib.sha256(key).hexdigest()[:8]}"


def trial_value(row: dict, label: str) -> tuple[float, float, float]:
    """A trial's cost and its two terms from its row in the store; DIVERGED_COST and NaN
    terms for a run that diverged; EmasimError for one that failed."""
    status = str(row["status"])
    if status.startswith(DIVERGED):
        return DIVERGED_COST, math.nan, math.nan
    if status != OK:
        raise EmasimError(f"tune {label}: trial {row[RUN_ID]}: {status}")
    values = [row.get(key) for key in (COST_METRIC, TERMS[TRACKING], TERMS[CHATTER])]
    cost, tracking, chatter = (math.nan if v is None else float(v) for v in values)  # JSON null
    return cost, tracking, chatter


def _completed_values(study) -> list[float]:
    """The costs of the search's completed trials, in trial order (the neighbourhood check's
    points left out)."""
    complete = optuna.trial.TrialState.COMPLETE
    return [
        t.value
        for t in sorted(study.trials, key=lambda t: t.number)
        if t.state == complete and NEIGHBOUR not in t.user_attrs
    ]


def neighbour_points(
    centre: dict[str, float], controllers, count: int, seed: int
) -> list[dict[str, float]]:
    """``count`` points about ``centre`` ('loop.field' -> value): a Latin hypercube
    (scipy.stats.qmc, seeded) over NEIGHBOUR_SPAN either way of each knob in log space, kept
    strictly inside what each field's validation admits."""
    from scipy.stats import qmc

    keys = sorted(centre)
    unit = qmc.LatinHypercube(d=len(keys), seed=seed).random(count)
    points = []
    for row in unit:
        point = {}
        for key, u in zip(keys, row, strict=True):
            loop, field = key.split(".", 1)
            low, high = hard_limits(getattr(controllers, loop), field)
            value = centre[key] * NEIGHBOUR_SPAN ** (2.0 * u - 1.0)
            # strictly inside: a limit may be exclusive (gt, lt)
            point[key] = float(min(max(value, low * (1 + 1e-9)), high * (1 - 1e-9)))
        points.append(point)
    return points


def check_neighbourhood(
    study, controllers, count: int, seed: int, batch: int, evaluate_params
) -> dict:
    """Prove the optimum converged: run the cost at ``count`` :func:`neighbour_points` about
    the best trial and record the best neighbour. Returns {"points", "best_cost_ratio" (the
    best neighbour's cost over the optimum's: below 1 - analysis.report.CHECK_TOLERANCE, the
    search had not converged, and the neighbour, now the study's best, is the tuned set),
    "best_point"}.

    The points are trials of the study (user attribute NEIGHBOUR: check number x
    CHECK_STRIDE + their index); each check is recorded in the study's user attribute
    ``checks``. A check that found a better neighbour is followed by one about it
    (tune_variant: at most CHECK_ROUNDS checks)."""
    checks = list(study.user_attrs.get("checks", []))
    first = len(checks) * CHECK_STRIDE
    centre, cost = dict(study.best_params), study.best_value
    after = len(_completed_values(study))
    check = {"centre": centre, "cost": cost, "after": after, "first": first}
    study.set_user_attr("checks", [*checks, check])
    points = neighbour_points(centre, controllers, count, seed)
    for start in range(0, len(points), batch):
        chunk = range(start, min(start + batch, len(points)))
        costs = evaluate_params([points[i] for i in chunk], [first + i for i in chunk])
        for i, (value, tracking, chatter) in zip(chunk, costs, strict=True):
            study.add_trial(
                optuna.trial.create_trial(
                    params=points[i],
                    distributions={
                        k: optuna.distributions.FloatDistribution(v, v * (1 + 1e-12), log=True)
                        for k, v in points[i].items()
                    },
                    value=value,
                    user_attrs={NEIGHBOUR: first + i, TRACKING: tracking, CHATTER: chatter},
                )
            )
    neighbours = [
        t for t in study.trials if t.user_attrs.get(NEIGHBOUR, -1) >= first and t.value is not None
    ]
    best = min(neighbours, key=lambda t: t.value)
    return {
        "points": len(neighbours),
        "best_cost_ratio": best.value / cost,
        "best_point": {k: best.params[k] for k in sorted(best.params)},
    }


def tune_variant(
    scenario,
    label: str,
    controllers,
    budget: Budget | int,
    store: Store,
    seed: int = 0,
    progress=None,
    client=None,
) -> Tuned:
    """Tune one controller set on ``scenario`` under ``budget`` (emasim.search_rules; a bare
    int is that many trials: Budget.fixed), its trials run as jobs of ``store``
    (:func:`tuning_store`, made for this ``seed`` and ``client``); ``progress(done, cap)`` is
    told the finished trials after each batch. The trials run as many at once as ``client``
    has worker threads (default: one at a time, in this process); the sampler is told their
    costs in trial order, so a seed and a batch size give the same search whatever the
    schedule, and the same search run again finds its finished trials in the store."""
    if isinstance(budget, int):
        budget = Budget.fixed(budget)
    if store.record.get("batch") != trials_at_once(client):
        raise ValueError("a tuning store is made for the client its trials run on")
    controllers = with_explicit_gains(controllers, scenario)
    base = search_space(controllers)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    start = {}
    for key in base:
        loop, field = key.split(".", 1)
        value = getattr(getattr(controllers, loop), field)
        if value is not None:
            start[key] = float(value)
            low, high = base[key]
            base[key] = (min(low, start[key]), max(high, start[key]))  # the gains given included
    study.enqueue_trial(start, user_attrs={GIVEN: True})
    space = dict(base)
    rounds = round_start = 0
    batch = trials_at_once(client)

    def evaluate_params(points: list[dict], numbers: list[int], kind: str = "n"):
        jobs = [
            Job(
                scenario.model_copy(
                    update={"controllers": _controllers_with(controllers, params), "compare": []}
                ),
                label,
                {
                    RUN_ID: trial_id(label, kind, number, params),
                    "set": label,
                    "trial": f"{kind}{number}",
                    **params,
                },
            )
            for params, number in zip(points, numbers, strict=True)
        ]
        store.add(jobs)
        rows = store.run_pending(client, inline=client is None)
        return [trial_value(rows[job.tags[RUN_ID]], label) for job in jobs]

    def evaluate(trials):
        return evaluate_params([t.params for t in trials], [t.number for t in trials], "t")

    with store.opened():
        while True:
            cap = budget.cap(len(space)) * (rounds + 1)
            stopped = _search(study, space, cap, round_start, budget, batch, evaluate, progress)
            best = study.best_params
            sides = {key: bound_side(best[key], *space[key]) for key in space}
            sides = {key: side for key, side in sides.items() if side is not None}
            if not sides or rounds >= budget.widenings:
                break
            wider = dict(space)
            for key, side in sides.items():
                loop, field = key.split(".", 1)
                wider[key] = widened(
                    *space[key], side, hard_limits(getattr(controllers, loop), field)
                )
            if wider == space:  # every bound it sits on is a limit of the config itself
                break
            space, rounds, round_start = wider, rounds + 1, len(_completed_values(study))
            study.set_user_attr("widenings", rounds)
        values = _completed_values(study)
        if not values:
            raise InputError(f"tune {label}: no trial completed; raise --trials")
        check = None
        for _ in range(CHECK_ROUNDS if budget.neighbours else 0):
            check = check_neighbourhood(
                study, controllers, budget.neighbours, seed, batch, evaluate_params
            )
            if check["best_cost_ratio"] >= 1.0 - CHECK_TOLERANCE:
                break  # converged: no neighbour is better by more than the tolerance
        given = [t.value for t in study.trials if t.value is not None and t.user_attrs.get(GIVEN)]
        return Tuned(
            _controllers_with(controllers, study.best_params),
            study.best_value,
            given[0] if given else None,
            study,
            len(values),
            stopped,
            {key: span for key, span in space.items() if span != base[key]},
            sides,
            check,
        )


def _search(study, space, cap, round_start, budget, batch, evaluate, progress) -> str:
    """Ask, run and tell trials over ``space`` until ``cap`` trials have completed ("budget")
    or, once this round has run the budget's window of trials, the search has converged
    ("converged")."""
    distributions = {
        k: optuna.distributions.FloatDistribution(*s, log=True) for k, s in space.items()
    }
    while True:
        values = _completed_values(study)
        if progress is not None:
            progress(min(len(values), cap), cap)
        if len(values) >= cap:
            return "budget"
        patience = budget.window(len(space))
        if (
            patience
            and len(values) - round_start >= patience
            and converged(values, patience, budget.tolerance)
        ):
            return "converged"
        trials = [study.ask(distributions) for _ in range(min(batch, cap - len(values)))]
        for trial, (cost, tracking, chatter) in zip(trials, evaluate(trials), strict=True):
            trial.set_user_attr(TRACKING, tracking)
            trial.set_user_attr(CHATTER, chatter)
            study.tell(trial, cost)


def trials_at_once(client) -> int:
    """The batch size of the ask-and-tell search: the Dask client's worker threads (1 without
    a client). With the seed it fixes the search, so the record states it."""
    return 1 if client is None else max(1, sum(client.nthreads().values()))


def tune_scenario(
    raw: dict,
    scenario,
    budget: Budget | int,
    store: Store,
    seed: int = 0,
    report=None,
    progress=None,
    client=None,
):
    """Tune every controller set of a scenario under the same rule (``budget``, see
    :func:`tune_variant`), their trials jobs of ``store`` (:func:`tuning_store`); return the
    raw scenario table with the tuned gains written in, and label -> :class:`Tuned`.

    ``raw`` is the scenario file's table (as read, before validation); the tuned values are
    written as overrides of each controller set, and a ``tuning`` record says how, with each
    set's trials, why it stopped, the ranges widened and any optimum left on a bound.
    ``report(label, tuned)`` after each set, ``progress(label, done, cap)`` after each batch.
    """
    if isinstance(budget, int):
        budget = Budget.fixed(budget)
    tuned_raw = dict(raw)
    results = {}
    entries = list(tuned_raw["compare"]) if scenario.compare else None
    for i, (label, variant) in enumerate(scenario.variants()):
        result = tune_variant(
            variant,
            label,
            variant.controllers,
            budget,
            store,
            seed,
            None if progress is None else lambda d, n, lb=label: progress(lb, d, n),
            client,
        )
        results[label] = result
        if report is not None:
            report(label, result)
        tuned = result.controllers
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
            entry["controllers"] = _with_overrides(entry.get("controllers", {}), overrides, tuned)
            entries[i] = entry
        else:
            tuned_raw["controllers"] = _with_overrides(
                tuned_raw.get("controllers", {}), overrides, tuned
            )
    if entries is not None:
        tuned_raw["compare"] = entries
    tuned_raw["tuning"] = {
        "method": "optuna TPE, log-uniform over each controller's tunable_ranges, "
        "first trial = the gains given",
        "budget": budget.describe(),
        "seed": seed,
        "batch": trials_at_once(client),
        "cost": COST_FORMULA,
        "sets": {label: result.record() for label, result in results.items()},
    }
    return tuned_raw, results


def _with_overrides(section, overrides: dict, tuned) -> dict:
    """A controllers table (or cascade name) with per-loop overrides laid over it, less the
    keys the tuned Controllers ``tuned`` leave unset (None: a bandwidth its explicit gains
    replace)."""
    section = {"cascade": section} if isinstance(section, str) else dict(section)
    for loop, values in overrides.items():
        config = getattr(tuned, loop)
        merged = {**section.get(loop, {}), **values}
        section[loop] = {k: v for k, v in merged.items() if getattr(config, k, v) is not None}
    return section
