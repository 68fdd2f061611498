"""The drive's rated limits: the motor's rated speed, and its peak and continuous current.

The drive holds them on whatever a controller commands (emasim.sim.engine.control_tick):

* **peak and continuous current (I^2 t).** The drive integrates the heat above the continuous
  rating, E(k+1) = clamp(E(k) + (iq*^2 - I_cont^2) Ts, 0, E_max), with the capacity
  E_max = (I_peak^2 - I_cont^2) t_peak: the peak current may flow for t_peak from cold. The
  current command is limited to I_peak (the motor's max_current_A) until E reaches E_max, then
  to I_cont until the motor has cooled to (1 - RECOVERY) E_max (the hysteresis keeps the
  limit from chattering as the current settles about I_cont).
* **rated speed.** Above (1 - SPEED_FOLDBACK) of the rated speed w_r, the current that drives
  the motor faster folds back linearly, to zero at w_r (on the drive's own speed reading):

      iq* <= I_lim clamp((w_r - w) / (SPEED_FOLDBACK w_r), 0, 1)   for w > 0, and mirrored.

Each tick the engine records which limits acted (the LIMIT_* bits of emasim.interface) and the
current limit in force;
the run metrics give the time spent in each (emasim.analysis.report). Without the element the
drive holds only max_current_A, max_speed_rpm on the speed command, and the inverter's voltage.
"""

from pydantic import Field

from ...config import RPM, Strict
from ...jit import njit
from ...numerics import clamp
from ..element import Element, Quantity

SPEED_FOLDBACK = 0.05  # the current folds back over the last 5 % below the rated speed
RECOVERY = 0.1  # the peak current returns once the heat is 10 % below its capacity


@njit(cache=True, inline="always", error_model="numpy")
def heat_update(heat, iq, continuous, capacity, ts):
    """E(k+1) = clamp(E(k) + (iq^2 - I_cont^2) Ts, 0, E_max) (A^2 s)."""
    return clamp(heat + (iq * iq - continuous * continuous) * ts, 0.0, capacity)


@njit(cache=True, inline="always", error_model="numpy")
def folded_back(folded, heat, capacity):
    """Whether the current stays folded back to I_cont after this tick's heat (the hysteresis
    of the module docstring)."""
    if heat >= capacity:
        return True
    if heat <= (1.0 - RECOVERY) * capacity:
        return False
    return folded


@njit(cache=True, inline="always", error_model="numpy")
def speed_foldback(w, rated):
    """The fractions (upper, lower) of the current limit left for driving the motor forward
    and backward at speed w (module docstring)."""
    band = SPEED_FOLDBACK * rated
    return clamp((rated - w) / band, 0.0, 1.0), clamp((rated + w) / band, 0.0, 1.0)


class RatingsParams(Strict):
    """The rated limits (module docstring); the peak current is the motor's max_current_A."""

    rated_speed_rpm: float = Field(gt=0, le=1e5, description="w_r, held on the motor's speed")
    continuous_current_A: float = Field(gt=0, le=1e4, description="I_cont, the thermal rating")
    peak_current_s: float = Field(
        gt=0, le=3600, description="t_peak: how long the peak current may flow from cold"
    )


RATINGS = Element(
    "ratings",
    "the drive's rated speed and its peak and continuous current (I^2 t)",
    params=(
        Quantity("ratings_present", "1", "1 with the element, 0 without"),
        Quantity("rated_speed_rad_s", "rad/s", "w_r"),
        Quantity("continuous_current_A", "A", "I_cont"),
        Quantity("heat_capacity_A2s", "A^2 s", "E_max = (I_peak^2 - I_cont^2) t_peak"),
    ),
    presence="ratings_present",
    after="end_stops",
    section="ratings",
    config=RatingsParams,
    pack=lambda plant: {
        "rated_speed_rad_s": plant.ratings.rated_speed_rpm * RPM,
        "continuous_current_A": plant.ratings.continuous_current_A,
        "heat_capacity_A2s": (plant.motor.max_current_A**2 - plant.ratings.continuous_current_A**2)
        * plant.ratings.peak_current_s,
    },
    stage="digital drive",
)
