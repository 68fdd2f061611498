"""The compiled core's inputs: two records, MuJoCo-style, each declared once.

One run of the compiled loop is ``run_ticks(k0, k1, model, data, position_law, speed_law,
current_law)`` (:func:`emasim.sim.engine.run_ticks`):

* :class:`Model`: what the run reads and never changes (the plant's parameters and bounds, the
  signals, the sensor table, the slots' parameters, the kept trace columns, :class:`Timing`);
* :class:`Data`: what it changes (the plant state, the sensors', the drive's and the slots'
  states, the scratch, the trace, the status);
* the three **laws** (position, speed, current): controller laws with the library's signature
  (:data:`emasim.control.slot.CONTROLLER_SIG`), called through function pointers. They are
  arguments of their own: numba types a law given inside a tuple through an experimental path,
  with a warning at every call.

Each record is a NamedTuple whose annotations are its fields' numba types; :func:`numba_type`
derives its numba type from them, and :data:`RUN_SIG` follows from those, so a field is added
in one place. The loop borrows every array of both records on entry, whatever their fields
(emasim.sim.borrowed.borrowed_record). :meth:`emasim.sim.setup.Setup.start` builds them from
a Setup, which a scenario builds (:meth:`emasim.scenarios.schema.Scenario.setup`); the engine,
the reference path, the co-simulation, the FMU slaves and the benchmarks all take them from
there.

Measured before adopting this, on the 2-core development machine:

* a prototype loop of 5e6 ticks calling a controller through a pointer, the arrays as records
  or as flat arguments, interleaved in one process: 0.175 s against 0.174 s; numba's disk
  cache serves records in a fresh process, provided their classes live in a module (here),
  not in ``__main__``;
* a record passed to a function called at every RK4 sub-step costs 15 % of the lumped loop
  (0.87 against 0.75 us per sub-step), so ``plant_step`` takes its three loads as arrays
  (the records are read once a tick);
* each call of ``run_ticks`` from Python costs far more than a tick: 116 us with the old 26
  arguments, 278 us with three laws handed over as dispatchers (numba looks up their machine
  code at every call), 91 us as :class:`LawAddress`. So a run is one call
  (twenty with a progress bar), and laws travel as addresses.
"""

from collections.abc import Callable
from typing import ClassVar, NamedTuple

import numpy as np
from numba import types

from ..control.slot import CONTROLLER_TYPE, controller_signature
from ..plant.actuator import N_STATE
from ..plant.elements.linkage import N_HINGES

F8 = types.float64
I8 = types.int64
I8A = types.int64[::1]
F8A = types.float64[::1]
F8A2 = types.float64[:, ::1]


class LawAddress(types.WrapperAddressProtocol):
    """A compiled law's address, for numba's first-class function arguments.

    Handed a dispatcher, numba looks its address up in the LLVM library at every call of the
    compiled loop (two symbol look-ups per law); handed this, it reads the cached integer.
    Measured: 91 against 278 us per call of run_ticks with three laws (module docstring). One
    instance per law function, shared: :meth:`of`.
    """

    _cache: ClassVar[dict] = {}

    def __init__(self, function: Callable):
        from numba.experimental.function_type import _get_wrapper_address

        self.function = function
        # a law declared with emasim.jit.njit hands over its numba dispatcher
        self.address = _get_wrapper_address(
            getattr(function, "dispatcher", function), controller_signature()
        )

    @classmethod
    def of(cls, function: Callable) -> "LawAddress":
        if function not in cls._cache:
            cls._cache[function] = cls(function)
        return cls._cache[function]

    def __wrapper_address__(self) -> int:
        return self.address

    def signature(self):
        return controller_signature()


def numba_type(record: type) -> types.Type:
    """The numba type of a record class, from its fields' annotations (a record field's type is
    that record's numba type in turn): the one declaration each record needs."""
    fields = tuple(
        numba_type(t) if isinstance(t, type) and issubclass(t, tuple) else t
        for t in (record.__annotations__[name] for name in record._fields)
    )
    if len(set(fields)) == 1:  # numba types a namedtuple of one field type as a "uni" tuple
        return types.NamedUniTuple(fields[0], len(fields), record)
    return types.NamedTuple(fields, record)


