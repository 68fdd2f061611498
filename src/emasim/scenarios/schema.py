"""Scenario files: what one run is, validated field by field.

A scenario is a TOML file (see the files beside this module). Plant and sensor sections start
from a named preset (:mod:`emasim.plant.presets`) and override single fields; references and
loads are lists of signal terms (:mod:`emasim.signals`) in the unit named by their key. Every
value is checked: unknown keys, NaN/inf and out-of-range values are rejected with the field's
dotted path and the allowed range. :meth:`Scenario.setup` compiles a scenario into the arrays
of a :class:`emasim.sim.setup.Setup`.
"""

import difflib
import math
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..control.current import CurrentPI
from ..control.pid import SpeedPI
from ..control.registry import CASCADES, PositionController, SpeedController
from ..interface import MEASUREMENT_NAMES as MEASUREMENT_CHANNELS
from ..naming import slug
from ..plant import actuator as A
from ..plant.elements.linkage import rudder_angle_of_extension
from ..plant.parameters import MM, RPM, PlantParams, SensorParams, Strict
from ..plant.presets import PRESETS, SENSOR_PRESETS
from ..signals import Term, encode, lookup_table, signal_samples, signal_values
from ..sim.trace import TRACE_COLUMNS

if TYPE_CHECKING:
    from ..sim.result import Experiment
    from ..sim.setup import Setup

# the sections every plant has: a plant table holding all of them is whole (_from_preset)
PLANT_SECTIONS = tuple(
    name for name, info in PlantParams.model_fields.items() if info.is_required()
)
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"
MAX_SUBSTEPS = 10_000  # integration sub-steps per controller sample
# rows of the trace: it streams to disk as it is recorded (emasim.sim.spool), but the bench
# metrics still read a column whole, 0.8 GB a column at 1e8 rows: 10 000 s at 10 kHz
MAX_RECORDED_ROWS = 100_000_000
MIN_RECORDED_ROWS = 4  # the metrics' steady window, the run's second half, holds 2 rows


Pair = Annotated[list[float], Field(min_length=2, max_length=2)]  # a TOML array of two numbers


class Neighbourhood(Strict):
    """The tuned optimum's neighbourhood check, as ``emasim tune`` records it
    (emasim.tuning.check_neighbourhood)."""

    points: int = Field(ge=0, description="points run about the optimum")
    best_cost_ratio: float = Field(
        ge=0, description="the best point's cost over the optimum's (below 0.99: not converged)"
    )
    best_point: dict[str, float] = Field(default={}, description="'loop.field' -> its value")


class TuningSet(Strict):
    """One controller set's search, as ``emasim tune`` records it (emasim.tuning.Tuned)."""

    trials: int = Field(ge=0, description="trials completed")
    knobs: int = Field(ge=0, description="knobs searched")
    stopped: Literal["converged", "budget"]
    widened: dict[str, Pair] = Field(
        default={}, description="knob -> the search range it ended with, where widened"
    )
    on_bound: dict[str, Literal["lower", "upper"]] = Field(
        default={}, description="knob -> the bound its optimum still sits on"
    )
    tuned_point: Pair | None = Field(
        default=None, description="(chattering, tracking) of the tuned gains' trial"
    )
    front: list[Pair] = Field(
        default=[], description="(chattering, tracking) of the non-dominated trials"
    )
    neighbourhood: Neighbourhood | None = Field(
        default=None, description="the check of the optimum's neighbourhood (emasim.tuning)"
    )


