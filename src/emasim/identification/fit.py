"""The keys a fit varies, and the output-error fit: bounded nonlinear least squares.

A key is a scenario's dotted path with its range, ``plant.mass_kg=10:1000`` (the range is the
scenario's default where only the path is given), or a factor on several paths' own values,
``plant.friction.coulomb_Nm,plant.friction.static_Nm=*0.25:4``. The output-error fit
simulates the model with the candidate values and minimises the weighted relative residuals of
the measured outputs (or of features of them: emasim.identification.bench_model),

    r = [w_j (y_j,sim - y_j,meas) / |y_j,meas|  for each output j],

by scipy.optimize.least_squares (trust-region reflective within the ranges, the Jacobian by
forward differences of relative step ``DIFF_STEP``, its columns simulated side by side where a
model allows). ``starts`` > 1 adds starts drawn in the ranges (a scrambled Sobol sequence,
seeded) and keeps the best: a multi-start for a multimodal cost. It stops when a step changes
the cost or the values by less than the tolerance (relative); never on the gradient's size,
which scales with the residuals' (a trace fitted to 1e-5 stopped at its start). Before it
starts, the Jacobian at the start refuses the keys the outputs cannot identify
(:func:`check_identifiable`). At the optimum, the
covariance s^2 (J^T J)^-1 with s^2 = |r|^2 / (N - p) gives each value's 95 % interval (1.96
standard deviations) and the correlations. The residuals of a closed loop are correlated in
time, so these intervals are narrower than the truth; they rank what the data pin down and
what they do not.
"""

import concurrent.futures
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import EmasimError, InputError
from ..experiments.variation import FACTOR

DIFF_STEP = 1e-3
TOLERANCE = 1e-8  # scipy's default ftol and xtol
NULL_DIRECTION = 1e-10  # a singular value this far below the largest: a direction unseen
SENSITIVITY_FLOOR = 1e-6  # a key moving the relative residuals less over its range: unseen
Z95 = 1.959963984540054  # the two-sided 95 % point of the normal distribution


@dataclass(frozen=True)
class Key:
    """A fitted key: its dotted path and range. A ``scaled`` key (``KEY[,KEY...]=*LOW:HIGH``)
    is a factor on the scenario's own value of each of its comma-separated paths, fitted as
    one number (friction's Coulomb, stiction and viscous parts together)."""

    path: str
    low: float
    high: float
    scaled: bool = False

    @property
    def paths(self) -> tuple[str, ...]:
        """The dotted paths the key sets."""
        return tuple(self.path.split(","))

    @property
    def name(self) -> str:
        """How results name it: the path, with FACTOR after a scaled key's."""
        return self.path + FACTOR if self.scaled else self.path


def parse_keys(items: list[str], defaults: list[str]) -> list[Key]:
    """``KEY`` or ``KEY=LOW:HIGH`` items as Keys; a bare KEY takes its range from the
    scenario's ``defaults`` (items of the same form). One InputError line for a bad item."""
    ranges = {}
    for item in defaults:
        key = _key(item, {}, "identify.fit")
        ranges[key.path] = key
    keys = [_key(item, ranges, "--fit") for item in items] if items else list(ranges.values())
    paths = [path for key in keys for path in key.paths]  # a factor group's each
    twice = sorted({path for path in paths if paths.count(path) > 1})
    if twice:
        raise InputError(f"--fit: {', '.join(twice)} given twice")
    return keys


