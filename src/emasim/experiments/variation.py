"""What a study varies: ``KEY=SPEC`` parsed, and the samples it makes.

KEY is a dotted scenario key (``plant.backlash.width_mm``, ``load.rudder_Nm.0.value``,
``seed``), or several joined by commas that take one value together. SPEC is one of

* a value or a list, the points of a grid: ``0.1``, ``0.05,0.1,0.2``, ``[0.05, 0.1]``
  (each item read as TOML: numbers, booleans, strings); for several keys, a list of arrays
  gives each key its own value at each point, ``a,b=[[1, 10], [2, 20]]``, and the study's
  column for them holds the point's place in the list (0, 1, ...);
* a range, also a grid: ``linspace(a, b, n)`` (n evenly spaced values from a to b) or
  ``geomspace(a, b, n)`` (n values in geometric progression from a to b);
* a distribution, drawn afresh for each Monte Carlo run: ``uniform(a, b)``,
  ``normal(mean, std)``, ``loguniform(a, b)`` (log-uniform on [a, b], 0 < a < b),
  ``integers(a, b)`` (a to b, both included) or ``discrete(a, b, n)`` (one of the n evenly
  spaced values from a to b, each equally likely: a value that must sit on a grid, such as
  a delay of whole solver steps).

A SPEC that starts with ``*`` scales the scenario's own value of each key:
``plant.friction.coulomb_Nm=*uniform(0.5, 1.5)`` is friction +-50 %.

The samples of a study (:func:`samples`) are the Cartesian product of the grids, in the order
given, each repeated for ``runs`` Monte Carlo runs. The distributions of sample (g, r) (grid
point g, run r) are drawn from ``numpy.random.default_rng([seed, g, r])``: a sample's values
depend on nothing but its place, so a resumed or re-run study draws exactly the same ones.
"""

import itertools
import math
import re
import tomllib
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

DISTRIBUTIONS = {"uniform": 2, "normal": 2, "loguniform": 2, "integers": 2, "discrete": 3}
RANGES = {"linspace": 3, "geomspace": 3}
_CALL = re.compile(r"^(?P<name>[a-z]+)\((?P<args>.*)\)$")
FACTOR = " (factor)"  # after the paths of a '*' key in a result's names (emasim identify)
MAX_SAMPLES = 100_000
INT_MIN, INT_MAX = -(2**63), 2**63 - 1  # what integers(a, b) draws (numpy's int64)
FLOAT_MAX = float(np.finfo(float).max)


@dataclass(frozen=True)
class Variation:
    """One ``KEY=SPEC``: ``keys`` set together; ``grid`` the values of a grid (None for a
    distribution); ``distribution`` (name, parameters); ``relative``: the value multiplies
    the scenario's own value of each key; ``name``: the KEY as given, the column that holds
    the drawn value (the factor when relative)."""

    name: str
    keys: tuple[str, ...]
    grid: tuple | None
    distribution: tuple[str, tuple[float, ...]] | None
    relative: bool

    def value_of(self, value, i: int):
        """The value the ``i``-th key takes when the variation's value is ``value``."""
        return value[i] if isinstance(value, list) else value

    def column(self, value):
        """What the study's table holds for ``value``: the place in the grid of a list of
        arrays, else the value."""
        return self.grid.index(value) if isinstance(value, list) else value

    def draw(self, rng: np.random.Generator):
        """One value of the distribution."""
        kind, (a, b, *n) = self.distribution
        if kind == "discrete":
            return float(np.linspace(a, b, int(n[0]))[rng.integers(int(n[0]))])
        if kind == "uniform":
            return float(rng.uniform(a, b))
        if kind == "normal":
            return float(rng.normal(a, b))
        if kind == "loguniform":
            return float(math.exp(rng.uniform(math.log(a), math.log(b))))
        return int(rng.integers(int(a), int(b), endpoint=True))