class Solver(Strict):
    """Sample period of the controllers, integration sub-step, and recording period."""

    sample_period_s: float = Field(default=1e-4, ge=1e-6, le=0.01)
    step_s: float = Field(default=1e-5, ge=1e-8, le=0.01)
    record_period_s: float = Field(default=1e-3, ge=1e-6, le=1.0)
    record_signals: list[str] | None = Field(
        default=None,
        max_length=len(TRACE_COLUMNS),
        description="trace columns to record (t_s always, and the columns the metrics and plots "
        "read); default every column of the plant's elements",
    )
    communication_step_s: float | None = Field(
        default=None,
        ge=1e-6,
        le=0.1,
        description="co-simulate drive and linkage, exchanging at this step (needs a linkage)",
    )
    mechanism_fmu: str | None = Field(
        default=None,
        min_length=1,
        max_length=4096,
        description="path of an FMI 2.0 co-simulation FMU that replaces the built-in mechanism "
        "in the co-simulation (inputs rod_velocity_m_s [, rod_position_m], outputs "
        "rudder_angle_rad, rod_force_N; see emasim.sim.fmi); needs communication_step_s",
    )

    @field_validator("record_signals")
    @classmethod
    def _known_signals(cls, names):
        for name in names or []:
            if name not in TRACE_COLUMNS:
                close = difflib.get_close_matches(name, TRACE_COLUMNS, n=1)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                raise ValueError(
                    f"unknown signal {name!r}{hint}; allowed: {', '.join(TRACE_COLUMNS)}"
                )
        return names

    @model_validator(mode="after")
    def _fmu_needs_cosimulation(self):
        if self.mechanism_fmu is not None and self.communication_step_s is None:
            raise ValueError(
                "mechanism_fmu is used only in a co-simulation: set communication_step_s too"
            )
        return self

    @model_validator(mode="after")
    def _whole_multiples(self):
        for name, value, of in (
            ("step_s", self.step_s, self.sample_period_s),
            ("sample_period_s", self.sample_period_s, self.record_period_s),
        ):
            ratio = of / value
            if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6 * ratio:
                owner = "sample_period_s" if name == "step_s" else "record_period_s"
                raise ValueError(
                    f"{owner} ({of:g} s) must be a whole multiple (>= 1) of {name} ({value:g} s)"
                )
        return self

    @model_validator(mode="after")
    def _substeps_bounded(self):
        if self.substeps > MAX_SUBSTEPS:
            raise ValueError(
                f"sample_period_s / step_s = {self.substeps} sub-steps per sample; at most "
                f"{MAX_SUBSTEPS} (raise step_s)"
            )
        return self

    @property
    def substeps(self) -> int:
        return round(self.sample_period_s / self.step_s)

    @property
    def record_every(self) -> int:
        return round(self.record_period_s / self.sample_period_s)


class Reference(Strict):
    """The set-point: exactly one of a motor speed, a rod position or a rudder angle."""

    speed_rpm: list[Term] | None = None
    position_mm: list[Term] | None = None
    rudder_deg: list[Term] | None = None

    @model_validator(mode="after")
    def _exactly_one(self):
        given = [k for k in ("speed_rpm", "position_mm", "rudder_deg") if getattr(self, k)]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of speed_rpm, position_mm, rudder_deg "
                f"(got {', '.join(given) or 'none'})"
            )
        return self

    @property
    def loop(self) -> str:
        """The outermost loop this reference closes: 'speed' or 'position'."""
        return "speed" if self.speed_rpm else "position"

    def encode(self, plant: PlantParams, duration_s: float) -> np.ndarray:
        """SI signal: motor speed (rad/s) or rod position (m).

        A rudder angle goes through the lumped arm, or, with the linkage, through its rigid
        inverse kinematics: sampled every millisecond over the run and interpolated (a table,
        built here, so of any length: a Table term's MAX_TABLE_POINTS bounds what a scenario
        file may give, not the runs emasim may make).
        """
        if self.speed_rpm:
            return encode(self.speed_rpm, RPM)
        if self.position_mm:
            return encode(self.position_mm, MM)
        if plant.linkage is None:
            return encode(self.rudder_deg, math.radians(1.0) * plant.load.rudder_arm_mm * MM)
        angle_grid, s_grid = rudder_rod_grid(plant)
        angle = encode(self.rudder_deg, math.radians(1.0))
        times = np.arange(0.0, duration_s + 1e-3, 1e-3)
        return lookup_table(times, np.interp(signal_samples(angle, times), angle_grid, s_grid))


