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

Studies live in SQLite by default (any SQLAlchemy URL works). A study is named by the scenario,
the label and a hash of the fully resolved single-run scenario (:func:`study_key`), so a changed
plant, sensor, load or solver starts a new study, and an unchanged one resumes where it stopped.
Trials send a heartbeat: a trial whose process was killed is failed once its heartbeat is
HEARTBEAT_GRACE_S old and run again with the same gains, so a kill at any moment, during the
first trial included, costs at most that trial. Several machines can share a study.
"""

import hashlib
import json
import sqlite3
import warnings
from pathlib import Path

import optuna

from .analysis.report import tuning_cost
from .errors import InputError, SimulationDiverged
from .sim.engine import simulate

DIVERGED_COST = 1e3
LOOPS = ("position", "speed")
HEARTBEAT_S = 1  # a running trial tells the storage it is alive this often
HEARTBEAT_GRACE_S = 5  # ... and is taken as killed when silent this long
GIVEN = "given_gains"  # user attribute of the first trial: the scenario's own gains
TUNED_HEADER = "# emasim tune:"  # first line of every tuned scenario file emasim writes


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
    if path is not None:
        if path.exists() and not (path.is_file() and _is_optuna_database(path)):
            raise InputError(
                f"--storage {url}: {path} exists and is not an Optuna study database; "
                "emasim never writes into it (choose another path)"
            )
        check_parents(path, "--storage")
        path.parent.mkdir(parents=True, exist_ok=True)
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
    stay (tomlkit); only the values that changed are rewritten."""
    import tomlkit

    if original.startswith(TUNED_HEADER):  # re-tuning a tuned file: one header
        original = original.partition("\n")[2]
    document = tomlkit.parse(original)
    _lay_over(document, tuned_raw)
    return f"{TUNED_HEADER} {name} with tuned gains (see [tuning])\n" + tomlkit.dumps(document)


def _lay_over(table, values: dict) -> None:
    """Make the tomlkit ``table`` hold ``values``, keeping every item (and its comments) whose
    value is unchanged: tables and arrays of tables of the same length are entered, other
    values replaced, keys that ``values`` lacks removed."""
    for key in [k for k in table if k not in values]:
        del table[key]
    for key, value in values.items():
        old = table.get(key)
        if isinstance(value, dict) and isinstance(old, dict):
            _lay_over(old, value)
        elif _tables(value) and _tables(old) and len(old) == len(value):
            for item, new in zip(old, value, strict=True):
                _lay_over(item, new)
        elif old is None or _plain(old) != value:
            table[key] = value


def _tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _plain(value):
    """A tomlkit item as plain Python data."""
    return value.unwrap() if hasattr(value, "unwrap") else value


def tune_variant(
    scenario, label: str, controllers, trials: int, storage, seed: int = 0, progress=None
):
    """Tune one controller set on ``scenario``; returns (tuned Controllers, best cost, the cost
    of the given gains or None while their trial is unfinished, study). ``storage`` is an
    Optuna storage or URL (see :func:`open_storage`); ``progress(done, trials)`` is told the
    finished trials after each one (a resumed study's earlier trials included)."""
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
    if isinstance(storage, str):
        storage = open_storage(storage)
    study = optuna.create_study(
        study_name=f"{scenario.name}:{label}:{study_key(scenario)}",
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
        study.enqueue_trial(start, user_attrs={GIVEN: True})
    complete = optuna.trial.TrialState.COMPLETE
    done = sum(t.state == complete for t in study.trials)
    callbacks = []
    if progress is not None:
        progress(min(done, trials), trials)

        def told(study_now, _):
            finished = sum(t.state == complete for t in study_now.trials)
            progress(min(finished, trials), trials)

        callbacks.append(told)
    study.optimize(objective, n_trials=max(0, trials - done), callbacks=callbacks)
    if not any(t.state == complete for t in study.trials):
        raise InputError(f"tune {label}: no trial completed; raise --trials")
    given = [t.value for t in study.trials if t.state == complete and t.user_attrs.get(GIVEN)]
    tuned = _controllers_with(controllers, study.best_params)
    return tuned, study.best_value, (given[0] if given else None), study


def tune_scenario(
    raw: dict,
    scenario,
    trials: int,
    storage: str,
    seed: int = 0,
    report=None,
    progress=None,
):
    """Tune every controller set of a scenario with the same budget; return the raw scenario
    table with the tuned gains written in, and label -> (cost before, cost after).

    ``raw`` is the scenario file's table (as read, before validation); the tuned values are
    written as overrides of each controller set, and a ``tuning`` record says how.
    ``report(label, cost before, cost after)`` after each set, ``progress(label, done,
    trials)`` after each trial.
    """
    tuned_raw = dict(raw)
    costs = {}
    entries = list(tuned_raw["compare"]) if scenario.compare else None
    for i, (label, variant) in enumerate(scenario.variants()):
        tuned, best, before, _ = tune_variant(
            variant,
            label,
            variant.controllers,
            trials,
            storage,
            seed,
            None if progress is None else lambda d, n, lb=label: progress(lb, d, n),
        )
        costs[label] = (before, best)
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