def parse_variation(text: str) -> Variation:
    """``KEY[,KEY...]=SPEC`` (module docstring) as a Variation; InputError names what is wrong."""
    name, sep, spec = text.partition("=")
    name, spec = name.strip(), spec.strip()
    keys = tuple(k.strip() for k in name.split(","))
    if not sep or not spec or not all(keys) or not all(all(k.split(".")) for k in keys):
        raise InputError(f"--vary: expected KEY=SPEC with a dotted KEY, got {text!r}")
    where = f"--vary {name}"
    relative = spec.startswith("*")
    body = spec[1:].strip() if relative else spec
    call = _CALL.match(body)
    if call is None:
        values = _values(body, where)
        zipped = any(isinstance(v, list) for v in values)
        if zipped and not all(isinstance(v, list) and len(v) == len(keys) for v in values):
            raise InputError(
                f"{where}: each item of a list of arrays needs one value per key "
                f"({len(keys)}), got {body!r}"
            )
        numbers = [x for v in values for x in (v if zipped else [v])]
        if relative and not all(_is_number(x) for x in numbers):
            raise InputError(f"{where}: a '*' factor must be a number, got {body!r}")
        return Variation(name, keys, values, None, relative)
    kind, args = call["name"], _numbers(call["args"], where)
    expected = DISTRIBUTIONS.get(kind, RANGES.get(kind))
    if expected is None:
        known = ", ".join([*RANGES, *DISTRIBUTIONS])
        raise InputError(f"{where}: unknown '{kind}(...)'; use a list or one of: {known}")
    if len(args) != expected:
        raise InputError(f"{where}: {kind} takes {expected} numbers, got {len(args)}")
    if kind in RANGES:
        return Variation(name, keys, _range(kind, args, where), None, relative)
    _check_distribution(kind, args, where)
    return Variation(name, keys, None, (kind, tuple(args)), relative)


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _values(body: str, where: str) -> tuple:
    """The items of a list SPEC, each read as TOML (a bare word is a string); a list of
    arrays as the TOML array it is."""
    if body.startswith("[["):
        try:
            items = tomllib.loads(f"v = {body}")["v"]
        except tomllib.TOMLDecodeError as err:
            raise InputError(f"{where}: not a list of arrays ({err})") from None
        return tuple(items)
    inner = body[1:-1] if body.startswith("[") and body.endswith("]") else body
    items = [item.strip() for item in inner.split(",")]
    if not all(items):
        raise InputError(f"{where}: an empty item in {body!r}")
    values = []
    for item in items:
        try:
            values.append(tomllib.loads(f"v = {item}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(item)
    return tuple(values)


def _numbers(args: str, where: str) -> list[float]:
    try:
        numbers = [_number(a) for a in args.split(",")] if args.strip() else []
    except ValueError:
        raise InputError(f"{where}: expected numbers in ({args})") from None
    if not all(math.isfinite(x) for x in numbers):
        raise InputError(f"{where}: the numbers must be finite, got ({args})")
    return numbers


def _number(text: str) -> int | float:
    """A whole number as an int (exact, however large), else a float."""
    text = text.strip()
    return int(text) if re.fullmatch(r"[+-]?\d+", text) else float(text)


def _range(kind: str, args: list[float], where: str) -> tuple[float, ...]:
    a, b, n = args
    if n != int(n) or not 1 <= n <= MAX_SAMPLES:
        raise InputError(f"{where}: {kind} count must be a whole number from 1 to {MAX_SAMPLES}")
    if kind == "geomspace" and not (a > 0 and b > 0):
        raise InputError(f"{where}: geomspace needs a > 0 and b > 0, got {a:g} and {b:g}")
    space = np.linspace if kind == "linspace" else np.geomspace
    return tuple(float(v) for v in space(a, b, int(n)))


def _check_distribution(kind: str, args: list[float], where: str) -> None:
    if kind == "discrete":
        a, b, n = args
        if n != int(n) or not 2 <= n <= MAX_SAMPLES or not a < b:
            raise InputError(
                f"{where}: discrete(a, b, n) needs a < b and a whole n from 2 to {MAX_SAMPLES}"
            )
        return
    a, b = args
    if kind == "normal" and not b > 0:
        raise InputError(f"{where}: normal(mean, std) needs std > 0, got {b:g}")
    if kind != "normal" and not a < b:
        raise InputError(f"{where}: {kind}(a, b) needs a < b, got {a:g} and {b:g}")
    if kind == "loguniform" and not a > 0:
        raise InputError(f"{where}: loguniform(a, b) needs a > 0, got {a:g}")
    if kind == "integers" and not (a == int(a) and b == int(b)):
        raise InputError(f"{where}: integers(a, b) needs whole numbers, got {a:g} and {b:g}")
    if kind == "integers" and not (INT_MIN <= int(a) and int(b) <= INT_MAX):
        raise InputError(
            f"{where}: integers(a, b) needs whole numbers from {INT_MIN} to {INT_MAX}, "
            f"got {a:g} and {b:g}"
        )
    if kind == "uniform" and not math.isfinite(b - a):
        raise InputError(
            f"{where}: uniform(a, b) needs b - a at most {FLOAT_MAX:g}, got {a:g} and {b:g}"
        )


@dataclass(frozen=True)
class Sample:
    """One point of a study: ``index`` (0, 1, ... in the study's order), grid point ``grid``
    and Monte Carlo run ``run``, and the value of each variation by its name."""

    index: int
    grid: int
    run: int
    values: dict


def samples(variations: list[Variation], runs: int, seed: int) -> list[Sample]:
    """Every sample of a study (module docstring); InputError when it would repeat one run."""
    names = [v.name for v in variations]
    if len(set(names)) != len(names):
        raise InputError(f"--vary: {next(n for n in names if names.count(n) > 1)} given twice")
    keys = [k for v in variations for k in v.keys]
    if len(set(keys)) != len(keys):
        raise InputError(f"--vary: {next(k for k in keys if keys.count(k) > 1)} varied twice")
    grids = [v for v in variations if v.grid is not None]
    drawn = [v for v in variations if v.grid is None]
    if runs > 1 and not drawn:
        raise InputError(
            "--runs: more than one run of each grid point needs a distribution to draw "
            "(e.g. --vary seed=integers(0, 99999)); without one every run is the same"
        )
    points = list(itertools.product(*(v.grid for v in grids)))
    if len(points) * runs > MAX_SAMPLES:
        raise InputError(f"--vary/--runs: {len(points) * runs} samples; at most {MAX_SAMPLES}")
    out = []
    for g, point in enumerate(points):
        for r in range(runs):
            values = {v.name: value for v, value in zip(grids, point, strict=True)}
            rng = np.random.default_rng([seed, g, r])
            values |= {v.name: v.draw(rng) for v in drawn}
            out.append(Sample(len(out), g, r, {n: values[n] for n in names}))
    return out
