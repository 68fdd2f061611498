"""Scenarios of a force-driven axis (emasim.plant.axis) in its closed loop, for identification.

Such a scenario (``kind = "axis"``, in ``scenarios/axis/``) holds the axis, its loop
(emasim.sim.axis_loop) and how to identify it from a measured trace: the keys it fits by
default with their ranges, the map from a data file's columns to its signals, and the
weight of each measured output in the output-error fit. Its reference comes from the
measured trace, so it runs under ``emasim identify``, never alone.
"""

import tomllib
from importlib import resources
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, model_validator

from ..config import Strict
from ..errors import InputError
from ..plant.axis import AxisParams
from ..sim.axis_loop import AxisLoop
from .loader import apply_setting, check_raw, describe_errors, parse_toml, read_scenario_text

# the signals an axis trace holds: time, the loop's reference and added command (inputs), the
# encoder's reading and the drive's input (outputs)
SIGNALS = ("time_s", "reference_m", "added_command_V", "position_m", "command_V")
INPUTS = ("reference_m", "added_command_V")
REQUIRED = ("time_s", "reference_m", "position_m")
OUTPUTS = ("position_m", "command_V")
MAX_SUBSTEPS = 1000


class AxisLoopConfig(Strict):
    """The loop of emasim.sim.axis_loop: sampling, integration, encoder, gains, drive."""

    sample_period_s: float = Field(gt=0.0, le=1.0)
    substeps: int = Field(ge=1, le=MAX_SUBSTEPS, description="RK4 sub-steps per sample")
    # bounded as the axis's numbers are (emasim.plant.axis.AxisFriction)
    encoder_resolution_m: float = Field(ge=0.0, le=0.01, description="0: an ideal reading")
    kp_per_s: float = Field(gt=0.0, le=1e5)
    kv_V_s_per_m: float = Field(gt=0.0, le=1e7)
    command_limit_V: float = Field(gt=0.0, le=1e4)
    computation_delay_s: float = Field(ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _delay_in_substeps(self):
        h = self.sample_period_s / self.substeps
        steps = self.computation_delay_s / h
        if self.computation_delay_s > self.sample_period_s or abs(steps - round(steps)) > 1e-9:
            raise ValueError(
                f"computation_delay_s={self.computation_delay_s} must be a whole number of "
                f"sub-steps ({h:.6g} s) from 0 to sample_period_s={self.sample_period_s}"
            )
        return self

    def loop(self) -> AxisLoop:
        h = self.sample_period_s / self.substeps
        return AxisLoop(
            self.sample_period_s,
            self.substeps,
            self.encoder_resolution_m,
            self.kp_per_s,
            self.kv_V_s_per_m,
            self.command_limit_V,
            round(self.computation_delay_s / h),
        )


class IdentifyConfig(Strict):
    """How to identify the scenario by default: ``fit`` the keys ``KEY=LOW:HIGH``, ``map``
    file column -> signal, ``outputs`` measured signal -> its weight in the fit's cost, and the
    method."""

    fit: list[str] = Field(min_length=1)
    map: dict[str, Literal[SIGNALS]] = {}
    outputs: dict[Literal[OUTPUTS], float] = Field(min_length=1)
    method: Literal["output-error", "idim"] = "output-error"

    @model_validator(mode="after")
    def _weights(self):
        bad = {k: w for k, w in self.outputs.items() if not w > 0.0}
        if bad:
            raise ValueError(f"outputs: every weight must be > 0 (got {bad})")
        return self


class AxisScenario(Strict):
    """A force-driven axis in its loop, identified against measured traces."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
    kind: Literal["axis"]
    description: str = ""
    source: str = Field(default="", description="where the axis and its data come from")
    plant: AxisParams
    loop: AxisLoopConfig
    identify: IdentifyConfig


def builtin_axis_scenarios() -> dict[str, Path]:
    """Name -> path of every axis scenario shipped with the package."""
    folder = resources.files(__package__) / "axis"
    return {p.name[:-5]: Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml")}


def is_axis_scenario(name_or_path: str) -> bool:
    """Whether ``name_or_path`` is a shipped axis scenario or a file declaring kind = "axis"."""
    if name_or_path in builtin_axis_scenarios():
        return True
    path = Path(name_or_path)
    if path.suffix != ".toml" or not path.is_file():
        return False
    try:
        return tomllib.loads(path.read_text(encoding="utf-8-sig")).get("kind") == "axis"
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError):
        return False  # read_axis_raw names the problem


def read_axis_raw(name_or_path: str) -> tuple[dict, str, str]:
    """The raw table of an axis scenario (a shipped name or a path), where it came from and
    its text."""
    shipped = builtin_axis_scenarios()
    path = str(shipped[name_or_path]) if name_or_path in shipped else name_or_path
    text, source = read_scenario_text(path)
    source = name_or_path if name_or_path in shipped else source
    raw = parse_toml(text, f"scenario: {source}")
    check_raw(raw, source)
    return raw, source, text


def validate_axis(raw: dict, source: str) -> AxisScenario:
    """An AxisScenario, or one InputError line per field that is wrong."""
    try:
        return AxisScenario.model_validate(raw)
    except ValidationError as err:
        raise InputError(f"{source}: " + "; ".join(describe_errors(err, AxisScenario))) from None


def load_axis_scenario(name_or_path: str, settings: list[str] = ()) -> AxisScenario:
    """Read, override (``--set KEY=VALUE``) and validate an axis scenario."""
    raw, source, _ = read_axis_raw(name_or_path)
    for setting in settings:
        apply_setting(raw, setting)
    return validate_axis(raw, source)
