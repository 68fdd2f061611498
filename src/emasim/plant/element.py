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

import functools
import heapq
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..config import MM, RPM
from ..jit import njit

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


@njit(cache=True, inline="always", error_model="numpy")
def viscous_force(damping, rate):
    """c v: a viscous force (N) or torque (N m) on a body moving at ``rate``."""
    return damping * rate


@njit(cache=True, inline="always", error_model="numpy")
def total(a, b):
    """a + b: two forces on one body."""
    return a + b


def two_body_rate(stiffness: float, m1: float, m2: float = math.inf) -> float:
    """omega = sqrt(k (1/m1 + 1/m2)) (rad/s): two masses on a spring, each free (m2 = inf: the
    spring's other end fixed)."""
    return math.sqrt(stiffness * (1.0 / m1 + 1.0 / m2))


GROUND = "ground"  # the node that never moves
# how far a closed gap's contact overlaps (m or rad; Element.closed): it loads the contact so
# that its damping limit |c dv| <= k |dx| (emasim.plant.elements.backlash) stays beyond a
# small signal's velocity, while its force k * 1e-9 (0.15 N on sea805) changes no slope
CLOSED_OVERLAP = 1e-9
RK4_OSCILLATOR_LIMIT = 2.0 * math.sqrt(2.0)  # RK4 is stable for omega h below this (imaginary axis)
RK4_DECAY_LIMIT = 2.78  # and for lambda h below this (negative real axis)


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
class Law:
    """A compiled function (``inline="always"``) of bound arguments, its results named.

    An argument is bound by a token: ``x.<state>``, ``p.<param>``, ``in.<input>`` (u_d, u_q,
    t_load, f_load, t_rudder), ``<node>.x``/``.v`` (a node's motion), ``<node>.fold`` (the
    force an absent body passes to the node it merges into, 0 while present), ``x[<element>]``,
    ``dx[<element>]`` or ``p[<element>]`` (an element's slice: a view made at every call, so
    for outputs only), ``x``, ``dx``, ``p`` and ``x0[<element>]``, ``p0[<element>]`` (the whole
    vectors and where an element starts in them: what the right-hand side passes, slicing
    only where it must), ``hinges``, a number, or the
    name of a result of an earlier law of the same element. A port written ``a|b`` is node a
    where some element provides it, else b.
    """

    function: Callable
    args: tuple[str, ...]
    results: tuple[str, ...]
    always: bool = False  # evaluated whether or not the element is present


@dataclass(frozen=True)
class Body:
    """A moving node: ``position`` and ``velocity`` states (m, m/s or rad, rad/s) and the
    parameter ``mass`` (kg or kg m^2); d velocity/dt = (sum of the forces on the node) / mass
    (+ the accelerations derived nodes push). While its element is absent the node is
    ``alias`` (its forces go there, its states stay). ``order`` fixes the order of the sum
    (floating-point sums are not associative, and the clearance-joint bench amplifies a
    rounding difference into a different trace): the terms of the named elements, or the
    named terms (``fold_far``, ``f_load``), first in that order, then the rest in element
    order."""

    node: str
    position: str
    velocity: str
    mass: str
    alias: str | None = None
    order: tuple[str, ...] = ()  # its equation's terms, in this order: element names or terms


@dataclass(frozen=True)
class Coupling:
    """A force between two ports: F = law(x_a - x_b, v_a - v_b, *params) pushes port ``b``
    forward and port ``a`` back (a port ``ground`` feels nothing). ``result`` names F for the
    element's forces and values."""

    law: Callable
    a: str
    b: str
    params: tuple[str, ...]
    result: str = "force"


@dataclass(frozen=True)
class Derived:
    """A node whose motion follows other nodes: ``motion`` returns (x, v); the force on the
    node, bound as ``<node>.f``, is passed on by ``fold``, whose results push the nodes of
    ``onto`` in order (``<node>.a``: an acceleration of the node, added after the division by
    its mass). ``exchange`` names the fold result the
    right-hand side returns (the force a co-simulation exchanges), if any."""

    node: str
    motion: Law
    fold: Law
    onto: tuple[str, ...]
    exchange: str | None = None


Mode = tuple[str, float, float]  # (what, rate in rad/s or 1/s, the RK4 stability limit of h * rate)


