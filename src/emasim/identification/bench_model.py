"""An actuator scenario bound to a trace of its sensors' readings: the bench's identification.

The scenario's own experiment is simulated (its reference and its load command are the
experiment's inputs: the trace must be a record of that experiment from its start, sampled at
the scenario's record period over its duration) and compared with the readings through the
features of emasim.identification.bench_features: a sample-by-sample comparison of the readings
is chaotic in the parameters. Every simulation of the fit keeps the scenario's seed (common
random numbers: the sensors' noise does not change from one candidate to the next), and the
Jacobian's relative step is ``DIFF_STEP``, twenty times the axis fit's: the features average
quantised readings, and are smooth at that scale, not below it.

The model is not linear in its parameters: it has no IDIM-LS estimate; the fit starts from the
scenario's values.
"""

import math

import numpy as np

from ..errors import InputError
from ..experiments.batch import workers_available
from ..experiments.study import resolved_value, sampled_table
from ..experiments.variation import Variation
from ..scenarios.loader import validate_scenario
from ..signals import signal_value
from .bench_features import FEATURES, READINGS, TRACE_COLUMNS, Constants, features
from .data import SAMPLING_TOLERANCE, load_trace
from .fit import Key, relative_error

DIFF_STEP = 0.02
TOLERANCE = 1e-3  # relative: a thousandth of a value, well inside the features' own scatter
TIME = "time_s"


class BenchModel:
    """An actuator scenario (its raw table, checked as a file's would be) and the trace of its
    experiment's readings (module docstring)."""

    diff_step = DIFF_STEP
    tolerance = TOLERANCE
    threads = workers_available()  # the Jacobian's simulations side by side

    def __init__(self, raw: dict, source: str, data, mapping: dict[str, str]):
        self.raw, self.source = raw, source
        self.scenario = validate_scenario(raw, source)
        if self.scenario.compare:
            raise InputError(
                f"identify: {self.scenario.name} compares controller sets; choose the one "
                f"that ran the experiment with --label "
                f"({', '.join(label for label, _ in self.scenario.variants())})"
            )
        self.resolved = self.scenario.model_dump(mode="json")
        defaults = {"t_s": TIME, **TRACE_COLUMNS}  # an emasim run's trace reads as it is
        if self.scenario.identify is not None:
            defaults.update(self.scenario.identify.map)
        self.trace = load_trace(data, (TIME, *READINGS), (TIME, *READINGS), mapping, defaults, TIME)
        self.time_signal = TIME
        self.keys: dict[str, Key] = {}
        period = self.scenario.solver.record_period_s
        self._check_sampling(period)
        self.outputs = {name: 1.0 for name in READINGS}
        self.time = period * np.arange(len(self.trace))  # the experiment's, from its start
        packed = self.scenario.load.encode()[2]  # the rudder load: the loader's command
        self.load = np.array([signal_value(packed, t) for t in self.time])
        plant = self.scenario.plant
        self.known = Constants(
            plant.ratio_m_per_rad,
            plant.torque_constant_Nm_per_A,
            plant.friction.stribeck_speed_rad_s,
        )
        self.measured = self.features_of(self.trace.signals)

    def _check_sampling(self, period: float) -> None:
        trace = self.trace
        if abs(trace.sample_period_s - period) > SAMPLING_TOLERANCE * period:
            raise InputError(
                f"--data {trace.path}: sampled every {trace.sample_period_s:.6g} s; the "
                f"scenario records every {period:g} s (solver.record_period_s)"
            )
        rows = math.floor(self.scenario.duration_s / period + 1e-9)
        if len(trace) != rows:
            raise InputError(
                f"--data {trace.path}: {len(trace)} samples; the scenario's experiment "
                f"({self.scenario.duration_s:g} s every {period:g} s) records {rows}"
            )

    def features_of(self, readings: dict) -> np.ndarray:
        """The FEATURES of ``readings`` (by READINGS' names) under the experiment's load; an
        InputError where the readings do not hold them (bench_features.features)."""
        try:
            return features(self.time, readings, self.load, self.known)
        except ValueError as err:
            raise InputError(f"--data {self.trace.path}: {err}") from None

    def check_keys(self, keys: list[Key]) -> None:
        """Take ``keys`` as the ones this model sets (:meth:`raw_with`); refuse, in one line,
        one that is no number of the scenario or whose range leaves the field's own."""
        self.keys = {key.name: key for key in keys}
        for key in keys:
            for value in (key.low, key.high):
                self.with_values({key.name: value}, what=f"--fit {key.path}")

    def idim(self, keys: list[Key]):
        """No inverse model: the bench's is not linear in its parameters."""
        raise InputError(
            f"--method idim: {self.scenario.name}'s model is not linear in its parameters "
            "(no inverse-model least squares); use output-error"
        )

    def value(self, key: Key) -> float:
        """The scenario's own value of ``key`` (1 for a factor; the mean of a list)."""
        if key.scaled:
            return 1.0
        value = resolved_value(self.resolved, key.path)
        if value is None:
            raise InputError(f"--fit {key.path}: the scenario has no number there")
        return float(np.mean(value))

    def raw_with(self, values: dict[str, float], what: str = "--fit") -> dict:
        """A copy of the raw table with each key of ``values`` (by name, of those
        :meth:`check_keys` took) set to its value: every element of a list of numbers, or,
        for a factor, each path's own value times it."""
        keys = [self.keys[name] for name in values]
        variations = [Variation(k.name, k.paths, None, None, k.scaled) for k in keys]
        return sampled_table(self.raw, self.resolved, variations, values, what)

    def with_values(self, values: dict[str, float], what: str = "--fit"):
        """The scenario with the keys set to ``values``, validated."""
        return validate_scenario(self.raw_with(values, what), f"{what} {self.source}")

    def simulate(self, scenario) -> dict:
        """The readings of the scenario's experiment, simulated."""
        from ..experiments.runs import simulate_scenario

        run = scenario.setup().with_(record_signals=tuple(TRACE_COLUMNS))
        result = simulate_scenario(scenario, setup=run)
        simulated = {name: np.asarray(result[column]) for column, name in TRACE_COLUMNS.items()}
        return {TIME: np.asarray(result.t), **simulated}

    def residuals(self, keys: list[Key]):
        """values -> the relative residuals of the features, (f_sim - f_meas) / |f_meas|."""
        scale = np.abs(self.measured)

        def residual(values: np.ndarray) -> np.ndarray:
            scenario = self.with_values(dict(zip((k.name for k in keys), values, strict=True)))
            return (self.features_of(self.simulate(scenario)) - self.measured) / scale

        return residual

    def errors(self, scenario) -> tuple[dict[str, float], dict]:
        """The relative errors |y - y_sim| / |y| of each reading, and of each feature
        (``feature <name>``), of the simulation of ``scenario``; and the simulated readings."""
        simulated = self.simulate(scenario)
        errors = {
            name: relative_error(self.trace.signals[name], simulated[name]) for name in READINGS
        }
        model = self.features_of(simulated)
        for name, measured, value in zip(FEATURES, self.measured, model, strict=True):
            errors[f"feature {name}"] = float(abs(value - measured) / abs(measured))
        return errors, simulated
