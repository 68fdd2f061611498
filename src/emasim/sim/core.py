"""The compiled core's inputs: a few typed records instead of a long list of arrays.

One run of the compiled loop (:func:`emasim.sim.engine.run_ticks`) reads

* :class:`PlantArrays`: the packed SI parameters and every state's divergence bound;
* :class:`SignalArrays`: the reference and the three loads, encoded (emasim.signals);
* :class:`SensorArrays`: the sensor table and the play operators' states;
* the **slots**: a tuple (position, speed, current), each slot a plain tuple
  ``(function, params, state)`` of a controller law with the library's signature
  (:data:`emasim.control.slot.CONTROLLER_SIG`), called through a function pointer;
* :class:`Timing`: sample period, sub-steps per sample, recording period, noise seed and
  which loops close.

:meth:`emasim.sim.setup.Setup.start` builds them from a Setup, which a scenario builds
(:meth:`emasim.scenarios.schema.Scenario.setup`); the engine, the reference path, the
co-simulation, the FMU slaves and the benchmarks all take them from there.

Measured before adopting this (a prototype loop of 5e6 ticks calling a controller through a
pointer, in one process, interleaved; numba 0.6x): the records cost nothing against flat
arrays (0.175 s against 0.174 s), and numba's disk cache serves them in a fresh process,
provided the record classes live in a module (here), not in ``__main__``.
"""

from typing import NamedTuple

import numpy as np
from numba import types

from ..control.slot import CONTROLLER_TYPE

F8 = types.float64
I8 = types.int64
F8A = types.float64[::1]
F8A2 = types.float64[:, ::1]


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
    """The (N_MEAS x 4) sensor table and the state of each channel's play operator."""

    table: np.ndarray
    gap: np.ndarray


class Timing(NamedTuple):
    """When things happen: Ts (s), RK4 sub-steps per tick, ticks per recorded row, the seed of
    the sensor noise, and the loop structure (engine.LOOP_*)."""

    sample_period_s: float
    substeps: int
    record_every: int
    seed: int
    loop: int


PLANT_TYPE = types.NamedUniTuple(F8A, 2, PlantArrays)
SIGNALS_TYPE = types.NamedUniTuple(F8A, 4, SignalArrays)
SENSORS_TYPE = types.NamedTuple((F8A2, F8A), SensorArrays)
TIMING_TYPE = types.NamedTuple((F8, I8, I8, I8, I8), Timing)
SLOT_TYPE = types.Tuple((CONTROLLER_TYPE, F8A, F8A))  # (function, params, state)
SLOTS_TYPE = types.UniTuple(SLOT_TYPE, 3)  # position, speed, current
POSITION_SLOT, SPEED_SLOT, CURRENT_SLOT = range(3)