@dataclass(frozen=True)
class Element:
    """One physical element of the plant (module docstring).

    Its behaviour: ``bodies`` (nodes it owns), ``derived`` (nodes that follow others),
    ``couplings`` and ``laws`` (computed in that order), ``forces`` ((node, signed result):
    ``"-torque"`` pushes the node back), ``rates`` ((state, result): d state/dt), ``values``
    ((output, result)), and ``modes(value)``, its natural modes for the divergence diagnosis
    and the stable step (``value(name)`` reads a packed parameter, ``mass(port)`` the mass of
    the body at a port, that of its alias while it is absent). ``mechanism`` marks the
    rudder side, which a co-simulation integrates apart (emasim.sim.mechanism).

    Its place and configuration: ``after`` names the element it follows in the vectors (the
    first has none; the mechanism's elements come after the drive's); ``section`` the
    PlantParams field that configures it, whose model is ``config`` for an optional element
    (emasim.plant.parameters adds the field); ``pack(plant)`` its parameters' SI values by
    name from a validated PlantParams (an optional element's presence parameter is then 1),
    ``initial(plant)`` its states' initial values (0 where it names none), ``reflected(plant)``
    the inertia it adds at the motor shaft (kg m^2) and the mass it adds at the rod (kg), for
    design; ``stage`` the ablation stage (emasim.experiments.ablation) whose removal takes it
    out, with ``removed(plant)`` the other sections' changes its removal needs.
    """

    name: str
    description: str
    states: tuple[State, ...] = ()
    params: tuple[Quantity, ...] = ()
    outputs: tuple[Quantity, ...] = ()
    presence: str | None = None  # a parameter that is 0 when the element is absent
    bodies: tuple[Body, ...] = ()
    derived: tuple[Derived, ...] = ()
    couplings: tuple[Coupling, ...] = ()
    laws: tuple[Law, ...] = ()
    forces: tuple[tuple[str, str], ...] = ()
    rates: tuple[tuple[str, str], ...] = ()
    values: tuple[tuple[str, str], ...] = ()
    modes: Callable = field(default=lambda value, mass: [], compare=False)
    mechanism: bool = False
    after: str | None = None  # the element it follows in the state and parameter vectors
    section: str | None = None  # the PlantParams section that configures it
    config: type | None = None  # an optional element's section model (None: a fixed section)
    pack: Callable = field(default=lambda plant: {}, compare=False)
    initial: Callable = field(default=lambda plant: {}, compare=False)
    reflected: Callable = field(default=lambda plant: (0.0, 0.0), compare=False)
    stage: str | None = None  # the ablation stage that takes the element out
    removed: Callable = field(default=lambda plant: {}, compare=False)
    # parameter -> value that closes the element's play for a small-signal model
    # (emasim.linear, gaps="closed"): its contact kept loaded by CLOSED_OVERLAP
    closed: tuple[tuple[str, float], ...] = ()


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

    def value_of(self, params: np.ndarray) -> Callable[[str], float]:
        """A reader of the packed ``params`` by parameter name."""
        return lambda name: float(params[self.params.index(name)])

    @functools.cached_property
    def bodies(self) -> dict[str, tuple[Element, Body]]:
        """node -> (the element, its Body) of every body of the plant."""
        return {b.node: (e, b) for e in self.elements for b in e.bodies}

    @functools.cached_property
    def derived(self) -> dict[str, tuple[Element, Derived]]:
        """node -> (the element, its Derived) of every derived node of the plant."""
        return {d.node: (e, d) for e in self.elements for d in e.derived}

    def port(self, name: str) -> str:
        """The node a port names: the first of ``a|b`` that some element provides (or the
        ground)."""
        for candidate in name.split("|"):
            if candidate == GROUND or candidate in self.bodies or candidate in self.derived:
                return candidate
        raise ValueError(f"no element provides a node for the port '{name}'")

    def mass_at(self, params: np.ndarray, port: str) -> float:
        """The mass (kg or kg m^2) of the body at ``port``: its own while its element is
        present, else its alias's; infinite for the ground."""
        node = self.port(port)
        if node == GROUND:
            return math.inf
        if node not in self.bodies:
            raise ValueError(f"no body at the port '{port}'")
        element, body = self.bodies[node]
        if element.presence is None or params[self.params.index(element.presence)] != 0:
            return float(params[self.params.index(body.mass)])
        return self.mass_at(params, body.alias)

    def modes(self, params: np.ndarray) -> list[Mode]:
        """The natural modes (what, rate, RK4 limit of h * rate) of every present element."""
        present = self.present_elements(params)
        value = self.value_of(params)
        return [
            mode
            for element in self.elements
            if element.name in present
            for mode in element.modes(value, lambda port: self.mass_at(params, port))
        ]

    def atol(self) -> np.ndarray:
        """Every state's absolute tolerance, for the reference solver."""
        return np.array([s.atol for s in self.states.quantities], dtype=np.float64)


def ordered(elements: Sequence[Element]) -> tuple[Element, ...]:
    """The elements in the order of the vectors: each after the element it names in ``after``
    (the drive's before the mechanism's, then by name, where several follow one)."""
    by_name = {e.name: e for e in elements}
    followers: dict[str | None, list[Element]] = {}
    for element in elements:
        if element.after is not None and element.after not in by_name:
            raise ValueError(
                f"element '{element.name}' follows '{element.after}', not a plant element"
            )
        followers.setdefault(element.after, []).append(element)
    ready = [(e.mechanism, e.name) for e in followers.get(None, [])]
    heapq.heapify(ready)
    out = []
    while ready:
        element = by_name[heapq.heappop(ready)[1]]
        out.append(element)
        for follower in followers.get(element.name, []):
            heapq.heappush(ready, (follower.mechanism, follower.name))
    if len(out) != len(elements):
        raise ValueError("the elements' 'after' names make a loop")
    return tuple(out)


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
