"""The controller calling convention, and what a controller may know of the plant.

A controller is a compiled function ``f(state, params, meas, ref, ts, out)``:

    state  float64[::1]  its own memory (integrators, filters), read and written
    params float64[::1]  its gains and limits, read only
    meas   float64[::1]  sensor readings, layout in emasim.interface (M_*)
    ref    float64[::1]  set-point, its rate and acceleration (R_*)
    ts     float64       sample period (s)
    out    float64[::1]  command and its rate (O_*), written

Every library controller is compiled with exactly :data:`CONTROLLER_SIG` and ``cache=True``
(:func:`controller_law`, when a :class:`Compiled` is made); the engine receives it as a
first-class function value
(:data:`CONTROLLER_TYPE`), so changing the controller never recompiles the loop. A user's own
``@numba.njit(CONTROLLER_SIG)`` function plugs in the same way.

``CONTROLLER_SIG`` and ``CONTROLLER_TYPE`` are numba types, made when first asked for: the
configs of this package are checked without importing numba (emasim.jit).
"""

import functools
import math
from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

from ..config import STRICT
from ..errors import InputError
from ..jit import njit

Loop = Literal["speed", "position"]


@functools.cache
def controller_signature():
    """CONTROLLER_SIG: void(state, params, meas, ref, ts, out), float64[::1] arrays and a
    float64 ts (the module docstring)."""
    from numba import types

    array = types.float64[::1]
    return types.void(array, array, array, array, types.float64, array)


def __getattr__(name: str):
    """CONTROLLER_SIG and CONTROLLER_TYPE (its first-class function type), made on first use."""
    if name == "CONTROLLER_SIG":
        return controller_signature()
    if name == "CONTROLLER_TYPE":
        from numba import types

        return types.FunctionType(controller_signature())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass(frozen=True)
class PlantFacts:
    """The plant knowledge a controller design may use (SI units)."""

    inertia_kgm2: float  # motor inertia + load reflected to the motor shaft
    torque_constant_Nm_per_A: float  # kt = 1.5 np psi_f
    ratio_m_per_rad: float  # K: rod metres per motor radian
    max_current_A: float
    max_speed_rad_s: float
    resistance_ohm: float
    inductance_d_H: float
    inductance_q_H: float
    flux_linkage_Wb: float
    pole_pairs: int
    dc_bus_V: float

    @property
    def max_voltage_V(self) -> float:
        """Largest dq voltage magnitude of an SVPWM inverter, Udc/sqrt(3)."""
        return self.dc_bus_V / math.sqrt(3.0)


@dataclass(frozen=True)
class Compiled:
    """A controller ready for the engine: its function, parameter array and initial state.

    ``commands`` says what its out[O_VALUE] is: a q-axis current (A) or a motor speed (rad/s).
    Speed-loop controllers command a current; a position controller commands either the speed
    loop (cascade) or the current loop directly; the current loop commands the voltages.
    """

    function: Callable
    params: np.ndarray
    state: np.ndarray
    commands: Literal["current", "speed", "voltage"] = "current"

    def __post_init__(self):
        # a law decorated with controller_law is compiled here, on first use (from the disk
        # cache when warm), so that importing the library does not load every controller
        signature = controller_signature()
        if not hasattr(self.function, "overloads"):  # a plain Python function: numba cannot call it
            name = getattr(self.function, "__name__", repr(self.function))
            raise InputError(
                f"the control law {name} is a plain Python function; compile it with "
                "numba.njit(emasim.control.slot.CONTROLLER_SIG) "
                "(docs/guide.md: a controller of your own)"
            )
        if signature.args not in self.function.overloads:
            self.function.compile(signature)


def controller_law(function: Callable) -> Callable:
    """Decorator of library controller laws: numba-compiled with the engine's conventions
    (``cache=True``, numpy error model), compiled to :data:`CONTROLLER_SIG` when first used."""
    return njit(cache=True, error_model="numpy")(function)


@controller_law
def unused_law(state, params, meas, ref, ts, out):
    """The law of a slot no loop closes (the position slot of a speed-loop run): the loop never
    calls it; were it called, its NaN output would stop the run as a failed law."""
    out[:] = np.nan


@functools.cache
def absent_slot() -> Compiled:
    """:func:`unused_law`, ready for a slot no loop closes."""
    return Compiled(unused_law, np.zeros(1), np.zeros(1))


class ControllerConfig(BaseModel):
    """Base of controller configs: validated, unit-suffixed fields, no unknown keys."""

    model_config = ConfigDict(**STRICT, validate_assignment=True)
    loop: ClassVar[Loop]

    @abstractmethod
    def build(self, plant: PlantFacts, ts: float) -> Compiled:
        """Gains and limits for this plant and sample period, packed for the engine."""

    def tunable_ranges(self) -> dict[str, tuple[float, float]]:
        """Fields a tuning study may set, each with its search range (sampled log-uniformly).

        Only design knobs of the law this config selects; limits and structure stay fixed.
        """
        return {}

    def with_explicit_gains(self, plant: PlantFacts) -> "ControllerConfig":
        """This config with every gain a design rule derives written out as a field of its
        own, so that a tuning study searches the gains themselves (emasim.tuning); the same
        law. Itself for a config whose knobs are its gains already."""
        return self
