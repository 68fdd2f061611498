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
errors are reported beside the training trace's.
"""

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..jsonio import json_text
from ..naming import RUNS_ROOT, fresh_folder
from ..output import write_folder, write_new
from ..version import __version__
from .axis_model import AxisModel
from .data import parse_map
from .fit import Fit, output_error, parse_keys
from .idim import Estimate

METHODS = ("output-error", "idim")


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


def _calibrated_text(text: str, values: dict[str, float]) -> str:
    """The scenario's text with the dotted keys set to the values (tomlkit keeps the rest)."""
    import tomlkit

    document = tomlkit.parse(text)
    for path, value in values.items():
        table = document
        *parents, last = path.split(".")
        for part in parents:
            if part not in table:
                table[part] = tomlkit.table()
            table = table[part]
        table[last] = value
    return tomlkit.dumps(document)


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
) -> Identified:
    """Identify ``scenario``'s keys ``fit`` (``KEY`` or ``KEY=LOW:HIGH``; the scenario's
    defaults where none is given) from the trace in ``data`` (module docstring); ``mapping``
    items ``FILE_COLUMN=SIGNAL`` add to the scenario's column map, ``settings`` items
    ``KEY=VALUE`` change it first. ``out``: the result folder (None: written nowhere; the
    command line writes runs/<scenario>/identify-<time> by default)."""
    from ..scenarios.axis_scenario import is_axis_scenario, read_axis_raw
    from ..scenarios.loader import apply_setting, read_scenario_text

    started = time.perf_counter()
    if not is_axis_scenario(str(scenario)):
        raise InputError(
            f"identify: '{scenario}' is not an axis scenario (kind = \"axis\"); identify "
            'takes emps or a file declaring kind = "axis"'
        )
    if starts < 1:
        raise InputError(f"--starts {starts}: give at least 1")
    raw, source = read_axis_raw(str(scenario))
    for setting in settings:
        apply_setting(raw, setting)
    model = AxisModel.read(raw, source, data, parse_map(list(mapping)))
    chosen = method or model.scenario.identify.method
    if chosen not in METHODS:
        raise InputError(f"--method {chosen}: choose one of {', '.join(METHODS)}")
    keys = parse_keys(list(fit), model.scenario.identify.fit)
    model.check_keys(keys)
    paths = [k.path for k in keys]
    estimate = None
    try:
        estimate = model.idim(keys)
    except InputError:
        if chosen == "idim":
            raise
    result_fit = None
    if chosen == "idim":
        values = estimate.values
        interval = {k: 1.959963984540054 * s for k, s in estimate.std.items()}
        correlation = estimate.correlation
    else:
        start = np.array(
            [estimate.values[k.path] if estimate else _value(model, k.path) for k in keys]
        )
        start = np.clip(start, [k.low for k in keys], [k.high for k in keys])
        result_fit = output_error(model.residuals(keys), keys, start, starts=starts)
        values, interval, correlation = (
            result_fit.values,
            result_fit.interval95,
            result_fit.correlation,
        )
    blind = [key for key, half in interval.items() if not np.isfinite(half)]
    if blind:
        raise InputError(
            f"--fit: this trace cannot tell {', '.join(blind)} apart from the other keys (a "
            "combination of them leaves the fit unchanged, so no value is identified); fit "
            "fewer keys or a trace that excites them"
        )
    calibrated = model.with_values(values)
    errors = model.errors(calibrated)
    validation = {}
    for other in validate:
        other_model = AxisModel(raw, source, _trace_like(model, other, mapping))
        validation[str(other)] = other_model.errors(other_model.with_values(values))
        validation[str(other)]["rmse_position_mm"] = _rmse_mm(other_model, values)
    text, _ = read_scenario_text(
        str(scenario) if Path(str(scenario)).is_file() else _shipped_path(scenario)
    )
    simulated = model.compared(model.simulate(calibrated))
    result = Identified(
        scenario=model.scenario.name,
        method=chosen,
        values=values,
        interval95=interval,
        correlation=_correlations(paths, correlation),
        errors=errors,
        validation=validation,
        data={"file": str(model.trace.path), "sha256": model.trace.sha256},
        seconds=time.perf_counter() - started,
        idim=estimate,
        fit=result_fit,
        calibrated_toml=_calibrated_text(text, {**_settings_values(settings), **values}),
        traces={
            "time_s": model.trace.signals["time_s"],
            **{f"measured_{n}": model.trace.signals[n] for n in model.outputs},
            **{f"simulated_{n}": simulated[n] for n in model.outputs},
        },
    )
    if out is None:
        return result
    folder = write_result(result, Path(out), force)
    return Identified(**{**result.__dict__, "folder": folder})