def _key(item: str, ranges: dict[str, Key], what: str) -> Key:
    path, sep, span = item.partition("=")
    path = ",".join(part.strip() for part in path.split(","))
    if not path or any(not part for one in path.split(",") for part in one.split(".")):
        raise InputError(f"{what} {item!r}: give KEY or KEY=LOW:HIGH with a dotted KEY")
    if not sep:
        if path not in ranges:
            raise InputError(
                f"{what} {path}: give its range as {path}=LOW:HIGH (the scenario gives one "
                f"for {', '.join(ranges) or 'no key'})"
            )
        return ranges[path]
    scaled = span.strip().startswith("*")
    if "," in path and not scaled:
        raise InputError(f"{what} {item!r}: keys fitted together take a factor, KEY,KEY=*LOW:HIGH")
    low, colon, high = span.strip().removeprefix("*").partition(":")
    try:
        lo, hi = float(low), float(high)
    except ValueError:
        lo = hi = math.nan
    if not colon or not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise InputError(f"{what} {item!r}: the range must be LOW:HIGH, finite, LOW < HIGH")
    return Key(path, lo, hi, scaled)


@dataclass(frozen=True)
class Fit:
    """An output-error fit's result: the values by key, their 95 % half-intervals, the
    correlation matrix (keys' order), the cost 0.5 |r|^2, the simulations run, whether the
    optimiser converged (and its message) and the seconds taken."""

    keys: tuple[Key, ...]
    values: dict[str, float]
    interval95: dict[str, float]
    correlation: np.ndarray
    cost: float
    evaluations: int
    converged: bool
    message: str
    seconds: float


def output_error(
    residuals: Callable[[np.ndarray], np.ndarray],
    keys: list[Key],
    start: np.ndarray,
    starts: int = 1,
    seed: int = 0,
    diff_step: float = DIFF_STEP,
    tolerance: float = TOLERANCE,
    threads: int = 1,
) -> Fit:
    """Minimise |residuals(values)|^2 over the keys' ranges from ``start`` (module
    docstring), until a step changes the cost or the values by less than ``tolerance``
    (relative), after :func:`check_identifiable` at the start (an InputError line where it
    refuses, or where the start cannot be simulated). The Jacobian is by forward differences:
    scipy's own, or with ``threads`` > 1 (and at the start) of step diff_step * max(1, |x|),
    at most half the range, taken towards the range's inside, its columns simulated that
    many at a time (the compiled engine releases the GIL). A candidate whose simulation
    diverges scores a residual of 1 per sample (the start itself must simulate: its error is
    raised)."""
    from scipy.optimize import least_squares
    from scipy.stats import qmc

    low = np.array([k.low for k in keys])
    high = np.array([k.high for k in keys])
    started = time.perf_counter()
    size, count, last, first = None, 0, {}, {}  # first: the start's residuals and Jacobian

    def guarded(values):
        nonlocal count, size
        if np.array_equal(first.get("x"), values):
            return first["r"]
        count += 1
        try:
            r = residuals(values)
        except EmasimError:
            if size is None:
                raise
            return np.ones(size)
        size = r.size
        last["x"], last["r"] = np.array(values), r
        return r

    def jacobian(x):
        if np.array_equal(first.get("x"), x):
            return first["jac"]
        steps = np.minimum(diff_step * np.maximum(1.0, np.abs(x)), (high - low) / 2)
        steps = np.where(x + steps > high, -steps, steps)
        steps = (x + steps) - x  # the step the rounded point takes
        points = [x + step * unit for step, unit in zip(steps, np.eye(x.size), strict=True)]
        r0 = last["r"] if np.array_equal(last.get("x"), x) else guarded(x)
        with concurrent.futures.ThreadPoolExecutor(threads) as pool:
            columns = list(pool.map(guarded, points))
        return np.column_stack([(r - r0) / step for r, step in zip(columns, steps, strict=True)])

    points = [np.clip(start, low, high)]
    try:
        r0 = guarded(points[0])
    except EmasimError as err:
        named = ", ".join(f"{k.name} = {v:.6g}" for k, v in zip(keys, points[0], strict=True))
        raise InputError(f"--fit: the fit's start ({named}) cannot be simulated: {err}") from None
    first.update(x=points[0], r=r0, jac=jacobian(points[0]))
    check_identifiable(first["jac"], keys)
    if starts > 1:
        # the first starts - 1 of a power of two of points: scipy warns on any other count
        power = math.ceil(math.log2(starts - 1)) if starts > 2 else 0
        sobol = qmc.Sobol(len(keys), scramble=True, seed=seed).random_base2(power)
        points += list(qmc.scale(sobol[: starts - 1], low, high))
    best = None
    for point in points:
        result = least_squares(
            guarded,
            point,
            jac=jacobian if threads > 1 else "2-point",
            bounds=(low, high),
            diff_step=diff_step,
            x_scale="jac",
            method="trf",
            ftol=tolerance,
            xtol=tolerance,
            gtol=None,  # the module docstring: the gradient's size is the residuals' scale
        )
        if best is None or result.cost < best.cost:
            best = result
    std, correlation = spread(best.jac, best.fun)
    return Fit(
        tuple(keys),
        {k.name: float(v) for k, v in zip(keys, best.x, strict=True)},
        {k.name: float(Z95 * s) for k, s in zip(keys, std, strict=True)},
        correlation,
        float(best.cost),
        count,
        bool(best.success),
        str(best.message),
        time.perf_counter() - started,
    )


