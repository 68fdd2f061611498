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
the ranges widened and any optimum still on a bound. The trials of a batch run through the
study facility (emasim.experiments.batch.map_runs), as many at once as the Dask client has
workers, and are told to the sampler in trial order.

Studies live in SQLite by default (any SQLAlchemy URL works). A study is named by the scenario,
the label and a hash of the fully resolved single-run scenario (:func:`study_key`), so a changed
plant, sensor, load or solver starts a new study, and an unchanged one resumes where it stopped.
Running trials send a heartbeat: a trial whose process was killed is failed once its heartbeat
is HEARTBEAT_GRACE_S old and asked again with the same gains by the next batch, so a kill at any
moment, during the first trial included, costs at most that batch. Several processes or
machines can tune one study through a shared RDB storage (e.g. PostgreSQL), each asking and
telling its own trials.
"""

import contextlib
import hashlib
import json
import math
import sqlite3
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

import optuna

from .analysis.pareto import pareto_front, thinned
from .analysis.report import CHECK_TOLERANCE, COST_FORMULA, tuning_terms, weighted_cost
from .config import hard_limits
from .errors import InputError, SimulationDiverged
from .experiments.runs import simulate_scenario
from .search_rules import Budget, bound_side, converged, widened
from .sim.cosim import check_runnable
from .toml_text import laid_over

DIVERGED_COST = 1e3
LOOPS = ("position", "speed")
HEARTBEAT_S = 1  # a running trial tells the storage it is alive this often
HEARTBEAT_GRACE_S = 5  # ... and is taken as killed when silent this long
GIVEN = "given_gains"  # user attribute of the first trial: the scenario's own gains
NEIGHBOUR = "neighbour"  # user attribute of a neighbourhood-check point: its index
CHECK_STRIDE = 100_000  # neighbour indices of successive checks of one study start this apart
CHECK_ROUNDS = 3  # checks about each new optimum a better neighbour gives, at most
NEIGHBOUR_SPAN = 1.5  # ... each knob within x1.5 either way (+-50 %, in log space)
TRACKING, CHATTER = "tracking", "chatter"  # user attributes: a trial's two cost terms
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


def default_storage(path: Path) -> str:
    """The SQLite URL of a study database file."""
    return f"sqlite:///{path}"


def _sqlite_path(url: str) -> Path | None:
    return Path(url.removeprefix("sqlite:///")) if url.startswith("sqlite:///") else None


def _is_optuna_database(path: Path) -> bool:
    """True for an SQLite file that holds Optuna's tables (so tuning only adds studies)."""
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as db:
            names = {row[0] for row in db.execute("SELECT name FROM sqlite_master")}
    except sqlite3.Error:
        return False
    return {"studies", "trials", "version_info"} <= names


def open_storage(url: str):
    """Optuna's RDB storage at ``url``, with heartbeats and retries of killed trials.

    Refused with one line: an SQLite file that exists but is not an Optuna database (it is
    never written to), a folder, a URL no database driver takes, a database that cannot open.
    """
    from .output import check_parents

    path = _sqlite_path(url)
    if path is None:
        return _rdb_storage(url)
    check_parents(path, "--storage")
    path.parent.mkdir(parents=True, exist_ok=True)
    with _creating(path):
        if path.exists() and not (path.is_file() and _is_optuna_database(path)):
            raise InputError(
                f"--storage {url}: {path} exists and is not an Optuna study database; "
                "emasim never writes into it (choose another path)"
            )
        if not path.exists():
            return _rdb_storage(url)  # its tables made under the lock
    return _rdb_storage(url)


def _creating(path: Path):
    """Hold the lock on ``path``'s folder while the SQLite database there is checked and its
    tables made: two tunings that first use a new storage at once would both create them
    ("table ... already exists"); the second waits, then finds them."""
    from .output import locked

    return locked(path.parent)


def _rdb_storage(url: str):
    """Optuna's RDBStorage at ``url`` (open_storage), or InputError with its first line."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            return optuna.storages.RDBStorage(
                url,
                heartbeat_interval=HEARTBEAT_S,
                grace_period=HEARTBEAT_GRACE_S,
                heartbeat_stale_trial_callback=optuna.storages.RetryHeartbeatStaleTrialCallback(),
            )
    except Exception as err:  # SQLAlchemy raises many kinds: say the first line of it
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise InputError(f"--storage {url}: cannot open ({first})") from None


def study_key(scenario) -> str:
    """A short hash of the fully resolved single-run scenario (its tuning record left out)."""
    resolved = scenario.model_dump(mode="json", exclude={"tuning"})
    text = json.dumps(resolved, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


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


def trial_cost(scenario, max_current: float) -> tuple[float, float, float]:
    """The tuning cost of one candidate (a single-run scenario) and its two terms (tracking,
    chattering: emasim.analysis.report.tuning_terms); DIVERGED_COST and NaN terms if it
    diverges. Module level, so that a Dask worker process can run it."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # eq. 37 notices, irrelevant while searching
            result = simulate_scenario(scenario)  # a co-simulation where one is set
    except SimulationDiverged:
        return DIVERGED_COST, math.nan, math.nan
    tracking, chatter = tuning_terms(result, max_current)
    return weighted_cost(tracking, chatter), tracking, chatter


@contextlib.contextmanager
def _heartbeats(storage, trials):
    """Tell the storage, every HEARTBEAT_S, that ``trials`` are alive while they run (the
    ask-and-tell loop has no heartbeat thread of Optuna's own)."""
    stop = threading.Event()

    def beat():
        while True:
            for trial in trials:
                storage.record_heartbeat(trial._trial_id)
            if stop.wait(HEARTBEAT_S):
                return

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


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


