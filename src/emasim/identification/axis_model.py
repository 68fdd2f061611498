"""An axis scenario bound to a measured trace: simulate it from the trace's inputs, compare its
outputs, and build its inverse model's observation matrix.

The measured reference (and the added command, where the trace has one) drives the closed loop
(emasim.sim.axis_loop), from the first measured position at the speed of the first two
samples; the simulated encoder reading and drive input are compared with the measured ones
sample by sample. The output-error fit's simulations read the encoder ideally: its
quantisation, a step of the residuals at every count, makes the cost a staircase on which
the optimiser stalls (on a noise-free synthetic trace it stopped 1 % off the truth with it,
0.01 % without it: tests/test_identification.py). The free-run errors it reports use the
scenario's encoder.
"""

import copy
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..plant.axis import inverse_model
from ..scenarios.axis_scenario import (
    INPUTS,
    REQUIRED,
    SIGNALS,
    AxisScenario,
    validate_axis,
)
from ..scenarios.loader import set_key
from ..sim.axis_loop import simulate_axis
from . import idim
from .data import SAMPLING_TOLERANCE, Trace, load_trace
from .fit import DIFF_STEP, TOLERANCE, Key, relative_error

PLANT_PREFIX = "plant."


class AxisModel:
    """An axis scenario (its raw table, so that candidate values are validated as a file's
    would be) and the measured trace it is identified against."""

    diff_step = DIFF_STEP  # the output-error fit's relative step (emasim.identification.fit)
    tolerance = TOLERANCE  # ... and its stopping tolerance
    threads = 1  # its simulations take milliseconds: one at a time
    time_signal = "time_s"

    def __init__(self, raw: dict, source: str, trace: Trace, scenario: AxisScenario | None = None):
        self.raw, self.source, self.trace = raw, source, trace
        self.scenario = validate_axis(raw, source) if scenario is None else scenario
        period = self.scenario.loop.sample_period_s
        if abs(trace.sample_period_s - period) > SAMPLING_TOLERANCE * period:  # before filtering
            raise InputError(
                f"--data {trace.path}: sampled every {trace.sample_period_s:.6g} s; the "
                f"scenario's loop runs every {period:g} s (loop.sample_period_s); give the "
                "time in s"
            )
        self._check_motion()
        self.motion = idim.bandpass(trace.signals["position_m"], trace.sample_period_s)
        self.outputs = {
            name: weight
            for name, weight in self.scenario.identify.outputs.items()
            if name in trace.signals
        }
        if not self.outputs:
            raise InputError(
                f"--data {trace.path}: none of the outputs the fit compares "
                f"({', '.join(self.scenario.identify.outputs)}) is in the file"
            )

    def _check_motion(self) -> None:
        """Refuse, in one line, a measured position the scenario's axis cannot make: a span
        beyond its stroke, or a step from one sample to the next faster than its top speed.
        Positions in mm, or traces joined with a jump at the seam, would otherwise be fitted
        as a wildly wrong mass and friction, or not simulate at all."""
        plant, trace = self.scenario.plant, self.trace
        position = trace.signals["position_m"]
        span = float(np.ptp(position))
        if span > plant.stroke_m:
            raise InputError(
                f"--data {trace.path}: the position spans {span:.4g} m, beyond the axis's "
                f"stroke (plant.stroke_m = {plant.stroke_m:g}); give positions in m"
            )
        speed = np.abs(np.diff(position)) / trace.sample_period_s
        at = int(np.argmax(speed))
        if speed[at] > plant.max_speed_m_s:
            raise InputError(
                f"--data {trace.path}: the position moves at {speed[at]:.4g} m/s from sample "
                f"{at} to {at + 1}, beyond the axis's top speed (plant.max_speed_m_s = "
                f"{plant.max_speed_m_s:g}): a jump, where traces were joined?"
            )

    @classmethod
    def read(cls, raw: dict, source: str, data, mapping: dict[str, str]) -> "AxisModel":
        """Bind the scenario to the trace of the file ``data``, its columns mapped by the
        scenario's map updated with ``mapping``."""
        scenario = validate_axis(raw, source)
        trace = load_trace(data, SIGNALS, REQUIRED, mapping, scenario.identify.map)
        return cls(raw, source, trace, scenario)

    def check_keys(self, keys: list[Key]) -> None:
        """Refuse, in one line, a key that is not a number of the scenario or whose range
        leaves the field's own."""
        for key in keys:
            if key.scaled:
                raise InputError(f"--fit {key.path}: an axis scenario fits values, not factors")
            for value in (key.low, key.high):
                self.with_values({key.path: value}, what=f"--fit {key.path}")

    def value(self, key: Key) -> float:
        """The scenario's own value of ``key``, the fit's start without an IDIM estimate."""
        value = raw_value(self.raw, key.path)
        if not isinstance(value, float | int):
            raise InputError(f"--fit {key.path}: the scenario does not set it; give it with --set")
        return float(value)

    def raw_with(self, values: dict[str, float], what: str = "--fit") -> dict:
        """A copy of the scenario's raw table with the dotted keys set to ``values``."""
        raw = copy.deepcopy(self.raw)
        for path, value in values.items():
            if isinstance(raw_value(raw, path), dict | list | str | bool):
                raise InputError(f"{what}: '{path}' is not a number of the scenario")
            set_key(raw, path, float(value), what)
        return raw

    def with_values(self, values: dict[str, float], what: str = "--fit") -> AxisScenario:
        """The scenario with the dotted keys set to ``values``, validated."""
        return validate_axis(self.raw_with(values, what), f"{what} {self.source}")

    def simulate(self, scenario: AxisScenario, ideal_reading: bool = False) -> dict:
        """The simulated trace (emasim.sim.axis_loop.COLUMNS) from the measured inputs; with
        ``ideal_reading`` the encoder is not quantised (module docstring). Values whose
        fastest mode the loop's sub-step cannot integrate (axis_loop.stable_substeps) are an
        InputError: a candidate the fit scores as diverged, or values identify names."""
        signals = self.trace.signals
        position = signals["position_m"]
        loop = scenario.loop.loop()
        if ideal_reading:
            loop = replace(loop, resolution_m=0.0)
        try:
            return simulate_axis(
                scenario.plant,
                loop,
                signals["reference_m"],
                signals.get(INPUTS[1]),
                position0=float(position[0]),
                velocity0=float(position[1] - position[0]) / self.trace.sample_period_s,
            )
        except ValueError as err:
            raise InputError(str(err)) from None

    def compared(self, simulated: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The simulated counterparts of the measured outputs, by signal."""
        return {
            "position_m": simulated["measured_position_m"],
            "command_V": simulated["command_V"],
        }

    def residuals(self, keys: list[Key]):
        """values -> the weighted relative residuals of the outputs (emasim.identification.fit)."""
        measured = {name: self.trace.signals[name] for name in self.outputs}
        norms = {name: float(np.linalg.norm(values)) for name, values in measured.items()}

        def residual(values: np.ndarray) -> np.ndarray:
            scenario = self.with_values(dict(zip((k.path for k in keys), values, strict=True)))
            simulated = self.compared(self.simulate(scenario, ideal_reading=True))
            return np.concatenate(
                [
                    weight * (simulated[name] - measured[name]) / norms[name]
                    for name, weight in self.outputs.items()
                ]
            )

        return residual

    def errors(self, scenario: AxisScenario) -> tuple[dict[str, float], dict]:
        """The relative errors |y - y_sim| / |y| of the free-run simulation (position, drive
        input, and velocity and acceleration, both band-passed as IDIM-LS does) with its
        position RMSE (mm, ``position_rmse_mm``), and the simulated outputs (:meth:`compared`)."""
        compared = self.compared(self.simulate(scenario))
        measured = self.motion
        model = idim.bandpass(compared["position_m"], self.trace.sample_period_s)
        errors = {
            name: relative_error(self.trace.signals[name], compared[name])
            for name in ("position_m", "command_V")
            if name in self.trace.signals
        }
        errors["velocity_m_s"] = relative_error(measured.velocity, model.velocity)
        errors["acceleration_m_s2"] = relative_error(measured.acceleration, model.acceleration)
        miss = self.trace.signals["position_m"] - compared["position_m"]
        errors["position_rmse_mm"] = float(1e3 * np.sqrt(np.mean(miss**2)))
        return errors, compared

    def _inverse_model(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The inverse model's columns by key and the measured force g_tau * command (N)."""
        if "command_V" not in self.trace.signals:
            raise InputError("--method idim: the trace has no command_V (the drive's input)")
        plant = self.scenario.plant
        motion = self.motion
        try:
            columns = inverse_model(plant.friction.model, motion.velocity, motion.acceleration)
        except ValueError as err:
            raise InputError(f"--method idim: {err}; use --method output-error") from None
        force = plant.drive_gain_N_per_V * self.trace.signals["command_V"]
        return {PLANT_PREFIX + name: column for name, column in columns.items()}, force

    def inverse_error(self, values: dict[str, float]) -> float:
        """The inverse model's relative error on this trace with ``values`` (the scenario's
        for the other parameters), decimated as IDIM-LS is: the cross-test of an estimate."""
        columns, force = self._inverse_model()
        model = sum(
            values.get(path, float(raw_value(self.raw, path) or 0.0)) * column
            for path, column in columns.items()
        )
        return idim.decimated_error(force, model)

    def idim(self, keys: list[Key], decimation: int = idim.DECIMATION) -> idim.Estimate:
        """IDIM-LS of the fitted keys: the inverse model's columns of those keys against the
        measured force g_tau * command, less the terms of the parameters not fitted."""
        columns, force = self._inverse_model()
        unknown = [k.path for k in keys if k.path not in columns]
        if unknown:
            raise InputError(
                f"--method idim: {', '.join(unknown)} is not a parameter of the inverse model "
                f"(its parameters: {', '.join(columns)}); use --method output-error"
            )
        fitted = {k.path for k in keys}
        for path, column in columns.items():
            if path not in fitted:
                value = raw_value(self.raw, path)
                force = force - (0.0 if value is None else float(value)) * column
        return idim.least_squares({k.path: columns[k.path] for k in keys}, force, decimation)


def raw_value(raw: dict, path: str):
    """The raw value at a dotted path, or None."""
    node = raw
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node
