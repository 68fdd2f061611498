"""What a plant element declares, and the layouts assembled from those declarations.

An element (the motor, the friction, the transmission, the backlash coupling, the rod and
rudder stage, the linkage) declares, in its own module:

* its **states**: name (the trace and FMU name, unit in the name), unit, description, the
  absolute tolerance the reference solver uses for it, and its divergence bound, a function of
  the validated :class:`~emasim.plant.parameters.PlantParams`;
* its **parameters**: the names of the SI values it reads from the packed parameter vector;
* its **outputs**: the trace columns its output function computes from the state;
* optionally its **presence**: the name of one of its parameters that is 0 when the element
  is absent from a plant. An absent element's states stay idle and its outputs are NaN; its
  columns are left out of a run's trace (:meth:`PlantLayout.absent_columns`).

:func:`assemble` lays the elements of a plant end to end: the state vector, the parameter
vector and the element outputs of the trace are the concatenations of the declarations, in
the plant's element order. Index constants (``X_IQ``, ``P_KB``) are then looked up by name
(:meth:`Layout.index`), so no layout is ever kept by hand; compiled code reads them as
module-level constants.
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..config import MM, RPM

RATED_RUNAWAY = 20.0  # a rated quantity (current, speed) this many times over is a runaway
FAR_RUNAWAY = 1e3  # a position this many strokes (or a state this many natural scales) away


def damping_for_ratio(zeta: float, stiffness: float, mass: float) -> float:
    """c = 2 zeta sqrt(k m): the damping that gives a mass (or inertia) m on a spring k the
    damping ratio zeta (SI, N s/m or N m s/rad)."""
    return 2.0 * zeta * math.sqrt(stiffness * mass)


def rod_position_bound(plant) -> float:
    """A rod-side position (m) this far out is a runaway: FAR_RUNAWAY strokes."""
    return FAR_RUNAWAY * plant.drivetrain.stroke_mm * MM


def rod_velocity_bound(plant) -> float:
    """A rod-side velocity (m/s) this fast is a runaway: RATED_RUNAWAY times the rated speed
    seen at the rod."""
    return RATED_RUNAWAY * plant.motor.max_speed_rpm * RPM * plant.ratio_m_per_rad


@dataclass(frozen=True)
class Quantity:
    """A named value with its unit: a parameter or an output column."""

    name: str
    unit: str
    description: str = ""


@dataclass(frozen=True)
class State(Quantity):
    """A state: ``atol`` is its absolute tolerance in the reference solver (its unit);
    ``bound(plant)`` the magnitude beyond which it means a runaway simulation."""

    atol: float = 1e-12
    bound: Callable = field(default=lambda plant: FAR_RUNAWAY, compare=False)


@dataclass(frozen=True)
class Element:
    """One physical element of the plant (module docstring)."""

    name: str
    description: str
    states: tuple[State, ...] = ()
    params: tuple[Quantity, ...] = ()
    outputs: tuple[Quantity, ...] = ()
    presence: str | None = None  # a parameter that is 0 when the element is absent


class Layout:
    """Quantities end to end in a flat vector, looked up by name."""

    def __init__(self, quantities: Sequence[Quantity]):
        self.quantities = tuple(quantities)
        self.names = tuple(q.name for q in self.quantities)
        self._index = {name: i for i, name in enumerate(self.names)}
        if len(self._index) != len(self.names):
            twice = sorted({n for n in self.names if self.names.count(n) > 1})
            raise ValueError(f"names declared twice: {', '.join(twice)}")

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self._index[name]

    def units(self) -> dict[str, str]:
        return {q.name: q.unit for q in self.quantities}


@dataclass(frozen=True)
class PlantLayout:
    """The layouts of a plant: states, parameters, element outputs, and where each element
    starts in each (``state_offset[element.name]``, ``param_offset[element.name]``)."""

    elements: tuple[Element, ...]
    states: Layout
    params: Layout
    outputs: Layout
    state_offset: dict[str, int]
    param_offset: dict[str, int]

    def limits(self, plant) -> np.ndarray:
        """Every state's divergence bound for a validated PlantParams."""
        return np.array([s.bound(plant) for s in self.states.quantities], dtype=np.float64)

    def absent_columns(self, params: np.ndarray, keep: Sequence[str] = ()) -> frozenset[str]:
        """The state and output names of the elements absent from the plant of ``params``
        (packed), but for the elements named in ``keep``."""
        names = []
        for element in self.elements:
            if element.presence is None or element.name in keep:
                continue
            if params[self.params.index(element.presence)] == 0:
                names.extend(q.name for q in (*element.states, *element.outputs))
        return frozenset(names)

    def present_elements(self, params: np.ndarray, keep: Sequence[str] = ()) -> tuple[str, ...]:
        """The names of the elements present in the plant of ``params`` (and those in keep)."""
        return tuple(
            element.name
            for element in self.elements
            if element.presence is None
            or element.name in keep
            or params[self.params.index(element.presence)] != 0
        )

    def atol(self) -> np.ndarray:
        """Every state's absolute tolerance, for the reference solver."""
        return np.array([s.atol for s in self.states.quantities], dtype=np.float64)


def assemble(elements: Sequence[Element]) -> PlantLayout:
    """Lay ``elements`` end to end (module docstring)."""
    state_offset, param_offset = {}, {}
    states, params, outputs = [], [], []
    for element in elements:
        state_offset[element.name] = len(states)
        param_offset[element.name] = len(params)
        states.extend(element.states)
        params.extend(element.params)
        outputs.extend(element.outputs)
    return PlantLayout(
        tuple(elements),
        Layout(states),
        Layout(params),
        Layout(outputs),
        state_offset,
        param_offset,
    )