class Load(Strict):
    """External loads, summed: on the motor shaft, on the rod, and on the rudder shaft."""

    motor_torque_Nm: list[Term] = []
    rod_force_N: list[Term] = []
    rudder_torque_Nm: list[Term] = []

    def encode(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(motor torque in N*m, rod force in N, rudder-shaft torque in N*m) signals.

        A rudder torque is a load: positive opposes positive deflection. With the linkage it
        acts on the rudder shaft, with the lumped stage it reaches the rod as torque / arm,
        and with the load motor it is the load motor's command (emasim.plant.actuator).
        """
        return (
            encode(self.motor_torque_Nm),
            encode(self.rod_force_N),
            encode(self.rudder_torque_Nm),
        )


class Loop(Strict):
    """How the loops are implemented: the controllers' computation delay, and the sensor the
    position loop closes on: the rod's displacement sensor ('rod'), the rudder encoder read as
    the rod position the rigid kinematics give for its angle ('rudder'), or the motor encoder
    read as the nut's travel K theta_m ('motor': the semi-closed loop of an EMA without an
    output sensor in the loop, which leaves the backlash and the compliance outside it)."""

    computation_delay_s: float = Field(
        default=0.0,
        ge=0,
        le=0.01,
        description="from sampling to applying the voltage: a whole number of solver.step_s, "
        "at most solver.sample_period_s",
    )
    position_feedback: Literal["rod", "rudder", "motor"] = "rod"


def rudder_rod_grid(plant: PlantParams) -> tuple[np.ndarray, np.ndarray]:
    """(rudder angles in rad, rising; the rod positions in m that give them) at 501 points
    over the stroke: the lumped arm, or the linkage's rigid inverse kinematics."""
    half_stroke = 0.5 * plant.drivetrain.stroke_mm * MM
    s_grid = np.linspace(-half_stroke, half_stroke, 501)
    if plant.linkage is None:
        return s_grid / (plant.load.rudder_arm_mm * MM), s_grid
    angle_grid = rudder_angle_of_extension(s_grid, plant.linkage.pack())
    if angle_grid[-1] < angle_grid[0]:  # monotonic (checked by PlantParams): make it rise
        s_grid, angle_grid = s_grid[::-1], angle_grid[::-1]
    return angle_grid, s_grid


class Controllers(Strict):
    """One controller per loop; the position loop only when the reference is a position.

    In a file, ``controllers = "hybrid"`` (or a table with ``cascade = "hybrid"`` plus
    overrides) starts from a named cascade of :data:`emasim.control.registry.CASCADES`.
    """

    speed: SpeedController = SpeedPI()
    position: PositionController | None = None
    current: CurrentPI = CurrentPI()


def _merge(base: dict, override: dict) -> dict:
    """Recursive dict update: override's leaves replace base's."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _from_preset(section, presets: dict, what: str, complete: tuple[str, ...] = ()) -> dict:
    """A section given as a preset name, or a table with an optional ``preset`` key + overrides.

    A table without ``preset`` that names every one of ``complete`` is whole, as a saved
    scenario writes it, and stands alone: merging it onto the first preset would add that
    preset's optional elements (the end stops) to a plant that had none."""
    if isinstance(section, str):
        section = {"preset": section}
    if not isinstance(section, dict):
        return section  # let pydantic report the wrong type
    if complete and "preset" not in section and all(key in section for key in complete):
        return section
    section = dict(section)
    name = section.pop("preset", next(iter(presets)))
    if not isinstance(name, str) or name not in presets:
        choices = ", ".join(presets)
        raise ValueError(f"{what}.preset: unknown preset {name!r}; choose one of: {choices}")
    return _merge(presets[name]().model_dump(), section)


def _from_cascade(section, scenario: dict):
    """Expand a named cascade; a speed-loop scenario keeps only the cascade's speed controller."""
    if isinstance(section, str):
        section = {"cascade": section}
    if not isinstance(section, dict) or "cascade" not in section:
        return section
    section = dict(section)
    name = section.pop("cascade")
    if not isinstance(name, str) or name not in CASCADES:
        choices = ", ".join(CASCADES)
        raise ValueError(f"controllers.cascade: unknown cascade {name!r}; choose one of: {choices}")
    cascade = dict(CASCADES[name])
    reference = scenario.get("reference")
    if isinstance(reference, dict) and "speed_rpm" in reference:
        cascade.pop("position")
    return _merge(cascade, section)


class Variant(Strict):
    """One entry of a comparison: a label and the controllers it runs."""

    label: str = Field(min_length=1, max_length=40)
    controllers: Controllers


