"""The headline verdicts over the bench's plant uncertainty: a Monte Carlo study of each bench
experiment, the gains fixed at their nominal tuning, PID, the industrial PID and the hybrid run
on the same plants.

The uncertainty (UNCERTAINTY, ``--vary`` specs of :mod:`.variation`) is the table of
:mod:`.uncertainty`, each range with its reason: friction, backlash, hinge clearance, load
inertia, the standing preload over the loader's range, the screw's, anchorage's and rudder
shaft's stiffness and damping, the joints' contact stiffness, the load motor's bandwidth, the
computation delay, the speed filter, the motor's kt, J, R and L, the rudder encoder's accuracy
error, and the sensor-noise seed. The draws' seed is ``seed`` (DEFAULT_SEED unless given).

For each headline figure and the tuning cost, over the paired samples, against each PID
variant (BASELINES): the hybrid's win rate (the fraction of plants on which its |metric| is
below the baseline's; a run that diverged loses), with
its exact 95 % (Clopper-Pearson) interval, and the median improvement
100 * (|PID| - |hybrid|) / |PID| with a distribution-free 95 % interval (the order statistics
that bracket the median with at least 95 % probability, binomial(n, 1/2)); and the 5 % and
95 % quantiles of the improvement, its spread over the plants; the sampled parameter the
improvement follows most (the largest |Spearman rank correlation|); and the verdict's
sensitivity (:func:`thirds`): the win rate in the lower, middle and upper third of each sampled
parameter's values, and the parameter whose thirds' win rates spread most.

The studies live in ``runs/robustness/<scenario>-<key>-<runs>/``, ``key`` a hash of the
experiment's resolved scenario, the uncertainty, the draws' seed and the emasim version: a
study of the same experiments, seed and version is found again, resumed when interrupted, and
shown by a plain ``emasim reproduce`` (of that ``--seed``).
"""

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from ..analysis.judged import (
    BENCH_SINE_ROWS,
    BENCH_STEP_ROWS,
    HEADLINE,
    HYBRID_LABEL,
    INDUSTRIAL_LABEL,
    PID_LABEL,
)
from ..naming import RUNS_ROOT
from .store import OK
from .study import StudySpec, largest_complete, run_studies
from .uncertainty import COLUMNS, SEED, UNCERTAINTY

SCENARIOS = ("bench-step", "bench-sine")
DEFAULT_RUNS = 200
DEFAULT_SEED = 0  # the seed of the draws (StudySpec.seed) unless --seed gives another
BASELINES = (PID_LABEL, INDUSTRIAL_LABEL)  # the hybrid is judged against both PID variants
COST = "tuning_cost"
CONFIDENCE = 0.95
SPREAD = (0.05, 0.95)  # the quantiles of the improvement over the plants that show its spread
ROOT = RUNS_ROOT / "robustness"


def figures() -> dict[str, tuple[str, str]]:
    """figure -> (scenario, metric): the five headline figures, and the tuning cost of each
    bench experiment."""
    rows = {"bench_step": BENCH_STEP_ROWS, "bench_sine": BENCH_SINE_ROWS}
    out = {
        name: (experiment.replace("_", "-"), rows[experiment][row][0])
        for name, (experiment, row, _) in HEADLINE.items()
    }
    for scenario in SCENARIOS:
        out[f"{scenario.replace('-', '_')}_tuning_cost"] = (scenario, COST)
    return out


def spec_for(scenario: str, runs: int, seed: int = DEFAULT_SEED) -> StudySpec:
    return StudySpec(
        scenario, vary=UNCERTAINTY, runs=runs, seed=seed, labels=(*BASELINES, HYBRID_LABEL)
    )