class Timing(NamedTuple):
    """When things happen: Ts (s), RK4 sub-steps per tick, ticks per recorded row, the seed of
    the sensor noise, the loop structure (LOOP_*), the computation delay in sub-steps (the
    voltage computed at a tick is applied that many sub-steps later, at most one tick) and the
    position loop's feedback (FEEDBACK_*)."""

    sample_period_s: F8
    substeps: I8
    record_every: I8
    seed: I8
    loop: I8
    delay_substeps: I8
    feedback: I8


class Model(NamedTuple):
    """What a run reads and never changes: the packed SI parameters (emasim.plant.actuator
    layout) and every state's divergence bound; the encoded reference (SI) and loads
    (emasim.signals): N m on the motor shaft, N on the rod (positive opposing extension), N m
    on the rudder shaft (opposing positive deflection); the sensor table (emasim.plant.sensors)
    and ``rudder_to_rod``, an encoded table from a rudder angle (rad, as its "time") to the rod
    position (m) the rigid kinematics give, read when the position loop closes on the rudder
    encoder; each slot's parameters (position, speed, current); the TRACE index of each kept
    trace column (emasim.sim.trace); and the timing."""

    params: F8A
    limits: F8A
    reference: F8A
    motor_load: F8A
    rod_load: F8A
    rudder_load: F8A
    sensor_table: F8A2
    rudder_to_rod: F8A
    slot_params: types.UniTuple(F8A, 3)
    trace_columns: I8A
    timing: Timing


class Workspace(NamedTuple):
    """The plant step's scratch (emasim.sim.engine.plant_step): the RK4 stage derivatives
    k1..k4 and stage state, and the linkage's hinge table."""

    rk4: types.UniTuple(F8A, 5)
    hinges: F8A2


class Data(NamedTuple):
    """What a run changes: the plant state; the sensors' state; the drive's state (``D_*``);
    each slot's state; the plant step's workspace; the measurements, reference and output of a
    slot, reused from tick to tick; the recorded traces (one row of ``trace`` per kept column,
    so each signal is contiguous and a Result and its Parquet file take it without a copy) and
    the scratch a full TRACE row is assembled in before its kept columns are stored; and the
    status (code, tick, index) the loop stops with (emasim.sim.engine)."""

    x: F8A
    sensor_state: F8A2
    drive: F8A
    slot_states: types.UniTuple(F8A, 3)
    work: Workspace
    meas: F8A
    ref: F8A
    out: F8A
    trace: F8A2
    trace_row: F8A
    status: I8A


# the drive's state (Data.drive), kept from tick to tick
D_HEAT = 0  # I^2 t heat above the continuous rating (A^2 s; emasim.plant.elements.ratings)
D_UD = 1  # the voltage applied until the delayed command takes over (V)
D_UQ = 2
D_CURRENT_LIMIT = 3  # the current limit in force at the last tick (A)
D_FLAGS = 4  # the limits that acted at the last tick (emasim.interface.LIMIT_* bits)
D_FOLDED = 5  # 1 while the I^2 t protection holds the current at its continuous rating
D_LAW = 6  # 1 + the slot whose law gave a non-finite output this tick (0: none; engine)
N_DRIVE = 7

LOOP_SPEED = 0  # reference is a motor speed: speed controller -> current loop
LOOP_POSITION = 1  # reference is a rod position: position -> speed -> current (cascade)
LOOP_POSITION_CURRENT = 2  # position controller commands the current loop directly

FEEDBACK_ROD = 0  # the position loop closes on the rod's displacement sensor
FEEDBACK_RUDDER = 1  # ... on the rudder encoder, through the rigid kinematics' rod position
FEEDBACK_MOTOR = 2  # ... on the motor encoder, read as the nut's travel K theta_m (semi-closed)

MODEL_TYPE = numba_type(Model)
DATA_TYPE = numba_type(Data)
WORKSPACE_TYPE = numba_type(Workspace)
LAW_TYPE = CONTROLLER_TYPE
POSITION_SLOT, SPEED_SLOT, CURRENT_SLOT = range(3)
RUN_SIG = types.void(I8, I8, MODEL_TYPE, DATA_TYPE, LAW_TYPE, LAW_TYPE, LAW_TYPE)


def new_workspace() -> Workspace:
    """A fresh :class:`Workspace`."""
    return Workspace(tuple(np.zeros(N_STATE) for _ in range(5)), np.zeros((N_HINGES, 2)))
