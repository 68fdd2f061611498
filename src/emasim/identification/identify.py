"""``emasim identify``: fit a scenario's parameters to a measured trace, and say how well.

The methods (SPEC section 7):

- ``idim``: inverse-model least squares (emasim.identification.idim), where the model's force
  is linear in the fitted keys (the axis with Coulomb + viscous or asymmetric friction);
- ``output-error`` (the default): the closed loop simulated from the measured reference, its
  outputs fitted to the measured ones (emasim.identification.fit), started from the IDIM-LS
  estimate where there is one, else from the scenario's values.

The result folder holds ``identified.json`` (each key's value, 95 % interval and correlation
with the others; the relative errors of the free-run simulation; the method, the data file's
sha256, the time taken), the calibrated ``scenario.toml`` (the original text, the fitted
values set), ``traces.parquet`` (measured, simulated and residual), ``fit.png`` and
``report.md``. ``validate`` files are simulated with the fitted values (a cross-test): their
errors are reported beside the training trace's. A fit that pins nothing down, or whose
values the loop cannot simulate, is refused in one InputError line (:func:`check_identified`;
the fit's own check before it starts: emasim.identification.fit.check_identifiable).
"""

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..arguments import flag, optional_string, strings
from ..errors import EmasimError, InputError
from ..jsonio import json_text
from ..naming import RUNS_ROOT, fresh_folder, slug
from ..output import new_file, write_folder, write_new
from ..scenarios.axis_scenario import is_axis_scenario, read_axis_raw
from ..scenarios.loader import (
    apply_setting,
    choose_controllers,
    read_scenario_file,
    read_scenario_text,
)
from ..toml_text import laid_over
from ..version import __version__
from .axis_model import AxisModel
from .bench_model import BenchModel
from .data import parse_map
from .fit import Z95, Fit, Key, output_error, parse_keys
from .idim import Estimate

METHODS = ("output-error", "idim")
MAX_STARTS = 1000  # each start is a whole fit, tens of simulations: 1000 take hours
ON_BOUND = 1e-9  # of the range: a value this near a bound is on it (the fit's tolerance, if more)
MISSED = 0.9  # a relative error of the free run this large: the model explains nothing of it


@dataclass(frozen=True)
class Identified:
    """What ``identify`` found: the values, intervals and correlations of the keys, the
    relative errors of the training trace and of each validation trace, the method, the IDIM
    estimate (where one was made) and the output-error fit (where one ran)."""

    scenario: str
    method: str
    values: dict[str, float]
    interval95: dict[str, float]
    correlation: dict[str, dict[str, float]]
    on_bound: dict[str, str]
    errors: dict[str, float]
    validation: dict[str, dict[str, float]]
    data: dict[str, str]
    seconds: float
    idim: Estimate | None = None
    fit: Fit | None = None
    calibrated_toml: str = ""
    folder: Path | None = None
    traces: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def record(self) -> dict:
        """identified.json's content."""
        return {
            "scenario": self.scenario,
            "method": self.method,
            "parameters": {
                key: {
                    "value": value,
                    "interval95": self.interval95[key],
                    "correlation": self.correlation[key],
                    "on_bound": self.on_bound.get(key),
                }
                for key, value in self.values.items()
            },
            "fit": {"relative_errors": self.errors},
            "validation": self.validation,
            "idim": None
            if self.idim is None
            else {
                "condition_number": self.idim.condition,
                "relative_error": self.idim.relative_error,
                "samples": self.idim.samples,
            },
            "output_error": None
            if self.fit is None
            else {
                "cost": self.fit.cost,
                "simulations": self.fit.evaluations,
                "converged": self.fit.converged,
                "message": self.fit.message,
            },
            "data": self.data,
            "seconds": self.seconds,
            "emasim": __version__,
        }


def _correlations(paths: list[str], matrix: np.ndarray) -> dict[str, dict[str, float]]:
    return {
        a: {b: float(matrix[i, j]) for j, b in enumerate(paths) if b != a}
        for i, a in enumerate(paths)
    }