def default_folder(scenario: str) -> Path:
    """runs/<scenario>/identify-<time>."""
    from ..naming import slug

    return fresh_folder(RUNS_ROOT / slug(Path(scenario).stem), "identify")


def _value(model: AxisModel, path: str) -> float:
    from .axis_model import _get

    value = _get(model.raw, path)
    if value is None:
        raise InputError(f"--fit {path}: the scenario does not set it; give it with --set")
    return float(value)


def _settings_values(settings: list[str]) -> dict:
    """--set items as {key: value} for the calibrated file (only numbers and strings)."""
    import tomllib

    found = {}
    for item in settings:
        key, _, text = item.partition("=")
        try:
            found[key] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            found[key] = text
    return found


def _shipped_path(name: str) -> str:
    from ..scenarios.axis_scenario import builtin_axis_scenarios

    return str(builtin_axis_scenarios()[name])


def _trace_like(model: AxisModel, path, mapping: list[str]):
    from ..scenarios.axis_scenario import REQUIRED, SIGNALS
    from .data import load_trace

    return load_trace(
        path, SIGNALS, REQUIRED, parse_map(list(mapping)), model.scenario.identify.map
    )


def _rmse_mm(model: AxisModel, values: dict[str, float]) -> float:
    simulated = model.compared(model.simulate(model.with_values(values)))["position_m"]
    measured = model.trace.signals["position_m"]
    return float(1e3 * np.sqrt(np.mean((measured - simulated) ** 2)))


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
        lines.append(f"| `{key}` | {value:.6g} | ± {result.interval95[key]:.3g} |")
    lines += ["", "Relative errors of the free-run simulation, |y - y_sim| / |y|:", ""]
    columns = ["training", *result.validation]
    lines += [
        "| output | " + " | ".join(f"`{Path(c).name}`" for c in columns) + " |",
        "|---|" + "---:|" * len(columns),
    ]
    rows = [result.errors, *result.validation.values()]
    for name in result.errors:
        cells = [f"{100 * r[name]:.4g} %" if name in r else "" for r in rows]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    for path, errors in result.validation.items():
        lines.append("")
        lines.append(f"`{Path(path).name}`: position RMSE {errors['rmse_position_mm']:.4g} mm.")
    return "\n".join(lines) + "\n"


def write_result(result: Identified, out: Path, force: bool) -> Path:
    """Write the result folder (module docstring) at ``out``."""
    import pandas as pd

    from ..analysis.figure_process import DrawHere
    from ..analysis.identification_plots import fit_figure

    outputs = [n.removeprefix("measured_") for n in result.traces if n.startswith("measured_")]

    def write(tmp: Path) -> None:
        write_new(tmp / "identified.json", json_text(result.record()))
        write_new(tmp / "scenario.toml", result.calibrated_toml)
        table = dict(result.traces)
        for name in outputs:
            table[f"residual_{name}"] = table[f"measured_{name}"] - table[f"simulated_{name}"]
        frame = pd.DataFrame(table)
        from ..output import new_file

        with new_file(tmp / "traces.parquet") as handle:
            frame.to_parquet(handle)
        measured = {n: result.traces[f"measured_{n}"] for n in outputs}
        simulated = {n: result.traces[f"simulated_{n}"] for n in outputs}
        DrawHere().save(
            lambda: fit_figure(
                result.traces["time_s"], measured, simulated, f"{result.scenario}: {result.method}"
            ),
            tmp / "fit.png",
        )
        write_new(tmp / "report.md", report_text(result))

    unique = False
    return write_folder(out, write, force=force, unique=unique, kind="identification")
