"""One run, compiled to the arrays the engine reads (built by a scenario or by hand)."""

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..control.slot import Compiled, PlantFacts, absent_slot
from ..interface import MEASUREMENT_NAMES, N_MEAS, N_OUT, N_REF
from ..plant import actuator as A
from ..plant.parameters import RPM
from ..plant.sensors import (
    S_ALPHA,
    S_ERROR,
    S_EVERY,
    S_HALF_GAP,
    S_NOISE,
    S_OFFSET,
    S_RESOLUTION,
    S_SOURCE,
    S_WAVENUMBER,
    ideal_table,
    initial_state,
)
from ..signals import ZERO
from .core import (
    FEEDBACK_ROD,
    LOOP_POSITION,
    LOOP_POSITION_CURRENT,
    LOOP_SPEED,
    N_DRIVE,
    Data,
    LawAddress,
    Model,
    Timing,
    new_workspace,
)
from .trace import TRACE_COLUMNS


@dataclass
class Setup:
    """Plant, controllers, signals and timing of one run, as flat arrays (SI units).

    ``position`` is None for a speed-loop run (the reference is then a motor speed in rad/s);
    otherwise the reference is a rod position in m. Controller states are copied at the start
    of every run, so one Setup can be run many times.
    """

    plant: np.ndarray
    sample_period_s: float
    substeps: int
    duration_s: float
    reference: np.ndarray
    motor_load: np.ndarray
    rod_load: np.ndarray
    speed: Compiled
    current: Compiled
    position: Compiled | None = None
    rudder_load: np.ndarray = field(default_factory=lambda: ZERO.copy())
    sensors: np.ndarray = field(default_factory=ideal_table)  # emasim.plant.sensors table
    record_every: int = 10
    seed: int = 0
    x0: np.ndarray = field(default_factory=lambda: np.zeros(A.N_STATE))
    limits: np.ndarray = field(default_factory=lambda: np.full(A.N_STATE, 1e12))
    facts: PlantFacts | None = None  # the drive's ratings, for diagnosing a divergence
    record_signals: tuple[str, ...] | None = None  # trace columns to keep (None: every one)
    delay_substeps: int = 0  # computation delay, in sub-steps (0 .. substeps)
    feedback: int = FEEDBACK_ROD  # the position loop's sensor (core.FEEDBACK_*)
    rudder_to_rod: np.ndarray = field(default_factory=lambda: ZERO.copy())  # core.Model

    def __post_init__(self):
        for name in ("sample_period_s", "duration_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")
        if self.substeps < 1 or self.record_every < 1:
            raise ValueError("substeps and record_every must be whole numbers >= 1")
        if not 0 <= self.delay_substeps <= self.substeps:
            raise ValueError(
                f"delay_substeps must be 0 .. substeps ({self.substeps}), got {self.delay_substeps}"
            )

    @property
    def n_ticks(self) -> int:
        """Number of control ticks, round(duration / Ts)."""
        return int(round(self.duration_s / self.sample_period_s))

    @property
    def loop_structure(self) -> int:
        """Which loops close: core.LOOP_SPEED, LOOP_POSITION or LOOP_POSITION_CURRENT."""
        if self.position is None:
            return LOOP_SPEED
        return LOOP_POSITION if self.position.commands == "speed" else LOOP_POSITION_CURRENT

    @property
    def step_s(self) -> float:
        """Integration sub-step h = Ts / substeps."""
        return self.sample_period_s / self.substeps

    def loop_laws(self) -> dict[str, str]:
        """Slot -> the name of its law, for every closed loop, outermost first."""
        slots = {"position": self.position, "speed": self.speed, "current": self.current}
        if self.position is not None and self.position.commands == "current":
            del slots["speed"]
        return {
            slot: getattr(c.function, "__name__", type(c.function).__name__)
            for slot, c in slots.items()
            if c is not None
        }

    def sensor_description(self) -> dict[str, dict[str, float | str]]:
        """Channel -> what is not ideal about it (RunDescription.sensors), for every non-ideal
        channel."""
        out = {}
        for name, row in zip(MEASUREMENT_NAMES, self.sensors, strict=True):
            found = {
                key: float(row[column]) * factor
                for key, column, factor in (
                    ("resolution", S_RESOLUTION, 1.0),
                    ("noise_std", S_NOISE, 1.0),
                    ("offset", S_OFFSET, 1.0),
                    ("gap_width", S_HALF_GAP, 2.0),
                    ("accuracy_error", S_ERROR, 1.0),
                )
                if row[column] != 0.0
            }
            if row[S_ERROR] != 0.0:
                found["accuracy_period"] = 2.0 * math.pi / float(row[S_WAVENUMBER])
            if row[S_EVERY] != 1.0:
                found["sample_period_s"] = float(row[S_EVERY]) * self.sample_period_s
            if row[S_SOURCE] >= 0.0:
                found["derived_from"] = MEASUREMENT_NAMES[int(row[S_SOURCE])]
                found["filter_alpha"] = float(row[S_ALPHA])
            if found:
                out[name] = found
        return out

    def with_(self, **changes) -> "Setup":
        """A copy with some fields replaced."""
        return replace(self, **changes)

    def kept_columns(self, keep_elements: tuple[str, ...] = ()) -> tuple[str, ...]:
        """The trace columns a run stores, in TRACE order: t_s and the columns named in
        ``record_signals`` (every one when None), less those of elements absent from the
        plant (their states idle, their outputs NaN) but for the elements in keep_elements."""
        absent = A.PLANT.absent_columns(self.plant, keep=keep_elements)
        chosen = None if self.record_signals is None else {TRACE_COLUMNS[0], *self.record_signals}
        return tuple(
            name
            for name in TRACE_COLUMNS
            if name not in absent and (chosen is None or name in chosen)
        )

    @property
    def recorded_rows(self) -> int:
        """The trace's rows: one at every record_every-th tick, the first at tick 0."""
        return (self.n_ticks + self.record_every - 1) // self.record_every

    def start(self, keep_elements: tuple[str, ...] = (), rows: int | None = None) -> "RunState":
        """The compiled core's records (emasim.sim.core), with fresh copies of everything a run
        changes (plant state, slot states, play operators), and an empty trace of the columns
        :meth:`kept_columns` names, of ``rows`` rows (default: every recorded row; fewer, and
        the loop records row r at r modulo rows, for a caller that empties it as it fills).
        Without a position loop the position slot holds
        :func:`~emasim.control.slot.absent_slot` (the loop never calls it)."""
        position = self.position if self.position is not None else absent_slot()
        slots = (position, self.speed, self.current)
        kept = self.kept_columns(keep_elements)
        rows = self.recorded_rows if rows is None else rows
        model = Model(
            params=_floats(self.plant),
            limits=_floats(self.limits),
            reference=_floats(self.reference),
            motor_load=_floats(self.motor_load),
            rod_load=_floats(self.rod_load),
            rudder_load=_floats(self.rudder_load),
            sensor_table=_floats(self.sensors),
            rudder_to_rod=_floats(self.rudder_to_rod),
            slot_params=tuple(_floats(c.params) for c in slots),
            trace_columns=np.array([TRACE_COLUMNS.index(name) for name in kept], dtype=np.int64),
            timing=Timing(
                self.sample_period_s,
                self.substeps,
                self.record_every,
                self.seed,
                self.loop_structure,
                self.delay_substeps,
                self.feedback,
            ),
        )
        data = Data(
            x=_floats(self.x0).copy(),
            sensor_state=initial_state(self.x0, self.plant),
            drive=np.zeros(N_DRIVE),
            slot_states=tuple(_floats(c.state).copy() for c in slots),
            work=new_workspace(),
            meas=np.zeros(N_MEAS),
            ref=np.zeros(N_REF),
            out=np.zeros(N_OUT),
            trace=np.full((len(kept), rows), np.nan),
            trace_row=np.full(len(TRACE_COLUMNS), np.nan),
            status=np.zeros(3, dtype=np.int64),
        )
        return RunState(model, data, self.law_addresses())

    def law_addresses(self) -> tuple:
        """The slots' laws as machine-code addresses (position, speed, current), each compiled
        (or loaded from numba's cache) the first time this process asks for it."""
        position = self.position if self.position is not None else absent_slot()
        return tuple(LawAddress.of(c.function) for c in (position, self.speed, self.current))


@dataclass
class RunState:
    """One run of a Setup: its records (emasim.sim.core) and the three slots' laws."""

    model: Model
    data: Data
    laws: tuple


def _floats(array) -> np.ndarray:
    """A C-contiguous float64 array (the compiled core's type), copied only if needed."""
    return np.ascontiguousarray(array, dtype=np.float64)


def plant_facts(plant) -> PlantFacts:
    """What a controller design may know of a :class:`~emasim.plant.parameters.PlantParams`."""
    m = plant.motor
    return PlantFacts(
        inertia_kgm2=plant.total_inertia_kgm2,
        torque_constant_Nm_per_A=plant.torque_constant_Nm_per_A,
        ratio_m_per_rad=plant.ratio_m_per_rad,
        max_current_A=m.max_current_A,
        max_speed_rad_s=m.max_speed_rpm * RPM,
        resistance_ohm=m.resistance_ohm,
        inductance_d_H=m.inductance_d_H,
        inductance_q_H=m.inductance_q_H,
        flux_linkage_Wb=m.flux_linkage_Wb,
        pole_pairs=m.pole_pairs,
        dc_bus_V=m.dc_bus_V,
    )