def calibrated_text(text: str, calibrated: dict, keys: list[str], data: str, sha256: str) -> str:
    """The scenario's text with the table ``calibrated`` laid over it (emasim.toml_text: its
    comments kept) under a first line naming the identified ``keys`` and the data."""
    header = (
        f"# Calibrated by emasim identify from {data} (sha256 {sha256}): "
        f"{', '.join(keys)} hold the identified values (identified.json); the comments "
        "below are the original scenario's.\n"
    )
    return header + laid_over(text, calibrated)


def on_bound(keys: list[Key], values: dict[str, float], tolerance: float = 0.0) -> dict[str, str]:
    """Key -> "lower" or "upper" for a value on its range's bound: within the optimiser's
    ``tolerance`` (relative, as it was given it; at least ON_BOUND) of the range, where it
    stops short of a bound it is pressed against. The fit would go further; widen the range,
    or the model misses something."""
    found = {}
    for key in keys:
        margin = max(tolerance, ON_BOUND) * (key.high - key.low)
        if values[key.name] <= key.low + margin:
            found[key.name] = "lower"
        elif values[key.name] >= key.high - margin:
            found[key.name] = "upper"
    return found


def check_identified(path, keys: list[Key], interval: dict, errors: dict) -> None:
    """Refuse, in one InputError line, a fit that identified nothing it can vouch for: a key
    whose 95 % interval is wider than its range (the trace does not pin it down within it),
    or a relative error of the free run (each one ``errors`` holds, the RMSE in mm aside) of
    MISSED or more: the model, at the fitted values, explains almost none of that measured
    signal (a column in other units or mapped to the wrong signal, traces joined with a jump).
    Either way the values are the optimiser's stopping point, not a measurement."""
    wide = [
        f"the 95 % interval of {k.name} (± {interval[k.name]:.3g}) is wider than its range "
        f"({k.low:g} to {k.high:g})"
        for k in keys
        if 2.0 * interval[k.name] > k.high - k.low
    ]
    missed = [
        f"the fitted model misses {name} by {100 * errors[name]:.3g} %"
        for name, error in errors.items()
        if not name.endswith("_mm") and error >= MISSED
    ]
    if wide or missed:
        raise InputError(
            f"--data {path}: no value identified: {'; '.join(wide + missed)} "
            "(check the trace's units and --map, or fit fewer keys)"
        )


def _estimate(model, keys: list[Key], method: str, starts: int):
    """(values, 95 % half-intervals, correlation matrix, IDIM estimate, output-error fit)."""
    estimate = None
    try:
        estimate = model.idim(keys)
    except InputError:
        if method == "idim":
            raise
    if method == "idim":
        interval = {k: Z95 * s for k, s in estimate.std.items()}
        return estimate.values, interval, estimate.correlation, estimate, None
    start = np.array([estimate.values[k.path] if estimate else model.value(k) for k in keys])
    start = np.clip(start, [k.low for k in keys], [k.high for k in keys])
    fit = output_error(
        model.residuals(keys),
        keys,
        start,
        starts=starts,
        diff_step=model.diff_step,
        tolerance=model.tolerance,
        threads=model.threads,
    )
    return fit.values, fit.interval95, fit.correlation, estimate, fit


def bind(scenario: str, data, settings=(), columns=None, label: str | None = None):
    """The model of ``scenario`` bound to the trace in ``data``, and the scenario's text: an
    AxisModel for an axis scenario, a BenchModel (its experiment's readings) otherwise;
    ``label`` chooses an actuator scenario's controller set."""
    columns = columns or {}
    if is_axis_scenario(str(scenario)):
        if label is not None:
            raise InputError(f"--label {label}: an axis scenario has one controller")
        raw, source, text = read_axis_raw(str(scenario))
        for setting in settings:
            apply_setting(raw, setting)
        return AxisModel.read(raw, source, data, columns), text
    raw, source = read_scenario_file(str(scenario))
    choose_controllers(raw, [], label)
    for setting in settings:
        apply_setting(raw, setting)
    return BenchModel(raw, source, data, columns), read_scenario_text(str(scenario))[0]


