"""The refusal corpus: every bad input is refused cleanly, and no user data is ever lost.

What it proves, case by case, on the real command line (``emasim.cli.app`` in-process, and the
installed program in a few subprocess cases):

* every refused input (a bad number in any section, a malformed or hostile scenario file, a bad
  option, an output path that holds someone else's data) exits with code 2 and exactly one
  non-empty line on stderr starting with ``error:``, no Python traceback;
* nothing is written or changed on disk by a refused input: the whole working folder (every
  path, the bytes and mode of every file, every link target) is the same afterwards, and the
  user's own files (``thesis.tex``, ``victim.txt``, a user folder) are never touched;
* accepted runs never replace a result without ``--force``, never replace anything emasim did
  not write, leave no temporaries behind, write valid JSON, and clean up only the temporaries
  of dead emasim processes;
* faults: a run killed at any moment leaves its folder complete or absent, two concurrent runs
  to one folder never lose data, and a killed tuning study resumes.
"""

import json
import os
import signal
import stat
import subprocess
import sys
import time
import typing
import warnings
from pathlib import Path

import pytest
from helpers import HANG_GUARD_S
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from typer.testing import CliRunner

from emasim.cli import app
from emasim.control.adrc import SpeedADRC
from emasim.control.current import CurrentPI
from emasim.control.fuzzy import PositionFuzzyPI
from emasim.control.pid import PositionPID, SpeedPI
from emasim.control.rbf import PositionSlidingMode
from emasim.control.smc import SpeedSMC
from emasim.control.super_twisting import SpeedSuperTwisting
from emasim.experiments.store import read_table
from emasim.output import MARKER, foreign_files
from emasim.plant.contact import ContactParams
from emasim.plant.elements.linkage import LinkageParams
from emasim.plant.parameters import (
    BacklashParams,
    DrivetrainParams,
    FrictionParams,
    LoadParams,
    MotorParams,
    SensorChannel,
)
from emasim.plant.presets import sea805
from emasim.scenarios.loader import read_scenario_file, validate_scenario
from emasim.scenarios.schema import Scenario, Solver
from emasim.signals import Constant, Ramp, Sine, Step, Table

runner = CliRunner()

USER_FILE = "thesis.tex"
USER_TEXT = b"\\documentclass{article}\n% three years of work\n"
USER_MODE = 0o640
SHORT = ["--set", "duration_s=0.05", "--no-plot"]  # a refused case that is accepted stays short
RUN_FILES = {MARKER, "result.parquet", "metrics.json", "meta.json", "scenario.toml"}


# --- the working folder, its snapshot, and the refusal check -----------------------------------


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A fresh working folder holding the user's thesis, made the current directory."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("EMASIM_TRACEBACK", raising=False)
    user_file(tmp_path / USER_FILE, USER_TEXT)
    return tmp_path


def user_file(path: Path, content: bytes, mode: int = USER_MODE) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content)
    path.chmod(mode)
    return path


def snapshot(root: Path) -> dict[str, tuple]:
    """Every path under ``root`` (links not followed): its type and mode, and a file's bytes
    and modification time, a link's target."""
    tree = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            path = Path(folder, name)
            st = path.lstat()
            if stat.S_ISLNK(st.st_mode):
                entry = ("link", os.readlink(path))
            elif stat.S_ISREG(st.st_mode):
                entry = ("file", st.st_mode, st.st_mtime_ns, path.read_bytes())
            else:
                entry = ("dir", st.st_mode)
            tree[str(path.relative_to(root))] = entry
    return tree


def invoke(*args: str):
    return runner.invoke(app, list(args))


def error_lines(stderr: str) -> list[str]:
    """stderr's lines but blank ones and the note a cold numba cache prints (which depends
    on what ran before, not on the input)."""
    return [
        line
        for line in stderr.splitlines()
        if line.strip() and not line.startswith("compiling the simulation core")
    ]


def assert_refused(result, needle: str = "") -> None:
    """Exit code 2, one ``error:`` line on stderr (holding ``needle``), no traceback."""
    shown = f"exit {result.exit_code}\nstdout: {result.stdout}\nstderr: {result.stderr}"
    assert result.exit_code == 2, shown
    assert isinstance(result.exception, SystemExit | None), shown
    lines = error_lines(result.stderr)
    assert len(lines) == 1 and lines[0].startswith("error:"), shown
    assert "Traceback" not in result.stdout + result.stderr, shown
    assert needle in lines[0], shown


def assert_refused_untouched(root: Path, args: list[str], needle: str = "") -> None:
    """Run ``args``; it must be refused, warn nothing (a warning would be one more line on a
    real stderr) and leave the whole tree under ``root`` as it was."""
    before = snapshot(root)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")  # what a plain ``python`` shows, less the hidden kinds
        for hidden in (
            DeprecationWarning,
            PendingDeprecationWarning,
            ImportWarning,
            ResourceWarning,
        ):
            warnings.filterwarnings("ignore", category=hidden)
        result = invoke(*args)
    after = snapshot(root)
    assert_refused(result, needle)
    assert not caught, [f"{w.category.__name__}: {w.message}" for w in caught]
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    assert after == before, f"changed on disk: {changed}"


def assert_only_added(before: dict, after: dict, under: str) -> None:
    """Everything of ``before`` is unchanged; new paths lie only under ``under``."""
    assert {k: after.get(k) for k in before} == before
    assert all(k == under or k.startswith(under + os.sep) for k in set(after) - set(before))


def leftovers(root: Path) -> list[Path]:
    return list(root.rglob(".*.tmp-*"))