def check_identifiable(jac: np.ndarray, keys: list[Key]) -> None:
    """Refuse, in one InputError line naming them, the keys the residuals cannot identify,
    judged from their Jacobian ``jac`` at the fit's start with each column scaled by its key's
    range (to first order, what the whole range does to the relative residuals):

    - a column below SENSITIVITY_FLOOR: over its whole range the key moves the compared
      outputs by less than a millionth of their size (a bound the run never meets, a term
      the compared signals do not show);
    - a key with a part along a direction the unit columns do not see (:func:`spread`): a
      combination of keys leaves the outputs unchanged.

    Checked before the fit, so that neither its time is spent nor its start reported as a
    converged result: the optimiser stops at once where the cost is flat."""
    scaled = jac * np.array([k.high - k.low for k in keys])
    norms = np.linalg.norm(scaled, axis=0)
    flat = [k.name for k, norm in zip(keys, norms, strict=True) if not norm >= SENSITIVITY_FLOOR]
    if flat:
        raise InputError(
            f"--fit: {', '.join(flat)} cannot be identified from this trace: over its whole "
            f"range it moves the compared outputs by less than {SENSITIVITY_FLOOR:g} of their "
            "size; fit other keys, or a trace with the signals it acts on"
        )
    std, _ = spread(scaled / norms, np.ones(scaled.shape[0]))
    blind = [k.name for k, s in zip(keys, std, strict=True) if not np.isfinite(s)]
    if blind:
        raise InputError(
            f"--fit: this trace cannot tell {', '.join(blind)} apart (a combination of them "
            "leaves the compared outputs unchanged, so no value is identified); fit fewer "
            "keys or a trace that excites them"
        )


def spread(jac: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each parameter's standard deviation and the correlation matrix from the Jacobian of
    the residuals ``r`` at the optimum: s^2 (J^T J)^-1, s^2 = |r|^2 / (N - p), through the
    singular values of J. A parameter with a part along a direction J does not see (a
    singular value below 1e-10 of the largest) has an infinite deviation, and NaN
    correlations: the data do not pin it down."""
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    dof = max(r.size - jac.shape[1], 1)
    s2 = float(r @ r) / dof
    largest = singular[0] if singular.size else 0.0
    seen = singular > NULL_DIRECTION * largest if largest > 0.0 else np.zeros_like(singular, bool)
    v = vt[seen].T / singular[seen]
    covariance = s2 * (v @ v.T)
    blind = np.any(np.abs(vt[~seen]) > NULL_DIRECTION, axis=0)
    std = np.sqrt(np.abs(np.diag(covariance)))
    std[blind] = np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(std, std)
    correlation[blind, :] = np.nan
    correlation[:, blind] = np.nan
    return std, correlation


def relative_error(measured: np.ndarray, simulated: np.ndarray) -> float:
    """|measured - simulated|_2 / |measured|_2."""
    return float(np.linalg.norm(measured - simulated) / np.linalg.norm(measured))