def _check_loops(controllers: Controllers, loop: str, where: str) -> None:
    """Refuse a position controller on a speed reference, and a position reference without one."""
    if loop == "position" and controllers.position is None:
        raise ValueError(
            f"the reference is a position, so {where}.position is needed "
            "(e.g. --controller position=pid)"
        )
    if loop == "speed" and controllers.position is not None:
        raise ValueError(
            "the reference is a speed (reference.speed_rpm), so the position loop is open: "
            f"remove {where}.position"
        )


class Identify(Strict):
    """How ``emasim identify`` fits the scenario by default: the keys ``fit`` (``KEY=LOW:HIGH``,
    or ``KEY[,KEY...]=*LOW:HIGH`` for a factor on their own values) and ``map``, a trace's
    column -> a reading (emasim.identification.bench_features.READINGS)."""

    fit: list[str] = Field(min_length=1, description="the keys fitted when --fit names none")
    map: dict[str, str] = Field(default={}, description="a trace's column -> a reading")


class Scenario(Strict):
    """One experiment: plant, sensors, controllers, reference, loads, timing.

    ``compare`` lists controller sets to run one after the other on the same experiment (the
    paper's comparisons); ``controllers`` is what a single run uses.
    """

    name: str = Field(
        min_length=1,
        max_length=80,
        pattern=NAME_PATTERN,
        description="letters, digits, '_', '-' and '.', starting with a letter or digit; "
        "names the run folder, so it can never leave the output root",
    )
    description: str = Field(default="", max_length=10_000)
    # at most a day: a run's trace streams to disk (emasim.sim.spool), so memory sets no limit;
    # its recorded rows are held to MAX_RECORDED_ROWS (a day at 1 kHz; 10 000 s at 10 kHz)
    duration_s: float = Field(gt=0, le=86_400)
    seed: int = Field(default=0, ge=0, le=2**32 - 1)
    solver: Solver = Solver()
    plant: PlantParams
    sensors: SensorParams = SensorParams()
    controllers: Controllers = Controllers()
    loop: Loop = Loop()
    reference: Reference
    load: Load = Load()
    compare: list[Variant] = []
    identify: Identify | None = None
    tuning: dict[str, str | int | float | dict[str, TuningSet]] = Field(
        default={},
        description="how the gains were obtained (written by emasim tune); 'sets' holds each "
        "controller set's search",
    )

    @model_validator(mode="before")
    @classmethod
    def _resolve_presets(cls, data):
        if isinstance(data, dict):
            data = dict(data)
            data["plant"] = _from_preset(
                data.get("plant", {}), PRESETS, "plant", complete=PLANT_SECTIONS
            )
            data["sensors"] = _from_preset(data.get("sensors", {}), SENSOR_PRESETS, "sensors")
            data["controllers"] = _from_cascade(data.get("controllers", {}), data)
            if isinstance(data.get("compare"), list):
                data["compare"] = [
                    {**v, "controllers": _from_cascade(v.get("controllers", {}), data)}
                    if isinstance(v, dict)
                    else v
                    for v in data["compare"]
                ]
        return data

    @model_validator(mode="after")
    def _loops_match(self):
        loop = self.reference.loop
        _check_loops(self.controllers, loop, "controllers")
        for i, variant in enumerate(self.compare):
            _check_loops(variant.controllers, loop, f"compare.{i}.controllers")
        labels = [v.label for v in self.compare]
        if len(set(labels)) != len(labels):
            raise ValueError(f"compare labels must differ, got {labels}")
        folders = [slug(label) for label in labels]
        for i, folder in enumerate(folders):
            if folder in folders[:i]:
                other = labels[folders.index(folder)]
                raise ValueError(
                    f"compare.{i}.label: {labels[i]!r} and {other!r} both name the folder "
                    f"{folder!r}; make them differ in letters or digits"
                )
        if self.duration_s < self.solver.sample_period_s:
            raise ValueError("duration_s must be at least one solver.sample_period_s")
        rows = self.duration_s / self.solver.record_period_s
        if rows < MIN_RECORDED_ROWS - 1e-9:
            raise ValueError(
                f"duration_s ({self.duration_s:g} s) must hold at least {MIN_RECORDED_ROWS} "
                f"recorded rows of solver.record_period_s ({self.solver.record_period_s:g} s): "
                f"at least {MIN_RECORDED_ROWS * self.solver.record_period_s:g} s, or a shorter "
                "record_period_s"
            )
        if rows > MAX_RECORDED_ROWS:
            raise ValueError(
                f"duration_s / solver.record_period_s = {rows:.3g} recorded rows; at most "
                f"{MAX_RECORDED_ROWS:.0e} (raise solver.record_period_s)"
            )
        check_reference(self.reference, self.plant, self.duration_s)
        self._check_loop()
        for name in MEASUREMENT_CHANNELS:
            self.sensors.every(name, self.solver.sample_period_s)
        return self

    def _check_loop(self) -> None:
        delay, step = self.loop.computation_delay_s, self.solver.step_s
        if delay > self.solver.sample_period_s * (1 + 1e-9):
            raise ValueError(
                f"loop.computation_delay_s ({delay:g} s) must not exceed solver.sample_period_s "
                f"({self.solver.sample_period_s:g} s)"
            )
        if abs(delay / step - round(delay / step)) > 1e-6 * max(1.0, delay / step):
            raise ValueError(
                f"loop.computation_delay_s ({delay:g} s) must be a whole number of "
                f"solver.step_s ({step:g} s)"
            )
        if self.loop.position_feedback != "rod" and self.reference.loop != "position":
            raise ValueError(
                f"loop.position_feedback = {self.loop.position_feedback!r} needs a position loop "
                "(a position_mm or rudder_deg reference)"
            )

    def variants(self) -> list[tuple[str, "Scenario"]]:
        """(label, single-run scenario) of every comparison entry; just this one if none."""
        if not self.compare:
            return [(self.controllers_label(), self)]
        return [
            (v.label, self.model_copy(update={"controllers": v.controllers, "compare": []}))
            for v in self.compare
        ]

    def revalidated(self, **changes) -> "Scenario":
        """This scenario with top-level fields replaced (``solver=...``, ``plant=...``),
        validated again as a whole: a change that breaks a rule across sections (a delay that
        is no whole number of the new step) is refused as in a scenario file."""
        data = self.model_dump(mode="json", exclude_none=True)
        data.update({k: v.model_dump(mode="json", exclude_none=True) for k, v in changes.items()})
        return Scenario.model_validate(data)

    def experiment(self) -> "Experiment":
        """What this scenario's run makes, typed, for its metrics and figures
        (emasim.sim.result.Experiment)."""
        from ..sim.result import Experiment

        quantity, key = {
            "speed_rpm": ("speed", "speed_rpm"),
            "position_mm": ("position", "position_mm"),
            "rudder_deg": ("rudder", "rudder_deg"),
        }[next(k for k in ("speed_rpm", "position_mm", "rudder_deg") if getattr(self.reference, k))]
        terms = getattr(self.reference, key)
        sines = [t for t in terms if t.type == "sine"]
        steps = [  # the first load step that changes the load, by section
            t
            for section in ("motor_torque_Nm", "rod_force_N", "rudder_torque_Nm")
            for t in getattr(self.load, section)
            if t.type == "step" and t.final != t.initial
        ]
        plant = self.plant
        return Experiment(
            quantity=quantity,
            shape="sine" if sines else "step",
            reference=tuple(t.model_dump(mode="json", exclude_none=True) for t in terms),
            sine_frequency_Hz=float(sines[0].frequency_Hz) if len(sines) == 1 else None,
            load_step_s=float(steps[0].time_s) if steps else None,
            max_speed_rpm=plant.motor.max_speed_rpm,
            max_current_A=plant.motor.max_current_A,
            stroke_mm=plant.drivetrain.stroke_mm if plant.end_stops is None else None,
            rudder_arm_m=plant.load.rudder_arm_mm * MM if plant.linkage is None else None,
        )

    def controllers_label(self) -> str:
        """A short label of the controllers, e.g. 'position=pid, speed=pi'."""
        c = self.controllers
        parts = ([f"position={c.position.name}"] if c.position is not None else []) + [
            f"speed={c.speed.name}"
        ]
        return ", ".join(parts)

    def setup(self) -> "Setup":
        """Compile this scenario into the arrays the engine runs (the first call loads the
        compiled core: checking a scenario does not)."""
        from ..sim.core import FEEDBACK_MOTOR, FEEDBACK_ROD, FEEDBACK_RUDDER
        from ..sim.setup import Setup, plant_facts

        facts = plant_facts(self.plant)
        ts = self.solver.sample_period_s
        motor_load, rod_load, rudder_load = self.load.encode()
        c = self.controllers
        return Setup(
            plant=self.plant.pack(),
            sample_period_s=ts,
            substeps=self.solver.substeps,
            duration_s=self.duration_s,
            reference=self.reference.encode(self.plant, self.duration_s),
            motor_load=motor_load,
            rod_load=rod_load,
            rudder_load=rudder_load,
            speed=c.speed.build(facts, ts),
            position=c.position.build(facts, ts) if c.position is not None else None,
            current=c.current.build(facts, ts),
            sensors=self.sensors.pack(ts),
            record_every=self.solver.record_every,
            seed=self.seed,
            x0=self.plant.initial_state(),
            limits=A.PLANT.limits(self.plant),
            facts=facts,
            record_signals=(
                None if self.solver.record_signals is None else tuple(self.solver.record_signals)
            ),
            delay_substeps=round(self.loop.computation_delay_s / self.solver.step_s),
            feedback={"rod": FEEDBACK_ROD, "rudder": FEEDBACK_RUDDER, "motor": FEEDBACK_MOTOR}[
                self.loop.position_feedback
            ],
            rudder_to_rod=lookup_table(*rudder_rod_grid(self.plant)),
        )