def study_key(scenario: str, specs: tuple[str, ...] = UNCERTAINTY, seed: int = DEFAULT_SEED) -> str:
    """12 hex digits of the experiment's resolved scenario, what a study varies (``specs``),
    the draws' ``seed``, the emasim version and the digest of its source: another code's
    study is never resumed, nor shown as this code's."""
    from ..scenarios.loader import load_scenario
    from ..version import __version__
    from .runs import source_digest

    resolved = load_scenario(scenario).model_dump(mode="json")
    text = json.dumps([resolved, specs, seed, __version__, source_digest()], sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def study_folder(scenario: str, runs: int, root: Path = ROOT, seed: int = DEFAULT_SEED) -> Path:
    return root / f"{scenario}-{study_key(scenario, seed=seed)}-{runs}"


def run_robustness(
    runs: int = DEFAULT_RUNS,
    root: Path = ROOT,
    progress=None,
    client=None,
    scheduler=None,
    seed: int = DEFAULT_SEED,
) -> dict:
    """Run (or resume) the Monte Carlo of every bench experiment, its draws from ``seed``;
    return :func:`verdicts`. ``progress(done, total)`` counts the runs of all experiments
    together."""
    studies = {s: (spec_for(s, runs, seed), study_folder(s, runs, root, seed)) for s in SCENARIOS}
    tables = run_studies(studies, progress, client, scheduler)
    return verdicts(tables)


def latest(root: Path = ROOT, seed: int = DEFAULT_SEED) -> dict | None:
    """The verdicts of the largest complete robustness study of today's experiments, draws'
    ``seed`` and version, or None when there is none."""
    tables = {}
    for scenario in SCENARIOS:
        prefix = f"{scenario}-{study_key(scenario, seed=seed)}"
        found = largest_complete(root, prefix, len(BASELINES) + 1)
        if found is None:
            return None
        tables[scenario] = found[1]
    return verdicts(tables)


def sensitivity(table, metric: str, baseline: str = PID_LABEL) -> dict:
    """The sampled parameter the improvement over ``baseline`` follows most: the varied column
    with the largest |Spearman rank correlation| with the per-sample improvement (the seed
    left out)."""
    from scipy.stats import spearmanr

    samples, pid, hybrid = _by_sample(table, metric, baseline)
    gain = improvement_pct(pid, hybrid)
    usable = np.isfinite(gain)
    mine = table[table["label"] == baseline].set_index("sample").loc[samples]
    best = {}
    for name in COLUMNS:
        if name == SEED or name not in mine or usable.sum() < 3:
            continue
        values = mine[name].to_numpy()[usable]
        if np.ptp(values) == 0.0 or np.ptp(gain[usable]) == 0.0:
            continue  # a constant has no rank correlation: it cannot be what the gain follows
        rho = float(spearmanr(values, gain[usable]).statistic)
        if math.isfinite(rho) and abs(rho) > abs(best.get("spearman", 0.0)):
            best = {"parameter": name, "spearman": rho}
    return best


THIRDS = (1.0 / 3.0, 2.0 / 3.0)  # the quantiles that split a parameter's values in thirds


def thirds(table, metric: str, baseline: str = PID_LABEL) -> dict:
    """The verdict's sensitivity: ``sensitivity_thirds``, parameter name -> the hybrid's win
    rate against ``baseline`` on the samples in the lower, middle and upper third of that
    parameter's sampled values (split at their 1/3 and 2/3 quantiles, a value on a split in
    the lower third; None for a third with no sample), for each varied column of the table
    but the seed; and ``moves_most``: the parameter whose thirds' win rates spread most
    (``spread``, the largest rate less the smallest; the first in the table's order on a
    tie), empty when none has two thirds."""
    samples, pid, hybrid = _by_sample(table, metric, baseline)
    keep = _defined(pid, hybrid)
    won = (hybrid < pid)[keep]
    mine = table[table["label"] == baseline].set_index("sample").loc[samples]
    rates, most = {}, {}
    for column, name in COLUMNS.items():
        if column == SEED or column not in mine or not keep.any():
            continue
        values = mine[column].to_numpy(dtype=float)[keep]
        part = np.searchsorted(np.quantile(values, THIRDS), values, side="left")
        rates[name] = [
            float(won[part == k].mean()) if (part == k).any() else None for k in range(3)
        ]
        found = [r for r in rates[name] if r is not None]
        spread = max(found) - min(found)
        if len(found) > 1 and spread > most.get("spread", -1.0):
            most = {"parameter": name, "spread": spread}
    return {"sensitivity_thirds": rates, "moves_most": most}


def paired(table, metric: str, baseline: str = PID_LABEL) -> tuple[np.ndarray, np.ndarray]:
    """|metric| of ``baseline`` and of the hybrid on each sample both ran (diverged: inf)."""
    _, pid, hybrid = _by_sample(table, metric, baseline)
    return pid, hybrid


def _by_sample(
    table, metric: str, baseline: str = PID_LABEL
) -> tuple[list, np.ndarray, np.ndarray]:
    """(the samples both controller sets ran, ``baseline``'s and the hybrid's |metric| on
    each)."""
    values = {}
    for label in (baseline, HYBRID_LABEL):
        mine = table[table["label"] == label].set_index("sample")
        value = np.abs(mine[metric].astype(float)) if metric in mine else np.nan
        values[label] = dict(
            zip(mine.index, np.where(mine["status"] == OK, value, np.inf), strict=True)
        )
    samples = sorted(set(values[baseline]) & set(values[HYBRID_LABEL]))
    pid = np.array([values[baseline][s] for s in samples])
    hybrid = np.array([values[HYBRID_LABEL][s] for s in samples])
    return samples, pid, hybrid


def _defined(pid: np.ndarray, hybrid: np.ndarray) -> np.ndarray:
    """The samples a verdict counts: not both diverged, neither metric missing."""
    return ~(np.isinf(pid) & np.isinf(hybrid)) & ~(np.isnan(pid) | np.isnan(hybrid))


def improvement_pct(pid: np.ndarray, hybrid: np.ndarray) -> np.ndarray:
    """100 * (|PID| - |hybrid|) / |PID| per sample: 100 when PID alone diverged, -inf when the
    hybrid alone did, nan when both did or PID's value is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 100.0 * (pid - hybrid) / pid
    out = np.where(np.isinf(pid) & np.isfinite(hybrid), 100.0, out)
    return np.where(np.isfinite(pid) & np.isinf(hybrid), -np.inf, out)


def median_interval(x: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Distribution-free interval of the median: the order statistics x(k) and x(n+1-k), with
    k the largest rank such that P(k <= B <= n-k) >= confidence for B ~ binomial(n, 1/2)."""
    from scipy.stats import binom

    x = np.sort(x)
    n = x.size
    k = int(binom.ppf((1.0 - confidence) / 2.0, n, 0.5))  # P(B < k) <= alpha/2
    if k < 1:
        return (-math.inf, math.inf)
    return float(x[k - 1]), float(x[n - k])


def verdict(pid: np.ndarray, hybrid: np.ndarray) -> dict:
    """runs, win rate and its 95 % interval, median improvement (%) with its 95 % interval, and
    the improvement's 5 % and 95 % quantiles."""
    from scipy.stats import binomtest

    defined = _defined(pid, hybrid)
    pid, hybrid = pid[defined], hybrid[defined]
    n = int(pid.size)
    if n == 0:
        return {"runs": 0}
    wins = int(np.count_nonzero(hybrid < pid))
    rate = binomtest(wins, n).proportion_ci(CONFIDENCE, method="exact")
    gain = improvement_pct(pid, hybrid)
    gain = gain[~np.isnan(gain)]
    low, high = median_interval(gain)
    spread = np.quantile(gain, SPREAD, method="nearest")  # no interpolation with an inf
    return {
        "runs": n,
        "win_rate": wins / n,
        "win_rate_ci95": [float(rate.low), float(rate.high)],
        "median_improvement_pct": float(np.median(gain)),
        "ci95_pct": [low, high],
        "improvement_p05_pct": float(spread[0]),
        "improvement_p95_pct": float(spread[1]),
    }


def verdicts(tables: dict) -> dict:
    """figure -> verdict against PID (with its scenario and metric), from each experiment's
    study table, and ``against``: baseline -> the verdict against each of BASELINES, each with
    its sensitivity (:func:`sensitivity`, :func:`thirds`)."""
    out = {}
    for name, (scenario, metric) in figures().items():
        if scenario in tables:
            table = tables[scenario]
            against = {}
            for baseline in BASELINES:
                pid, hybrid = paired(table, metric, baseline)
                against[baseline] = (
                    verdict(pid, hybrid)
                    | {"most_sensitive_to": sensitivity(table, metric, baseline)}
                    | thirds(table, metric, baseline)
                )
            out[name] = {"scenario": scenario, "metric": metric, **against[PID_LABEL]}
            out[name]["against"] = against
    return out