def _check_arguments(scenario, data, fit, mapping, method, settings, validate, starts, out, label):
    """identify's arguments of the wrong type: InputError, one line naming the argument (the
    command line passes each as it should; its own messages for values follow)."""
    for name, value in (("scenario", scenario), ("data", data)):
        if not isinstance(value, str | Path):
            raise InputError(f"identify: {name} must be a string or a Path, got {value!r}")
    for name, value in (("fit", fit), ("mapping", mapping), ("settings", settings)):
        strings(f"identify: {name}", value)
    if not isinstance(validate, list | tuple) or not all(
        isinstance(path, str | Path) for path in validate
    ):
        raise InputError(f"identify: validate must be a list of paths, got {validate!r}")
    optional_string("identify: method", method)
    optional_string("identify: label", label)
    if isinstance(starts, bool) or not isinstance(starts, int):
        raise InputError(
            f"identify: starts must be a whole number from 1 to {MAX_STARTS}, got {starts!r}"
        )
    if out is not None and not isinstance(out, str | Path):
        raise InputError(f"identify: out must be a folder's path or None, got {out!r}")


def identify(
    scenario: str,
    data: str | Path,
    fit: list[str] = (),
    mapping: list[str] = (),
    method: str | None = None,
    settings: list[str] = (),
    validate: list[str | Path] = (),
    starts: int = 1,
    out: str | Path | None = None,
    force: bool = False,
    label: str | None = None,
) -> Identified:
    """Identify ``scenario``'s keys ``fit`` (``KEY`` or ``KEY=LOW:HIGH``, or
    ``KEY[,KEY...]=*LOW:HIGH`` for a factor; the scenario's defaults where none is given)
    from the trace in ``data`` (module docstring); ``mapping`` items ``FILE_COLUMN=SIGNAL``
    add to the scenario's column map, ``settings`` items ``KEY=VALUE`` change it first,
    ``label`` chooses a comparison's controller set. ``out``: the result folder (None: written
    nowhere; the command line writes runs/<scenario>/identify-<time> by default)."""
    started = time.perf_counter()
    _check_arguments(scenario, data, fit, mapping, method, settings, validate, starts, out, label)
    force = flag("identify: force", force)
    if not 1 <= starts <= MAX_STARTS:
        raise InputError(f"--starts {starts}: give 1 to {MAX_STARTS}")
    columns = parse_map(list(mapping))
    model, text = bind(scenario, data, settings, columns, label)
    defaults = model.scenario.identify
    chosen = method or getattr(defaults, "method", "output-error")
    if chosen not in METHODS:
        raise InputError(f"--method {chosen}: choose one of {', '.join(METHODS)}")
    if defaults is None and not fit:
        raise InputError(
            f"--fit: {model.scenario.name} names no keys to fit; give --fit KEY=LOW:HIGH"
        )
    keys = parse_keys(list(fit), defaults.fit if defaults else [])
    model.check_keys(keys)
    others = [bind(scenario, path, settings, columns, label)[0] for path in validate]
    for other in others:
        other.check_keys(keys)
    values, interval, correlation, estimate, result_fit = _estimate(model, keys, chosen, starts)
    blind = [key for key, half in interval.items() if not np.isfinite(half)]
    if blind:
        raise InputError(
            f"--fit: this trace cannot tell {', '.join(blind)} apart from the other keys (a "
            "combination of them leaves the fit unchanged, so no value is identified); fit "
            "fewer keys or a trace that excites them"
        )
    try:
        errors, simulated = model.errors(model.with_values(values))
        validation = {
            str(path): other.errors(other.with_values(values))[0]
            for path, other in zip(validate, others, strict=True)
        }
    except EmasimError as err:
        named = ", ".join(f"{key} = {value:.6g}" for key, value in values.items())
        raise InputError(
            f"--method {chosen}: the identified values ({named}) cannot be simulated: {err} "
            "(check the trace's units and --map)"
        ) from None
    check_identified(model.trace.path, keys, interval, errors)
    result = Identified(
        scenario=model.scenario.name,
        method=chosen,
        values=values,
        interval95=interval,
        on_bound=on_bound(keys, values, model.tolerance if result_fit else 0.0),
        correlation=_correlations([k.name for k in keys], correlation),
        errors=errors,
        validation=validation,
        data={"file": str(model.trace.path), "sha256": model.trace.sha256},
        seconds=time.perf_counter() - started,
        idim=estimate,
        fit=result_fit,
        calibrated_toml=calibrated_text(
            text, model.raw_with(values), list(values), str(model.trace.path), model.trace.sha256
        ),
        traces={
            "time_s": model.trace.signals[model.time_signal],
            **{f"measured_{n}": model.trace.signals[n] for n in model.outputs},
            **{f"simulated_{n}": simulated[n] for n in model.outputs},
        },
    )
    if out is None:
        return result
    return replace(result, folder=write_result(result, Path(out), force))