def signal_peak(terms: list, duration_s: float) -> float:
    """max |y(t)| of a signal over [0, duration_s], in the unit of its key: sampled at 10^4
    even points plus every step time and table point (a sine's peak is found to 5e-7 of it)."""
    encoded = encode(terms)
    times = [np.linspace(0.0, duration_s, 10_001)]
    for term in terms:
        times.append(np.atleast_1d(getattr(term, "time_s", [])))
    grid = np.concatenate(times)
    grid = grid[(grid >= 0.0) & (grid <= duration_s)]
    return float(np.max(np.abs(signal_values(encoded, grid))))


def check_reference(reference: Reference, plant: PlantParams, duration_s: float) -> None:
    """Refuse a set-point the drive cannot physically reach: a speed beyond its
    max_speed_rpm, a rod position beyond half the stroke, a rudder angle beyond the angle that
    half the stroke gives (through the lumped arm, or the linkage's rigid kinematics)."""
    half_stroke_mm = 0.5 * plant.drivetrain.stroke_mm
    if reference.speed_rpm:
        peak, limit = signal_peak(reference.speed_rpm, duration_s), plant.motor.max_speed_rpm
        if peak > limit:
            raise ValueError(
                f"reference.speed_rpm reaches {peak:.6g} rpm, beyond the drive's "
                f"plant.motor.max_speed_rpm = {limit:g}"
            )
    elif reference.position_mm:
        peak = signal_peak(reference.position_mm, duration_s)
        if peak > half_stroke_mm:
            raise ValueError(
                f"reference.position_mm reaches {peak:.6g} mm, beyond the stroke "
                f"(+-{half_stroke_mm:g} mm: plant.drivetrain.stroke_mm = "
                f"{plant.drivetrain.stroke_mm:g})"
            )
    else:
        peak = signal_peak(reference.rudder_deg, duration_s)
        limit = rudder_limit_deg(plant)
        if peak > limit:
            raise ValueError(
                f"reference.rudder_deg reaches {peak:.6g} deg, beyond the +-{limit:.4g} deg "
                f"that the stroke (plant.drivetrain.stroke_mm = {plant.drivetrain.stroke_mm:g}) "
                "gives"
            )


def rudder_limit_deg(plant: PlantParams) -> float:
    """The largest rudder angle reachable both ways within the stroke (deg)."""
    half_stroke_m = 0.5 * plant.drivetrain.stroke_mm * MM
    if plant.linkage is None:
        return math.degrees(half_stroke_m / (plant.load.rudder_arm_mm * MM))
    ends = rudder_angle_of_extension(
        np.array([-half_stroke_m, half_stroke_m]), plant.linkage.pack()
    )
    return math.degrees(float(np.min(np.abs(ends))))