def strict_json(path: Path):
    """json.loads that refuses the NaN, Infinity and -Infinity tokens (not JSON)."""

    def refuse(token):
        raise ValueError(f"{path}: {token} is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


# --- generated cases: every bad kind of value in many numeric fields ---------------------------


def bounds(model: type[BaseModel], name: str) -> tuple[float, float]:
    """(lower, upper) bound of a number field, also of a tuple's or a list's elements."""
    found = {}

    def visit(metadata):
        for item in metadata:
            if isinstance(item, FieldInfo):
                visit(item.metadata)
            for key in ("ge", "gt", "le", "lt"):
                if getattr(item, key, None) is not None:
                    found[key] = getattr(item, key)

    field = model.model_fields[name]
    visit(field.metadata)
    for arg in typing.get_args(field.annotation):
        visit(getattr(arg, "__metadata__", ()))
    lower, upper = found.get("ge", found.get("gt")), found.get("le", found.get("lt"))
    assert lower is not None and upper is not None, f"{model.__name__}.{name} is unbounded"
    return lower, upper


def is_int_field(model: type[BaseModel], name: str) -> bool:
    return model.model_fields[name].annotation is int


def bad_value(kind: str, model: type[BaseModel], name: str) -> str:
    """The TOML text of a value of ``kind`` that the field must refuse."""
    if kind == "string":
        return '"1"'
    if kind == "bool":
        return "true"
    if kind in ("nan", "inf"):
        return kind
    lower, upper = bounds(model, name)
    value = lower - 1 - 1e3 * abs(lower) if kind == "below" else upper + 1 + 1e3 * abs(upper)
    return str(int(value)) if is_int_field(model, name) else repr(float(value))


SPEED = ("speed-step", ["-c", "speed=pi"])
POSITION = ("position-step", ["-c", "speed=pi"])
BENCH = ("bench-step", ["-c", "pid"])

# (scenario, extra arguments, dotted key, model, field, TOML template: @ is the bad value)
FIELDS = [
    (*SPEED, "duration_s", Scenario, "duration_s", "@"),
    (*SPEED, "seed", Scenario, "seed", "@"),
    (*SPEED, "solver.sample_period_s", Solver, "sample_period_s", "@"),
    (*SPEED, "solver.step_s", Solver, "step_s", "@"),
    (*SPEED, "solver.record_period_s", Solver, "record_period_s", "@"),
    (*SPEED, "plant.motor.inertia_kgm2", MotorParams, "inertia_kgm2", "@"),
    (*SPEED, "plant.motor.resistance_ohm", MotorParams, "resistance_ohm", "@"),
    (*SPEED, "plant.motor.pole_pairs", MotorParams, "pole_pairs", "@"),
    (*SPEED, "plant.motor.max_speed_rpm", MotorParams, "max_speed_rpm", "@"),
    (*SPEED, "plant.motor.dc_bus_V", MotorParams, "dc_bus_V", "@"),
    (*SPEED, "plant.drivetrain.screw_lead_mm", DrivetrainParams, "screw_lead_mm", "@"),
    (*SPEED, "plant.drivetrain.gear_efficiency", DrivetrainParams, "gear_efficiency", "@"),
    (*SPEED, "plant.drivetrain.stroke_mm", DrivetrainParams, "stroke_mm", "@"),
    (*SPEED, "plant.friction.coulomb_Nm", FrictionParams, "coulomb_Nm", "@"),
    (
        *SPEED,
        "plant.friction.bristle_stiffness_Nm_per_rad",
        FrictionParams,
        "bristle_stiffness_Nm_per_rad",
        "@",
    ),
    (*SPEED, "plant.backlash.width_mm", BacklashParams, "width_mm", "@"),
    (*SPEED, "plant.backlash.stiffness_N_per_m", BacklashParams, "stiffness_N_per_m", "@"),
    (*SPEED, "plant.load.rod_mass_kg", LoadParams, "rod_mass_kg", "@"),
    (*SPEED, "plant.load.rudder_arm_mm", LoadParams, "rudder_arm_mm", "@"),
    (*SPEED, "sensors.speed.noise_std", SensorChannel, "noise_std", "@"),
    (*SPEED, "sensors.position.offset", SensorChannel, "offset", "@"),
    (*SPEED, "sensors.iq.gap_width", SensorChannel, "gap_width", "@"),
    (*SPEED, "controllers.speed.bandwidth_Hz", SpeedPI, "bandwidth_Hz", "@"),
    (*SPEED, "controllers.speed.kp_A_s_per_rad", SpeedPI, "kp_A_s_per_rad", "@"),
    (*SPEED, "controllers.current.bandwidth_Hz", CurrentPI, "bandwidth_Hz", "@"),
    (*SPEED, "reference.speed_rpm", Step, "final", '[{ type = "step", final = @ }]'),
    (*SPEED, "reference.speed_rpm", Step, "time_s", '[{ type = "step", time_s = @, final = 1.0 }]'),
    (
        *SPEED,
        "reference.speed_rpm",
        Sine,
        "frequency_Hz",
        '[{ type = "sine", amplitude = 100.0, frequency_Hz = @ }]',
    ),
    (
        *SPEED,
        "reference.speed_rpm",
        Sine,
        "phase_deg",
        '[{ type = "sine", amplitude = 100.0, frequency_Hz = 1.0, phase_deg = @ }]',
    ),
    (*SPEED, "load.motor_torque_Nm", Ramp, "slope_per_s", '[{ type = "ramp", slope_per_s = @ }]'),
    (*SPEED, "load.rod_force_N", Constant, "value", '[{ type = "constant", value = @ }]'),
    (
        "speed-step",
        ["-c", "speed=smc"],
        "controllers.speed.switching_gain_rad_s2",
        SpeedSMC,
        "switching_gain_rad_s2",
        "@",
    ),
    (
        "speed-step",
        ["-c", "speed=st-gpio"],
        "controllers.speed.boundary_layer_rad_s",
        SpeedSuperTwisting,
        "boundary_layer_rad_s",
        "@",
    ),
    (
        "speed-step",
        ["-c", "speed=st-gpio"],
        "controllers.speed.observer_bandwidth_Hz",
        SpeedSuperTwisting,
        "observer_bandwidth_Hz",
        "@",
    ),
    (
        "speed-step",
        ["-c", "speed=adrc"],
        "controllers.speed.observer_bandwidth_Hz",
        SpeedADRC,
        "observer_bandwidth_Hz",
        "@",
    ),
    (
        "position-step",
        ["-c", "position=pid"],
        "controllers.position.bandwidth_Hz",
        PositionPID,
        "bandwidth_Hz",
        "@",
    ),
    ("position-step", ["-c", "position=pid"], "controllers.position.kd", PositionPID, "kd", "@"),
    (
        "position-step",
        ["-c", "position=pid"],
        "controllers.position.derivative_filter_s",
        PositionPID,
        "derivative_filter_s",
        "@",
    ),
    (
        "position-step",
        ["-c", "position=fuzzy-pi"],
        "controllers.position.kp_span",
        PositionFuzzyPI,
        "kp_span",
        "@",
    ),
    (
        "position-step",
        ["-c", "position=rbf-smc"],
        "controllers.position.adaptation_gain",
        PositionSlidingMode,
        "adaptation_gain",
        "@",
    ),
    (
        "position-step",
        ["-c", "position=rbf-smc"],
        "controllers.position.nodes_per_axis",
        PositionSlidingMode,
        "nodes_per_axis",
        "@",
    ),
    (
        *POSITION,
        "reference.position_mm",
        Table,
        "values",
        '[{ type = "table", time_s = [0.0, 1.0], values = [0.0, @] }]',
    ),
    (
        *POSITION,
        "reference.position_mm",
        Table,
        "time_s",
        '[{ type = "table", time_s = [0.0, @], values = [0.0, 1.0] }]',
    ),
    (*BENCH, "plant.linkage.rod_length_mm", LinkageParams, "rod_length_mm", "@"),
    (*BENCH, "plant.linkage.rocker_arm_1_mm", LinkageParams, "rocker_arm_1_mm", "@"),
    (*BENCH, "plant.linkage.pin_radius_mm", LinkageParams, "pin_radius_mm", "@"),
    (
        *BENCH,
        "plant.linkage.rudder_damping_Nms_per_rad",
        LinkageParams,
        "rudder_damping_Nms_per_rad",
        "@",
    ),
    (
        *BENCH,
        "plant.linkage.hinge_clearance_mm",
        LinkageParams,
        "hinge_clearance_mm",
        "[@, 0.01, 0.01, 0.01]",
    ),
    (
        *BENCH,
        "plant.linkage.hinge_clearance_mm",
        LinkageParams,
        "hinge_clearance_mm",
        "[0.01, 0.01, 0.01, @]",
    ),
    (
        *BENCH,
        "plant.linkage.actuator_pivot_mm",
        LinkageParams,
        "actuator_pivot_mm",
        "[@, -750.0]",
    ),
    (*BENCH, "plant.linkage.contact.exponent", ContactParams, "exponent", "@"),
    (*BENCH, "plant.linkage.contact.mu_static", ContactParams, "mu_static", "@"),
    (*BENCH, "sensors.force.resolution", SensorChannel, "resolution", "@"),
    (*BENCH, "reference.rudder_deg", Step, "final", '[{ type = "step", final = @ }]'),
    (*BENCH, "load.rudder_torque_Nm", Step, "final", '[{ type = "step", final = @ }]'),
    (
        "cosim-step",
        ["-c", "pid"],
        "solver.communication_step_s",
        Solver,
        "communication_step_s",
        "@",
    ),
]
KINDS = ["string", "bool", "below", "above", "nan", "inf"]


def field_id(case) -> str:
    scenario, args, key, _, _, template = case
    return f"{scenario}[{args[1]}]:{key}" + ("" if template == "@" else f"={template}")


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("case", FIELDS, ids=field_id)
def test_a_bad_number_is_refused(work, case, kind):
    scenario, args, key, model, name, template = case
    value = template.replace("@", bad_value(kind, model, name))
    command = ["run", scenario, *args, *SHORT, "--set", f"{key}={value}"]
    assert_refused_untouched(work, command, needle=name)  # the line names the field


# --- hand-written scenario files ----------------------------------------------------------------

HEAD = 'name = "corpus"\nduration_s = 0.05\n'
SPEED_REF = '[reference]\nspeed_rpm = [{ type = "step", final = 100.0 }]\n'
POSITION_REF = '[reference]\nposition_mm = [{ type = "step", final = 10.0 }]\n'
RUDDER_REF = '[reference]\nrudder_deg = [{ type = "step", final = 1.0 }]\n'
LUMPED = '[plant]\npreset = "sea805"\n'
LINKED = '[plant]\npreset = "sea805-linkage"\n'
PI = '[controllers.speed]\nname = "pi"\n'
CASCADE_PID = '[controllers]\ncascade = "pid"\n'
MAX_RPM = sea805().motor.max_speed_rpm
STROKE_MM = sea805().drivetrain.stroke_mm


def speed_file(*sections: str, head: str = HEAD) -> str:
    """A valid speed-loop scenario; ``head`` holds the top-level keys, ``sections`` tables."""
    return head + LUMPED + PI + "".join(sections) + SPEED_REF


def linkage_file(linkage: str) -> str:
    return HEAD + LINKED + "[plant.linkage]\n" + linkage + CASCADE_PID + RUDDER_REF


NESTED = 50_000
CLEARANCE = "hinge_clearance_mm"
# (id, file content, what the error line must name)
FILES = [
    ("binary", bytes(range(256)) * 16, "UTF-8"),
    (
        "latin-1",
        (HEAD + 'description = "Müller"\n' + LUMPED + PI + SPEED_REF).encode("latin-1"),
        "UTF-8",
    ),
    ("empty", "", "name"),
    ("bad-syntax", "name = \n", "TOML"),
    (
        "nested-50000-arrays",
        speed_file() + "deep = " + "[" * NESTED + "]" * NESTED + "\n",
        "nested",
    ),
    (
        "nested-50000-tables",
        speed_file() + "deep = " + "{ a = " * NESTED + "1" + " }" * NESTED,
        "nested",
    ),
    ("nul-in-name", speed_file(head='name = "a\\u0000b"\nduration_s = 0.05\n'), "name"),
    ("nul-in-description", speed_file(head=HEAD + 'description = "x\\u0000"\n'), "description"),
    ("escape-in-key", speed_file().replace("duration_s", '"dura\\u001btion_s"'), "control"),
    ("reference-is-a-number", HEAD + "reference = 5\n" + LUMPED + PI, "reference"),
    ("reference-empty", HEAD + LUMPED + PI + "[reference]\nspeed_rpm = []\n", "reference"),
    (
        "reference-two-loops",
        speed_file() + 'position_mm = [{ type = "step", final = 1.0 }]\n',
        "reference",
    ),
    ("reference-missing", HEAD + LUMPED + PI, "reference"),
    (
        "reference-unknown-term",
        HEAD + LUMPED + PI + '[reference]\nspeed_rpm = [{ type = "square", final = 1.0 }]\n',
        "square",
    ),
    (
        "cascade-is-a-list",
        HEAD + "controllers = { cascade = [1] }\n" + LUMPED + SPEED_REF,
        "cascade",
    ),
    ("cascade-unknown", HEAD + 'controllers = "fancy"\n' + LUMPED + SPEED_REF, "cascade"),
    ("controllers-is-a-number", HEAD + "controllers = 3\n" + LUMPED + SPEED_REF, "controllers"),
    (
        "plant-preset-is-a-list",
        HEAD + "plant = { preset = [1] }\n" + PI + SPEED_REF,
        "plant.preset",
    ),
    ("plant-preset-unknown", HEAD + 'plant = "sea999"\n' + PI + SPEED_REF, "plant.preset"),
    ("plant-is-a-number", HEAD + "plant = 1\n" + PI + SPEED_REF, "plant"),
    (
        "sensors-preset-is-a-table",
        speed_file(head=HEAD + "sensors = { preset = { a = 1 } }\n"),
        "sensors.preset",
    ),
    (
        "screw-lead-1e300",
        speed_file("[plant.drivetrain]\nscrew_lead_mm = 1e300\n"),
        "screw_lead_mm",
    ),
    ("inertia-1e-300", speed_file("[plant.motor]\ninertia_kgm2 = 1e-300\n"), "inertia_kgm2"),
    ("step-1e-300", speed_file("[solver]\nstep_s = 1e-300\n"), "step_s"),
    ("step-not-dividing-sample", speed_file("[solver]\nstep_s = 3e-5\n"), "step_s"),
    (
        "substeps-too-many",
        speed_file("[solver]\nsample_period_s = 0.01\nstep_s = 1e-8\nrecord_period_s = 0.01\n"),
        "step_s",
    ),
    (
        "record-period-beyond-duration",
        speed_file("[solver]\nrecord_period_s = 0.1\n"),
        "record_period_s",
    ),
    (
        "mechanism-fmu-without-cosim",
        speed_file('[solver]\nmechanism_fmu = "x.fmu"\n'),
        "mechanism_fmu",
    ),
    (
        "duration-is-a-string",
        speed_file(head='name = "corpus"\nduration_s = "0.05"\n'),
        "duration_s",
    ),
    ("duration-is-true", speed_file(head='name = "corpus"\nduration_s = true\n'), "duration_s"),
    (
        "duration-below-sample",
        speed_file(head='name = "corpus"\nduration_s = 1e-5\n'),
        "duration_s",
    ),
    ("seed-is-a-float", speed_file(head=HEAD + "seed = 1.5\n"), "seed"),
    ("seed-negative", speed_file(head=HEAD + "seed = -1\n"), "seed"),
    (
        "speed-1e300-rpm",
        HEAD + LUMPED + PI + '[reference]\nspeed_rpm = [{ type = "step", final = 1e300 }]\n',
        "speed_rpm",
    ),
    (
        "speed-beyond-max-speed",
        HEAD
        + LUMPED
        + PI
        + f'[reference]\nspeed_rpm = [{{ type = "step", final = {1.5 * MAX_RPM} }}]\n',
        "max_speed_rpm",
    ),
    (
        "speed-sine-beyond-max-speed",
        HEAD + LUMPED + PI + "[reference]\nspeed_rpm = [{ type = "
        f'"sine", amplitude = {1.5 * MAX_RPM}, frequency_Hz = 100.0 }}]\n',
        "max_speed_rpm",
    ),
    (
        "position-beyond-half-stroke",
        HEAD
        + LUMPED
        + PI
        + '[controllers.position]\nname = "pid"\n'
        + f'[reference]\nposition_mm = [{{ type = "step", final = {0.6 * STROKE_MM} }}]\n',
        "stroke_mm",
    ),
    ("position-without-position-loop", HEAD + LUMPED + PI + POSITION_REF, "controllers.position"),
    (
        "position-loop-on-speed",
        speed_file('[controllers.position]\nname = "pid"\n'),
        "controllers.position",
    ),
    (
        "rudder-beyond-stroke",
        HEAD
        + LINKED
        + CASCADE_PID
        + '[reference]\nrudder_deg = [{ type = "step", final = 89.0 }]\n',
        "rudder_deg",
    ),
    (
        "ramp-ends-before-start",
        HEAD + LUMPED + PI + '[reference]\nspeed_rpm = [{ type = "ramp", '
        "slope_per_s = 1.0, start_s = 1.0, end_s = 0.5 }]\n",
        "end_s",
    ),
    (
        "table-time-not-rising",
        HEAD + LUMPED + PI + '[reference]\nspeed_rpm = [{ type = "table", '
        "time_s = [0.0, 0.0], values = [1.0, 2.0] }]\n",
        "time_s",
    ),
    (
        "table-lengths-differ",
        HEAD + LUMPED + PI + '[reference]\nspeed_rpm = [{ type = "table", '
        "time_s = [0.0, 1.0, 2.0], values = [1.0, 2.0] }]\n",
        "time_s",
    ),
    (
        "stiction-below-coulomb",
        speed_file("[plant.friction]\ncoulomb_Nm = 1.0\nstatic_Nm = 0.5\n"),
        "static_Nm",
    ),
    (
        "kd-on-pi",
        HEAD + LUMPED + PI + '[controllers.position]\nname = "pi"\nkd = 0.1\n' + POSITION_REF,
        "kd",
    ),
    ("linkage-cannot-close", linkage_file("link_length_mm = 1.0\n"), "linkage"),
    ("linkage-rod-too-short", linkage_file("rod_length_mm = 1.0\n"), "linkage"),
    (
        "linkage-negative-clearance",
        linkage_file("hinge_clearance_mm = [-0.01, 0.01, 0.01, 0.01]\n"),
        CLEARANCE,
    ),
    (
        "linkage-three-clearances",
        linkage_file("hinge_clearance_mm = [0.01, 0.01, 0.01]\n"),
        CLEARANCE,
    ),
    (
        "linkage-clearance-strings",
        linkage_file('hinge_clearance_mm = ["0.01", "0.01", "0.01", "0.01"]\n'),
        CLEARANCE,
    ),
    ("linkage-pivot-nan", linkage_file("actuator_pivot_mm = [nan, -750.0]\n"), "actuator_pivot_mm"),
    (
        "linkage-on-lumped-preset",
        speed_file("[plant.linkage]\nrod_length_mm = 500.0\n"),
        "plant.linkage",
    ),
    (
        "compare-labels-same-folder",
        speed_file(
            '[[compare]]\nlabel = "PI"\n[compare.controllers.speed]\nname = "pi"\n'
            '[[compare]]\nlabel = "pi!"\n[compare.controllers.speed]\nname = "pi"\n'
        ),
        "pi!",
    ),
    (
        "compare-labels-equal",
        speed_file(
            '[[compare]]\nlabel = "a"\n[compare.controllers.speed]\nname = "pi"\n'
            '[[compare]]\nlabel = "a"\n[compare.controllers.speed]\nname = "pi"\n'
        ),
        "compare",
    ),
    ("compare-is-a-table", speed_file("[compare]\nlabel = 1\n"), "compare"),
    ("name-climbs-out", speed_file(head='name = "../../../x"\nduration_s = 0.05\n'), "name"),
    ("name-absolute", speed_file(head='name = "/tmp/x"\nduration_s = 0.05\n'), "name"),
    ("name-empty", speed_file(head='name = ""\nduration_s = 0.05\n'), "name"),
    ("name-is-a-number", speed_file(head="name = 5\nduration_s = 0.05\n"), "name"),
    ("name-missing", speed_file(head="duration_s = 0.05\n"), "name"),
    ("unknown-top-level-key", speed_file(head=HEAD + "colour = 1\n"), "colour"),
    ("unknown-motor-key", speed_file("[plant.motor]\ncolour = 1\n"), "plant.motor.colour"),
    (
        "unknown-term-key",
        HEAD
        + LUMPED
        + PI
        + '[reference]\nspeed_rpm = [{ type = "step", final = 1.0, colour = 1 }]\n',
        "colour",
    ),
    ("misspelled-key", speed_file("[plant.backlash]\nwidht_mm = 0.1\n"), "did you mean"),
    ("misspelled-top-level-key", speed_file(head=HEAD + "sede = 1\n"), "did you mean"),
    ("tuning-is-a-table-of-tables", speed_file("[tuning]\na = { b = 1 }\n"), "tuning"),
]


@pytest.mark.parametrize("content,needle", [f[1:] for f in FILES], ids=[f[0] for f in FILES])
def test_a_bad_scenario_file_is_refused(work, content, needle):
    path = work / "case.toml"
    user_file(path, content if isinstance(content, bytes) else content.encode())
    assert_refused_untouched(work, ["run", "case.toml", "--no-plot"], needle)


# --- the command line: options, arguments, and output paths that hold someone else's data ------

VICTIM = b"my data\n"
RUN = ["run", "speed-step", "-c", "speed=pi", *SHORT]
TUNE = ["tune", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.05", "--trials", "1"]
DEEP = "[" * 100 + "]" * 100
COSIM_FMU = ["--set", "solver.communication_step_s=1e-3", "--set", 'solver.mechanism_fmu="x.fmu"']
STUDY = ["study", "cosim-step", "--out", "s", "--set", "duration_s=0.05"]

# (id, arguments, what the error line must name)
CLI = [
    ("out-user-folder", [*RUN, "--out", "userdir"], "userdir"),
    ("out-user-folder-force", [*RUN, "--out", "userdir", "--force"], "userdir"),
    ("out-user-file", [*RUN, "--out", "victim.txt"], "victim.txt"),
    ("out-user-file-force", [*RUN, "--out", "victim.txt", "--force"], "victim.txt"),
    ("out-under-user-file", [*RUN, "--out", "victim.txt/sub"], "victim.txt"),
    ("out-link-to-user-folder", [*RUN, "--out", "link"], "link"),
    ("out-link-to-user-folder-force", [*RUN, "--out", "link", "--force"], "link"),
    ("out-dangling-link", [*RUN, "--out", "dangling"], "dangling"),
    ("out-in-proc", [*RUN, "--out", "/proc/emasim-cannot-write"], "/proc/emasim-cannot-write"),
    ("out-missing-value", [*RUN, "--out"], "--out"),
    ("unknown-option", [*RUN, "--bogus"], "--bogus"),
    ("unknown-command", ["simulate", "speed-step"], "simulate"),
    ("missing-scenario", ["run"], "scenario"),
    ("unknown-scenario", ["run", "no-such-scenario", *SHORT], "no-such-scenario"),
    ("scenario-is-user-file", ["run", USER_FILE, *SHORT], USER_FILE),
    ("scenario-is-a-folder", ["run", "userdir.toml", *SHORT], "userdir.toml"),
    ("scenario-missing-file", ["run", "absent.toml", *SHORT], "absent.toml"),
    ("controller-unknown-name", ["run", "speed-step", "-c", "speed=fancy", *SHORT], "fancy"),
    ("controller-unknown-loop", ["run", "speed-step", "-c", "torque=pi", *SHORT], "torque"),
    ("controller-no-name", ["run", "speed-step", "-c", "speed=", *SHORT], "--controller"),
    ("controller-no-loop", ["run", "speed-step", "-c", "=pi", *SHORT], "--controller"),
    ("controller-bare-word", ["run", "speed-step", "-c", "speed", *SHORT], "--controller"),
    ("controller-wrong-loop", ["run", "speed-step", "-c", "speed=pid", *SHORT], "pid"),
    (
        "controller-position-on-speed",
        ["run", "speed-step", "-c", "position=pid", *SHORT],
        "controllers.position",
    ),
    ("controller-unknown-cascade", ["run", "speed-step", "-c", "hybridx", *SHORT], "hybridx"),
    (
        "position-controller-unknown-name",
        [
            "run",
            "position-step",
            "-c",
            "speed=pi",
            "--set",
            'controllers.position.name="nope"',
            *SHORT,
        ],
        "controllers.position",
    ),
    ("set-no-equals", [*RUN, "--set", "duration_s"], "--set"),
    ("set-no-key", [*RUN, "--set", "=1"], "--set"),
    ("set-leading-dot", [*RUN, "--set", ".duration_s=1"], "--set"),
    ("set-double-dot", [*RUN, "--set", "plant..motor=1"], "--set"),
    ("set-empty-value", [*RUN, "--set", "duration_s="], "duration_s"),
    ("set-bare-word", [*RUN, "--set", "duration_s=fast"], "duration_s"),
    ("set-into-a-value", [*RUN, "--set", "duration_s.x=1"], "duration_s"),
    ("set-section-to-number", [*RUN, "--set", "plant.motor=1"], "plant.motor"),
    ("set-deep-array", [*RUN, "--set", f"duration_s={DEEP}"], "nested"),
    ("set-nul-in-string", [*RUN, "--set", 'name="a\\u0000b"'], "control character"),
    ("set-unknown-key", [*RUN, "--set", "duration_ms=1"], "duration_ms"),
    ("set-misspelled-key", [*RUN, "--set", "duratoin_s=1"], "did you mean"),
    ("set-unknown-preset", [*RUN, "--set", 'plant.preset="nope"'], "plant.preset"),
    ("set-name-climbs-out", [*RUN, "--set", 'name="../x"'], "name"),
    (
        "mechanism-fmu-untrusted",
        ["run", "cosim-step", "-c", "pid", *SHORT, *COSIM_FMU],
        "--trust-fmu",
    ),
    # every scenario rule is checked before anything runs or is written (issue 26)
    ("run-cosim-lumped", [*RUN, "--set", "solver.communication_step_s=1e-3"], "communication"),
    ("tune-cosim-lumped", [*TUNE, "--set", "solver.communication_step_s=1e-3"], "communication"),
    ("tune-mechanism-fmu", ["tune", "cosim-step", "-c", "pid", *COSIM_FMU], "--trust-fmu"),
    ("study-mechanism-fmu-untrusted", [*STUDY, *COSIM_FMU], "--trust-fmu"),
    (
        "study-cosim-lumped",
        ["study", "speed-step", "--out", "s", "--set", "solver.communication_step_s=1e-3"],
        "communication_step_s",
    ),
    ("study-integers-beyond-int64", [*STUDY, "--vary", "seed=integers(0, 1e30)"], "--vary seed"),
    ("study-uniform-overflow", [*STUDY, "--vary", "seed=uniform(-1e308, 1e308)"], "--vary seed"),
    ("study-scheduler-nothing-there", [*STUDY, "--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
    (
        "reproduce-robustness-one-bench",
        ["reproduce", "--robustness", "--only", "bench-step"],
        "both",
    ),
    (
        "reproduce-robustness-no-bench",
        ["reproduce", "--robustness", "--only", "speed-step"],
        "both",
    ),
    ("tune-save-user-file", [*TUNE, "--save", "victim.toml"], "--save"),
    ("tune-save-user-file-force", [*TUNE, "--save", "victim.toml", "--force"], "--save"),
    ("tune-save-under-user-file", [*TUNE, "--save", "victim.txt/t.toml"], "--save"),
    ("tune-zero-trials", [*TUNE, "--trials", "0"], "--trials"),
    ("tune-negative-seed", [*TUNE, "--seed", "-1"], "--seed"),
    ("tune-bad-set", [*TUNE, "--set", "duration_s=nan"], "duration_s"),
    ("tune-unknown-scenario", ["tune", "nosuch", "--trials", "1"], "nosuch"),
    ("export-fmu-user-file", ["export-fmu", "--out", "victim.fmu"], "--out"),
    ("export-fmu-user-file-force", ["export-fmu", "--out", "victim.fmu", "--force"], "--out"),
    ("export-fmu-not-fmu-name", ["export-fmu", "--out", "x.txt"], "--out"),
    ("export-fmu-over-user-text", ["export-fmu", "--out", "victim.txt"], "--out"),
    ("export-fmu-under-user-file", ["export-fmu", "--out", "victim.txt/x.fmu"], "--out"),
    ("export-fmu-user-folder", ["export-fmu", "--out", "userdir.fmu"], "--out"),
    ("export-fmu-unknown-preset", ["export-fmu", "--out", "x.fmu", "--preset", "nope"], "--preset"),
    (
        "export-fmu-mechanism-no-linkage",
        ["export-fmu", "--out", "x.fmu", "--mechanism", "--preset", "sea805"],
        "--mechanism",
    ),
    ("reproduce-unknown-only", ["reproduce", "--only", "nosuch"], "--only"),
    ("reproduce-user-folder", ["reproduce", "--out", "userdir", "--only", "speed-step"], "--out"),
    ("reproduce-user-folder-force", ["reproduce", "--out", "userdir", "--force"], "--out"),
    ("reproduce-user-file", ["reproduce", "--out", "victim.txt", "--only", "speed-step"], "--out"),
]


def seed_user_data(folder: Path) -> None:
    """The user's files, folders and links that the command-line cases aim at."""
    user_file(folder / "victim.txt", VICTIM, 0o600)
    user_file(folder / "victim.toml", b'name = "mine"\n', 0o644)
    user_file(folder / "victim.fmu", b"PK\x03\x04 not emasim's\n", 0o644)
    user_file(folder / "x.fmu", b"an FMU nobody trusts\n", 0o755)
    user_file(folder / "userdir" / "notes.txt", VICTIM)
    user_file(folder / "userdir.toml" / "notes.txt", VICTIM)
    user_file(folder / "userdir.fmu" / "notes.txt", VICTIM)
    (folder / "link").symlink_to("userdir")
    (folder / "dangling").symlink_to("nowhere")


@pytest.mark.parametrize("args,needle", [c[1:] for c in CLI], ids=[c[0] for c in CLI])
def test_a_bad_command_line_is_refused(work, args, needle):
    seed_user_data(work)
    assert_refused_untouched(work, args, needle)
    assert (work / "victim.txt").read_bytes() == VICTIM
    assert stat.S_IMODE((work / "victim.txt").stat().st_mode) == 0o600
    assert not os.path.lexists("/proc/emasim-cannot-write")


# --- accepted runs: results are never replaced by accident, and they are complete -------------

OK_RUN = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.05", "--no-plot"]


def assert_ok(result) -> None:
    shown = f"exit {result.exit_code}\nstdout: {result.stdout}\nstderr: {result.stderr}"
    assert result.exit_code == 0, shown
    assert "Traceback" not in result.stdout + result.stderr, shown


def assert_complete(folder: Path) -> None:
    assert folder.is_dir() and not folder.is_symlink()
    assert RUN_FILES <= {p.name for p in folder.iterdir()}, sorted(folder.iterdir())
    assert foreign_files(folder) == []  # every file written is in the manifest
    for name in ("metrics.json", "meta.json"):
        strict_json(folder / name)


def test_a_result_is_kept_without_force_and_replaced_with_it(work):
    before = snapshot(work)
    assert_ok(invoke(*OK_RUN, "--out", "res"))
    first = snapshot(work)
    assert_only_added(before, first, "res")
    assert_complete(work / "res")
    assert_refused_untouched(work, [*OK_RUN, "--out", "res"], "--force")
    assert snapshot(work) == first
    assert_ok(invoke(*OK_RUN, "--out", "res", "--force", "--set", "seed=1"))
    assert_complete(work / "res")
    assert strict_json(work / "res" / "meta.json")["seed"] == 1
    assert_only_added(before, snapshot(work), "res")
    assert not leftovers(work)


def test_runs_without_out_get_fresh_folders(work):
    before = snapshot(work)
    assert_ok(invoke(*OK_RUN))
    assert_ok(invoke(*OK_RUN))
    folders = sorted((work / "runs" / "speed-step").iterdir())
    assert len(folders) == 2 and folders[0] != folders[1]
    for folder in folders:
        assert_complete(folder)
    assert_only_added(before, snapshot(work), "runs")
    assert not leftovers(work)


def test_an_empty_folder_is_a_valid_out(work):
    (work / "empty").mkdir()
    before = snapshot(work)
    assert_ok(invoke(*OK_RUN, "--out", "empty"))
    assert_complete(work / "empty")
    assert_only_added({k: v for k, v in before.items() if k != "empty"}, snapshot(work), "empty")
    assert not leftovers(work)


def test_a_comparison_writes_valid_json_everywhere(work):
    assert_ok(invoke("run", "speed-step", "--set", "duration_s=0.05", "--no-plot", "--out", "cmp"))
    files = sorted((work / "cmp").rglob("*.json"))
    assert len(files) >= 10  # metrics and meta of the comparison and of each of its four runs
    for path in files:
        strict_json(path)
    assert (work / "cmp" / MARKER).is_file() and not leftovers(work)


def dead_pid() -> int:
    """A process id that no process has now."""
    for pid in range(999_999, 900_000, -1):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return pid
        except PermissionError:
            continue
    raise AssertionError("no free pid found")


def test_only_dead_emasim_temporaries_are_cleaned_up(work):
    pid = dead_pid()
    parent = work / "runs" / "speed-step"
    ours = parent / f".x.tmp-{pid}-abcdef12"
    user_file(ours / MARKER, b'{"kind": "run"}\n', 0o644)
    theirs = parent / f".y.tmp-{pid}-abcdef12"
    user_file(theirs / "notes.txt", VICTIM)
    kept = {k: v for k, v in snapshot(work).items() if ".y.tmp-" in k}
    assert_ok(invoke(*OK_RUN))
    assert not ours.exists()
    assert {k: v for k, v in snapshot(work).items() if ".y.tmp-" in k} == kept
    assert (work / USER_FILE).read_bytes() == USER_TEXT


# --- faults, in real processes: kills and concurrent runs never lose data ----------------------


def emasim(*args: str) -> list[str]:
    return [sys.executable, "-m", "emasim", *args]


def start(cwd: Path, *args: str) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "EMASIM_TRACEBACK"}
    return subprocess.Popen(
        emasim(*args),
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def kill(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=HANG_GUARD_S)


def wait_for(condition, proc: subprocess.Popen) -> None:
    """Poll until ``condition`` holds or ``proc`` has ended; the caller's checks then say
    which. No time is measured: the run ends by itself, which bounds the wait."""
    while not condition() and proc.poll() is None:
        time.sleep(0.005)


KILL_RUN = ["run", "speed-step", "-c", "speed=pi", "--set", "duration_s=1", "--out", "out/X"]


def _written(work: Path, name: str) -> bool:
    """A file ``name`` inside a temporary result folder: the write is under way."""
    return any((tmp / name).exists() for tmp in leftovers(work))


# where in the run the kill lands: each moment is a condition on the files, never a time
KILL_AT = {
    "start": lambda work: True,
    "temporary": lambda work: bool(leftovers(work)),
    "traces-written": lambda work: _written(work, "result.parquet"),
    "records-written": lambda work: _written(work, "meta.json"),
    "published": lambda work: (work / "out" / "X").exists(),
}


@pytest.mark.parametrize("moment", list(KILL_AT))
def test_process_killed_leaves_result_complete_or_absent(work, moment):
    proc = start(work, *KILL_RUN)
    wait_for(lambda: KILL_AT[moment](work), proc)
    kill(proc)
    target = work / "out" / "X"
    if os.path.lexists(target):
        assert_complete(target)
        assert (target / "plot.png").is_file()
    assert_ok(invoke(*OK_RUN, "--out", "out/again"))
    assert not [p for p in leftovers(work / "out") if f"-{proc.pid}-" in p.name]
    assert (work / USER_FILE).read_bytes() == USER_TEXT


IN_PROCESS = {c[0]: c[1] for c in CLI}
REAL_STDERR = [
    "set-bare-word",
    "out-user-file",
    "mechanism-fmu-untrusted",
    "export-fmu-user-file",
]


def test_process_refusals_print_one_line_on_the_real_stderr(work):
    """What the in-process runner cannot see (warnings, log handlers bound to the real stderr)
    shows here: each refusal, run as a program, still prints exactly one line."""
    folders = {name: work / name for name in REAL_STDERR}
    for folder in folders.values():
        seed_user_data(folder)
    before = snapshot(work)
    procs = {name: start(folder, *IN_PROCESS[name]) for name, folder in folders.items()}
    for name, proc in procs.items():
        stdout, stderr = proc.communicate(timeout=HANG_GUARD_S)
        lines = error_lines(stderr)
        shown = f"{name}: exit {proc.returncode}\nstderr: {stderr}"
        assert proc.returncode == 2 and len(lines) == 1, shown
        assert lines[0].startswith("error:") and "Traceback" not in stdout + stderr, shown
    assert snapshot(work) == before


def test_process_concurrent_runs_to_one_folder_lose_nothing(work):
    procs = [start(work, *KILL_RUN, "--no-plot") for _ in range(2)]
    outcomes = [(*p.communicate(timeout=HANG_GUARD_S), p.returncode) for p in procs]
    for stdout, stderr, code in outcomes:
        assert "Traceback" not in stdout + stderr, stderr
        if code != 0:
            lines = error_lines(stderr)
            assert code == 2 and len(lines) == 1 and lines[0].startswith("error:"), stderr
    assert 0 in [code for _, _, code in outcomes]
    assert_complete(work / "out" / "X")
    assert not leftovers(work)


def finished_trials(work: Path) -> list[Path]:
    """The meta.json of every trial the tuning's job store under ``work`` has finished."""
    found = work.glob("runs/tune/jobs-*/runs/*/meta.json")
    return sorted(path for path in found if not path.parent.name.startswith("."))  # published


def test_process_killed_tuning_resumes(work):
    """A tuning killed once a trial has finished: the same command finishes it, keeps every
    trial finished before (not run again) and runs only the rest."""
    args = ["tune", "speed-step", "-c", "speed=pi", "--set", "duration_s=0.5", "--trials", "12"]
    args += ["--save", "t.toml"]
    proc = start(work, *args)
    wait_for(lambda: finished_trials(work), proc)
    assert proc.poll() is None, "the tuning ended before it could be killed"
    kill(proc)
    before = {path: path.read_bytes() for path in finished_trials(work)}
    assert before and not (work / "t.toml").exists()
    rerun = subprocess.run(
        emasim(*args), cwd=work, capture_output=True, text=True, timeout=HANG_GUARD_S
    )
    assert rerun.returncode == 0, rerun.stderr
    assert "Traceback" not in rerun.stdout + rerun.stderr
    assert (work / "t.toml").read_text().startswith("# emasim tune")
    assert {path: path.read_bytes() for path in before} == before  # kept, not run again
    (store,) = work.glob("runs/tune/jobs-*")
    table = read_table(store)
    assert len(table) == len(finished_trials(work)) > len(before)
    assert set(table["status"]) == {"ok"} and set(table["set"]) == {"speed=pi"}
    assert not leftovers(work)


def test_a_utf8_file_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + speed_file().encode())
    raw, _ = read_scenario_file(str(path))
    assert validate_scenario(raw).name