def _improved(study, check: dict) -> bool:
    """True when the study's best is better than ``check``'s optimum by more than
    CHECK_TOLERANCE: one of its points was, and is the new optimum."""
    return study.best_value < (1.0 - CHECK_TOLERANCE) * check["cost"]


def check_neighbourhood(
    study, controllers, count: int, seed: int, batch: int, evaluate_params
) -> dict:
    """Prove the optimum converged: run the cost at ``count`` :func:`neighbour_points` about
    the best trial and record the best neighbour. Returns {"points", "best_cost_ratio" (the
    best neighbour's cost over the optimum's: below 1 - analysis.report.CHECK_TOLERANCE, the
    search had not converged, and the neighbour, now the study's best, is the tuned set),
    "best_point"}.

    The points are trials of the study (user attribute NEIGHBOUR: check number x
    CHECK_STRIDE + their index), so an interrupted check resumes; a search that went on after
    a check (a larger budget), or whose check found a better neighbour, is checked again about
    its new optimum (tune_variant: at most CHECK_ROUNDS checks)."""
    searched = len(_completed_values(study))
    checks = list(study.user_attrs.get("checks", []))
    if not checks or checks[-1]["after"] != searched or _improved(study, checks[-1]):
        checks.append(
            {
                "centre": dict(study.best_params),
                "cost": study.best_value,
                "after": searched,
                "first": len(checks) * CHECK_STRIDE,
            }
        )
        study.set_user_attr("checks", checks)
    first = checks[-1].get("first", (len(checks) - 1) * CHECK_STRIDE)
    centre, cost = checks[-1]["centre"], checks[-1]["cost"]
    points = neighbour_points(centre, controllers, count, seed)
    done = {t.user_attrs[NEIGHBOUR] - first for t in study.trials if NEIGHBOUR in t.user_attrs}
    todo = [i for i in range(len(points)) if i not in done]
    for start in range(0, len(todo), batch):
        chunk = todo[start : start + batch]
        for i, (value, tracking, chatter) in zip(
            chunk, evaluate_params([points[i] for i in chunk]), strict=True
        ):
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
    storage,
    seed: int = 0,
    progress=None,
    client=None,
) -> Tuned:
    """Tune one controller set on ``scenario`` under ``budget`` (emasim.search_rules; a bare
    int is that many trials: Budget.fixed). ``storage`` is an Optuna storage or
    URL (:func:`open_storage`); ``progress(done, cap)`` is told the finished trials after each
    batch (a resumed study's earlier trials included). The trials run through the study
    facility's :func:`emasim.experiments.batch.map_runs`, as many at once as ``client`` has
    worker threads (default: one at a time, in this process); the sampler is told their costs
    in trial order, so a seed and a batch size give the same search whatever the schedule."""
    if isinstance(budget, int):
        budget = Budget.fixed(budget)
    controllers = with_explicit_gains(controllers, scenario)
    base = search_space(controllers)
    max_current = scenario.plant.motor.max_current_A
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    if isinstance(storage, str):
        storage = open_storage(storage)
    study = optuna.create_study(
        study_name=f"{scenario.name}:{label}:{study_key(scenario)}",
        storage=storage,
        load_if_exists=True,
        direction="minimize",
        sampler=optuna.samplers.TPESampler(seed=seed),
    )
    start = {}
    for key in base:
        loop, field = key.split(".", 1)
        value = getattr(getattr(controllers, loop), field)
        if value is not None:
            start[key] = float(value)
            low, high = base[key]
            base[key] = (min(low, start[key]), max(high, start[key]))  # the gains given included
    if not study.trials:
        study.enqueue_trial(start, user_attrs={GIVEN: True})
    attrs = study.user_attrs
    space = {key: tuple(span) for key, span in attrs.get("space", base).items()}
    rounds, round_start = attrs.get("widenings", 0), attrs.get("round_start", 0)
    batch = trials_at_once(client)

    def evaluate_params(points: list[dict]) -> list[tuple[float, float, float]]:
        candidates = [
            (
                scenario.model_copy(
                    update={"controllers": _controllers_with(controllers, params), "compare": []}
                ),
                max_current,
            )
            for params in points
        ]
        if client is None:
            return [trial_cost(*job) for job in candidates]
        from .experiments.batch import map_runs

        return map_runs(trial_cost, candidates, client)

    def evaluate(trials):
        with _heartbeats(storage, trials):
            return evaluate_params([trial.params for trial in trials])

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
            wider[key] = widened(*space[key], side, hard_limits(getattr(controllers, loop), field))
        if wider == space:  # every bound it sits on is a limit of the config itself
            break
        space, rounds, round_start = wider, rounds + 1, len(_completed_values(study))
        study.set_user_attr("space", {key: list(span) for key, span in space.items()})
        study.set_user_attr("widenings", rounds)
        study.set_user_attr("round_start", round_start)
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
        with warnings.catch_warnings():
            # our own heartbeats (_heartbeats) stand in for those of Study.optimize
            warnings.filterwarnings("ignore", message="Heartbeat of storage")
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)  # a killed run's trial: failed, re-asked
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
    storage: str,
    seed: int = 0,
    report=None,
    progress=None,
    client=None,
):
    """Tune every controller set of a scenario under the same rule (``budget``, see
    :func:`tune_variant`); return the raw scenario table with the tuned gains written in, and
    label -> :class:`Tuned`.

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
            storage,
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