@dataclass(frozen=True)
class Series:
    """The identification of each trace of a series (wear tracking): ``table`` has one row per
    trace (``at``: its date or cycle count as given, the file, its sha256, each key's value and
    95 % half-interval, the relative errors), ``runs`` each trace's Identified, ``wear`` the
    wear study at the identified values (emasim.experiments.wear.run_wear_series), if run."""

    table: "object"  # a pandas DataFrame
    runs: list[Identified]
    folder: Path | None = None
    wear: dict | None = None


def identify_series(
    scenario: str,
    data: list[str | Path],
    at: list[str] | None = None,
    out: str | Path | None = None,
    force: bool = False,
    wear: bool = False,
    **options,
) -> Series:
    """:func:`identify` on each trace of ``data`` with the same keys and method (``options``:
    its other arguments), tabulated against ``at`` (each trace's date or cycle count; its
    place in the series by default). ``out`` holds ``series.csv``, ``series.png`` (each key
    against ``at`` with its interval) and a folder per trace. ``wear``: also run the bench
    experiments with PID and the hybrid at each trace's identified values (the wear study,
    emasim.experiments.wear.run_wear_series), written as ``wear.json`` and ``wear.png``."""
    import pandas as pd

    labels = [str(i) for i in range(len(data))] if not at else [str(a) for a in at]
    if len(labels) != len(data):
        raise InputError(f"--at: {len(labels)} given for {len(data)} --data files; give one each")
    if len(set(labels)) != len(labels):
        raise InputError("--at: each trace needs its own date or cycle count")
    folders = [trace_folder(label, path) for label, path in zip(labels, data, strict=True)]
    clash = [label for label, f in zip(labels, folders, strict=True) if folders.count(f) > 1]
    if clash:  # refused before the fits, not when the series is written
        name = folders[labels.index(clash[0])]
        raise InputError(
            f"--at {', '.join(clash)}: these traces' result folders would share the name "
            f"{name} (the date or cycle count, then the file's name, every character but "
            "letters and digits a dash); give each trace a date or file of its own"
        )
    runs = [identify(scenario, path, **options) for path in data]
    rows = []
    for label, run in zip(labels, runs, strict=True):
        row = {"at": label, "file": run.data["file"], "sha256": run.data["sha256"]}
        for key, value in run.values.items():
            row[key] = value
            row[f"{key} interval95"] = run.interval95[key]
        row.update({f"error {name}": value for name, value in run.errors.items()})
        rows.append(row)
    series = Series(pd.DataFrame(rows), runs)
    if wear:
        from ..experiments.wear import run_wear_series

        values = {key: [run.values[key] for run in runs] for key in runs[0].values}
        series = replace(series, wear=run_wear_series(values, labels))
    if out is None:
        return series
    return replace(series, folder=_write_series(series, labels, Path(out), force))


