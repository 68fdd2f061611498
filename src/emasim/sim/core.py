"""The compiled core's inputs: a few typed records instead of a long list of arrays.

One run of the compiled loop (:func:`emasim.sim.engine.run_ticks`) reads

* :class:`PlantArrays`: the packed SI parameters and every state's divergence bound;
* :class:`SignalArrays`: the reference and the three loads, encoded (emasim.signals);
* :class:`SensorArrays`: the sensor table, the sensors' state, and the map from the rudder
  encoder's angle to the rod position it stands for (rudder feedback);
* the **drive**'s state: its I^2 t heat, the voltage applied before the computation delay,
  the current limit in force and the limits that acted (``D_*`` below);
* the **slots** position, speed and current: each a controller law with the library's
  signature (:data:`emasim.control.slot.CONTROLLER_SIG`), called through a function pointer,
  and its ``(params, state)`` arrays. The three laws are arguments of their own (numba types
  a law given inside a tuple through an experimental path, with a warning at every call);
  their arrays travel as one tuple;
* :class:`Timing`: sample period, sub-steps per sample, recording period, noise seed,
  which loops close, the computation delay and which sensor the position loop closes on;
* :class:`TraceArrays`: the recorded columns, which the loop fills every ``record_every``
  ticks;
* :class:`Workspace`: the scratch arrays of the RK4 stages and of the control tick, made by
  the caller so that the loop can borrow them (emasim.sim.borrowed).

:meth:`emasim.sim.setup.Setup.start` builds them from a Setup, which a scenario builds
(:meth:`emasim.scenarios.schema.Scenario.setup`); the engine, the reference path, the
co-simulation, the FMU slaves and the benchmarks all take them from there.

Measured before adopting this, on the 2-core development machine:

* a prototype loop of 5e6 ticks calling a controller through a pointer, the arrays as records
  or as flat arguments, interleaved in one process: 0.175 s against 0.174 s; numba's disk
  cache serves records in a fresh process, provided their classes live in a module (here),
  not in ``__main__``;
* a record passed to a function called at every RK4 sub-step costs 15 % of the lumped loop
  (0.87 against 0.75 us per sub-step), so ``plant_step`` takes its three loads as arrays;
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
from ..interface import N_MEAS, N_OUT, N_REF
from ..plant.actuator import N_STATE
from ..plant.linkage import N_HINGES

F8 = types.float64
I8 = types.int64
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


class PlantArrays(NamedTuple):
    """The plant: packed SI parameters (emasim.plant.actuator layout), state bounds."""

    params: np.ndarray
    limits: np.ndarray


class SignalArrays(NamedTuple):
    """Encoded signals: the outer loop's reference (SI) and the loads."""

    reference: np.ndarray
    motor_load: np.ndarray  # N m on the motor shaft
    rod_load: np.ndarray  # N on the rod, positive opposing extension
    rudder_load: np.ndarray  # N m on the linkage's rudder shaft, opposing positive deflection


class SensorArrays(NamedTuple):
    """The sensor table and state (emasim.plant.sensors), and ``rudder_to_rod``: an encoded
    table (emasim.signals) from a rudder angle (rad, as its "time") to the rod position (m)
    the rigid kinematics give, read when the position loop closes on the rudder encoder."""

    table: np.ndarray
    state: np.ndarray
    rudder_to_rod: np.ndarray


class Timing(NamedTuple):
    """When things happen: Ts (s), RK4 sub-steps per tick, ticks per recorded row, the seed of
    the sensor noise, the loop structure (engine.LOOP_*), the computation delay in sub-steps
    (the voltage computed at a tick is applied that many sub-steps later, at most one tick)
    and the position loop's feedback (engine.FEEDBACK_*)."""

    sample_period_s: float
    substeps: int
    record_every: int
    seed: int
    loop: int
    delay_substeps: int
    feedback: int


# the drive's state (Core.drive), kept from tick to tick
D_HEAT = 0  # I^2 t heat above the continuous rating (A^2 s; emasim.plant.ratings)
D_UD = 1  # the voltage applied until the delayed command takes over (V)
D_UQ = 2
D_CURRENT_LIMIT = 3  # the current limit in force at the last tick (A)
D_FLAGS = 4  # the limits that acted at the last tick (emasim.interface.LIMIT_* bits)
D_FOLDED = 5  # 1 while the I^2 t protection holds the current at its continuous rating
D_LAW = 6  # 1 + the slot whose law gave a non-finite output this tick (0: none; engine)
N_DRIVE = 7


class Workspace(NamedTuple):
    """Scratch reused from tick to tick: the RK4 stage derivatives k1..k4 and stage state and
    the linkage's hinge table (emasim.sim.engine.plant_step), and the measurements, reference
    and output of a slot."""

    rk4: tuple
    hinges: np.ndarray
    meas: np.ndarray
    ref: np.ndarray
    out: np.ndarray


class TraceArrays(NamedTuple):
    """The recorded traces, one row of ``data`` per kept column (so each signal is contiguous,
    and a Result and its Parquet file take it without a copy); ``columns`` holds the TRACE
    index (emasim.sim.engine) of each kept column, and ``row`` is the scratch a full TRACE
    row is assembled in before its kept columns are stored."""

    data: np.ndarray
    columns: np.ndarray
    row: np.ndarray


class Core(NamedTuple):
    """Everything :func:`emasim.sim.engine.run_ticks` reads besides the state and the trace,
    in its argument order: ``run_ticks(k0, k1, x, *core, trace, status)``."""

    plant: PlantArrays
    signals: SignalArrays
    sensors: SensorArrays
    drive: np.ndarray
    position_law: object  # the slots' compiled laws
    speed_law: object
    current_law: object
    slots: tuple  # ((params, state) of the position, the speed and the current slot)
    timing: Timing
    workspace: Workspace


PLANT_TYPE = types.NamedUniTuple(F8A, 2, PlantArrays)
SIGNALS_TYPE = types.NamedUniTuple(F8A, 4, SignalArrays)
SENSORS_TYPE = types.NamedTuple((F8A2, F8A2, F8A), SensorArrays)
TIMING_TYPE = types.NamedTuple((F8, I8, I8, I8, I8, I8, I8), Timing)
RK4_TYPE = types.UniTuple(F8A, 5)
TRACE_TYPE = types.NamedTuple((F8A2, types.int64[::1], F8A), TraceArrays)
WORKSPACE_TYPE = types.NamedTuple((RK4_TYPE, F8A2, F8A, F8A, F8A), Workspace)
SLOTS_TYPE = types.UniTuple(types.UniTuple(F8A, 2), 3)  # (params, state) of each slot
LAW_TYPE = CONTROLLER_TYPE
POSITION_SLOT, SPEED_SLOT, CURRENT_SLOT = range(3)


def new_workspace() -> Workspace:
    """A fresh :class:`Workspace`."""
    return Workspace(
        tuple(np.zeros(N_STATE) for _ in range(5)),
        np.zeros((N_HINGES, 2)),
        np.zeros(N_MEAS),
        np.zeros(N_REF),
        np.zeros(N_OUT),
    )