def trace_folder(label: str, path: str | Path) -> str:
    """The name of a series' folder for the trace ``path`` at ``label``: its date or cycle
    count and its file's stem, as slugs."""
    return f"{slug(label)}-{slug(Path(path).stem)}"


def _write_series(series: Series, labels: list[str], out: Path, force: bool) -> Path:
    from ..analysis.figure_process import DrawHere
    from ..analysis.identification_plots import series_figure

    def write(tmp: Path) -> None:
        write_new(tmp / "series.csv", series.table.to_csv(index=False))
        keys = list(series.runs[0].values)
        DrawHere().save(lambda: series_figure(series.table, keys), tmp / "series.png")
        if series.wear is not None:
            from ..analysis.plots import plot_wear

            write_new(tmp / "wear.json", json_text(series.wear))
            DrawHere().save(lambda: plot_wear(series.wear), tmp / "wear.png")
        for label, run in zip(labels, series.runs, strict=True):
            folder = tmp / trace_folder(label, run.data["file"])
            folder.mkdir()
            _write_files(run, folder)

    return write_folder(out, write, force=force, kind="identification-series")


def default_folder(scenario: str) -> Path:
    """runs/<scenario>/identify-<time>."""
    return fresh_folder(RUNS_ROOT / slug(Path(scenario).stem), "identify")


def report_text(result: Identified) -> str:
    """report.md: the values with their intervals, the errors, the validation."""
    lines = [
        f"# Identification of {result.scenario}",
        "",
        f"Method: {result.method}. Data: `{result.data['file']}` (sha256 "
        f"{result.data['sha256'][:16]}...). {result.seconds:.1f} s.",
        "",
        "| key | value | 95 % interval |",
        "|---|---:|---:|",
    ]
    for key, value in result.values.items():
        bound = result.on_bound.get(key)
        note = f" (on its {bound} bound)" if bound else ""
        lines.append(f"| `{key}` | {value:.6g}{note} | ± {result.interval95[key]:.3g} |")
    lines += [
        "",
        "Relative errors |y - y_sim| / |y| of the free-run simulation, and its position RMSE:",
        "",
    ]
    columns = ["training", *result.validation]
    lines += [
        "| output | " + " | ".join(f"`{Path(c).name}`" for c in columns) + " |",
        "|---|" + "---:|" * len(columns),
    ]
    rows = [result.errors, *result.validation.values()]
    for name in result.errors:
        cells = [shown(name, r[name]) if name in r else "" for r in rows]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def shown(name: str, value: float) -> str:
    """A relative error in %, an RMSE in its unit."""
    return f"{value:.4g} mm" if name.endswith("_mm") else f"{100 * value:.4g} %"


def write_result(result: Identified, out: Path, force: bool) -> Path:
    """Write the result folder (module docstring) at ``out``."""
    return write_folder(
        out, lambda tmp: _write_files(result, tmp), force=force, kind="identification"
    )


def _write_files(result: Identified, folder: Path) -> None:
    """The files of one identification (module docstring) into ``folder``."""
    import pandas as pd

    from ..analysis.figure_process import DrawHere
    from ..analysis.identification_plots import fit_figure

    outputs = [n.removeprefix("measured_") for n in result.traces if n.startswith("measured_")]
    write_new(folder / "identified.json", json_text(result.record()))
    write_new(folder / "scenario.toml", result.calibrated_toml)
    table = dict(result.traces)
    for name in outputs:
        table[f"residual_{name}"] = table[f"measured_{name}"] - table[f"simulated_{name}"]
    with new_file(folder / "traces.parquet") as handle:
        pd.DataFrame(table).to_parquet(handle)
    measured = {n: result.traces[f"measured_{n}"] for n in outputs}
    simulated = {n: result.traces[f"simulated_{n}"] for n in outputs}
    title = f"{result.scenario}: {result.method}"
    DrawHere().save(
        lambda: fit_figure(result.traces["time_s"], measured, simulated, title),
        folder / "fit.png",
    )
    write_new(folder / "report.md", report_text(result))
