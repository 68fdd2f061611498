"""Actuator acceptance tests, the ARP1281 family: the datasheet of each controller set.

The battery runs on a position scenario's plant and each of its controller sets. Every test is a
run of its own, from rest at mid stroke, with the scenario's load signals removed (the plant's
standing loads, a load motor's preload, stay) and its own command and load:

* **Frequency response**, small and large signal: stepped sines of the position command,
  amplitude a fraction of the full stroke (1 % and 10 %, peak), at log-spaced frequencies. Each
  run settles for ``settle_s`` plus ``settle_cycles`` periods, then the fundamental of the
  output over the command (:mod:`emasim.analysis.frequency`) is read over a whole number of
  periods. Figures: the -3 dB bandwidth, the frequencies of -45 and -90 deg phase, each
  interpolated inside the measured band or, outside it, a bound: ``< f_min`` where the response
  is already past the level at the lowest frequency, ``> f_max`` where it never reaches it
  (:func:`band_figures`). The phase is read up to where it turns back up (a smooth loop's phase
  does not; past the turn a crossing may hide between two frequencies, so a level not reached
  before it is ``>`` the last frequency before it), and a phase level is not measurable where
  the lowest frequency is already beyond the bandwidth (a lag there of more than 180 deg reads
  as a lead). With ``excitation="chirp"`` one logarithmic sweep per amplitude replaces the
  stepped sines (a band an eighth of a decade beyond the frequencies read, ``chirp_s`` long,
  after ``settle_s`` at rest and followed by ``settle_s`` more), read by the Fourier transforms
  of the whole record (:func:`emasim.analysis.frequency.sweep_response`): fewer simulated
  seconds (the wall time against the stepped sines': benchmarks/bench_acceptance.py), and for a
  nonlinear loop the best linear approximation instead of each amplitude's describing function.
  Every response is read on several outputs (OUTPUTS: the controlled position, the motor speed,
  the q current) and kept (:class:`Response`): the datasheet saves them as
  frequency_response.csv, and :meth:`Acceptance.frequency_response` gives any of them as a
  ``control.FrequencyResponseData``.
* **The linear model beside them**: where ``emasim.linearize`` models the loop (plays
  closed, friction dropped, about the battery's rest state: mid stroke after ``settle_s``,
  the standing loads on), its responses from the command and from the rod force at the same
  frequencies, overlaid on the measured ones; elsewhere the reason it has none (a law without
  a linear form; the nominal bench, whose linkage hinges hang open at rest with no standing
  load).
* **Threshold and hysteresis**: a slow triangle of the command after a hold of ``settle_s``
  at mid stroke. The threshold is the command travel after each reversal before the output
  has moved ``detection_mm`` the new way, less ``detection_mm`` (for a pure dead band of width
  w it is w, whatever the detection level); the median over the reversals. The hysteresis
  width is the largest gap between the output's falling and rising branches at equal
  command, over the middle 90 % of the command range (for a play of width w it is w). Both
  are read only where the loop's own motion leaves them readable: its limit cycle ±A (half
  the largest swing of the output against the command's direction mid sweep, or at rest in
  the hold: :func:`limit_cycle`) is a figure of the sheet, and with A over a fifth of the
  triangle's amplitude both are "not measurable: the loop limit-cycles ±A"; a swing 2A over
  the detection level leaves the threshold not measurable, one over a fifth of the width
  read the hysteresis (:func:`triangle_figures`, which says why). A threshold is never
  negative: where the output moved faster than the command it is the bound
  ``< detection_mm``.
* **Stiffness**: static, a rod-force step (a fraction of the theoretical stall force
  kt I_max / K) while the command holds: force over the output's deflection, the peak one and
  the one left at the end of the hold (with integral action none is left above the output's
  own jitter: the static figure is then a lower bound, force over the jitter, and says so);
  dynamic, |F / x|(f) from rod-force sines.
* **Rate and load**: the no-load rate (a step of ``rate_step_fraction`` of the stroke, the
  standing loads removed; the output's mean rate from 10 % to 90 % of the travel), the
  rate at rated load (the same step against a constant rod force: kt I_cont / K with the
  drive's ratings, else half the theoretical stall force), and the stall force: the opposing
  rod force, ramped slowly, at which the output has been pushed back ``stall_deflection_mm``.
  The RMS current sqrt(mean(id^2 + iq^2)) (A, the dq magnitude: the unit of the drive's
  current limit) and the net electrical energy per cycle
  integral 3/2 (ud id + uq iq) dt (J) come from the large-signal sine at ``cycle_frequency_Hz``.

A crossing outside the measured band or past a turn of the phase, a threshold below the
detection level and a figure the loop's limit cycle swamps are given neither as a number nor as
None: as a bound, ``{"bound": "<" or ">", "value": x}`` (with ``"why"`` where the band's edge is
not the reason), or as ``{"not_measurable": what, "why": why}`` (FIGURE_FORMS; the tables print
"< x", "> x" and "not measurable: what", report.html each "why" below its table).

The output is the position the loop controls, noise-free, in rod millimetres: the rod for 'rod'
and 'motor' feedback (with motor feedback the backlash and the compliance are outside the loop,
and show), the rudder angle through the rigid kinematics for 'rudder' feedback. Rod forces are
positive when they oppose extension. The runs are a job list on the job store
(:mod:`emasim.experiments.store`, ``runs/acceptance/jobs-<key>``: threads in this process by
default, the compiled loop releasing the GIL): each run's measurement is kept in its run folder
(``measured.json``) and its numbers in the store's table, so a battery killed part way resumes
from the runs it finished when run again.
"""

import itertools
import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import control
import numpy as np
from pydantic import ValidationError

from ..analysis import frequency as fr
from ..analysis.metrics import rise_time
from ..arguments import (
    choice,
    client_or_none,
    flag,
    function_or_none,
    integer,
    number,
    positive,
    positive_numbers,
    strings,
)
from ..errors import InputError
from ..jsonio import json_text
from ..linear import linearize
from ..naming import RUNS_ROOT, slug
from ..scenarios.loader import describe_errors
from ..scenarios.schema import Scenario, rudder_rod_grid
from ..sim.engine import EngineRun, simulate
from .batch import Job
from .store import RUN_ID, Measured, keyed

if TYPE_CHECKING:
    from dask.distributed import Client

MM = 1e-3
RPM_PER_RAD_S = 30.0 / math.pi
RECORDED = (
    "motor_speed_rad_s",
    "position_ref_m",
    "actuator_position_m",
    "rudder_angle_rad",
    "id_A",
    "iq_A",
    "ud_V",
    "uq_V",
    "rod_load_N",
)
DECADE_EIGHTHS = tuple(float(10 ** (k / 8)) for k in range(-4, 13))  # 0.32 .. 31.6 Hz
DECADE_QUARTERS = DECADE_EIGHTHS[::2]
EXCITATIONS = ("stepped", "chirp")
CHIRP_MARGIN = 10 ** (1 / 8)  # the chirp's band beyond the frequencies read: DECADE_EIGHTHS' step
INPUTS = {"position_command": "m", "rod_force_N": "N"}  # what a response is excited by
OUTPUTS = {  # what every response is read on, and the linear model's reading of it
    "position": ("m", "measured_position_m"),
    "motor_speed_rad_s": ("rad/s", "motor_speed_rad_s"),
    "iq_A": ("A", "iq_A"),
}


HALF_STROKE = 0.5  # a command's amplitude, as a fraction of the full stroke, about mid stroke
BATTERY_RANGES = {  # Battery's numeric settings: (check, its bounds) (emasim.arguments)
    "small_amplitude": (positive, HALF_STROKE),
    "large_amplitude": (positive, HALF_STROKE),
    "frequencies_Hz": (positive_numbers,),
    "settle_s": (positive,),
    "settle_cycles": (integer, 0),
    "measure_cycles": (integer, 1),
    "measure_min_s": (number, 0.0),
    "triangle_amplitude": (positive, HALF_STROKE),
    "triangle_period_s": (positive,),
    "triangle_cycles": (integer, 2),  # the hysteresis reads a whole rising and falling sweep
    "detection_mm": (positive,),
    "load_step": (positive, 1.0),  # of the theoretical stall force
    "load_hold_s": (positive,),
    "dynamic_force": (positive, 1.0),
    "stiffness_frequencies_Hz": (positive_numbers,),
    "rate_step_fraction": (positive, HALF_STROKE),
    "stall_ramp_per_s": (positive,),
    "stall_deflection_mm": (positive,),
    "cycle_frequency_Hz": (positive,),
    "chirp_s": (positive,),
}


@dataclass(frozen=True)
class Battery:
    """The battery's settings (amplitudes as fractions of the full stroke, forces of the
    theoretical stall force kt I_max / K; times in s). The time the defaults take is measured in
    benchmarks/bench_acceptance.py."""

    small_amplitude: float = 0.01
    large_amplitude: float = 0.10
    frequencies_Hz: tuple[float, ...] = DECADE_EIGHTHS
    settle_s: float = 1.0
    settle_cycles: int = 2
    measure_cycles: int = 2
    measure_min_s: float = 0.5
    triangle_amplitude: float = 0.002
    triangle_period_s: float = 4.0
    triangle_cycles: int = 2
    detection_mm: float = 0.002
    load_step: float = 0.2
    load_hold_s: float = 2.0
    dynamic_force: float = 0.05
    stiffness_frequencies_Hz: tuple[float, ...] = DECADE_QUARTERS
    rate_step_fraction: float = 0.2
    stall_ramp_per_s: float = 1.0
    stall_deflection_mm: float = 1.0
    cycle_frequency_Hz: float = 1.0
    excitation: str = "stepped"
    chirp_s: float = 30.0

    def __post_init__(self):
        """Every setting checked here, at construction: InputError, one line naming it and
        its range (BATTERY_RANGES); numbers kept as floats, frequency lists as tuples. What
        depends on the scenario (the frequencies below its recording's Nyquist frequency) is
        checked by :func:`check_acceptance`."""
        # the command line's message, kept: ``emasim acceptance --excitation`` reads it
        choice("excitation", self.excitation, EXCITATIONS)
        for name, (check, *bounds) in BATTERY_RANGES.items():
            object.__setattr__(self, name, check(f"Battery: {name}", getattr(self, name), *bounds))

    @property
    def band_Hz(self) -> tuple[float, float]:
        """A chirp's band: CHIRP_MARGIN below the lowest to CHIRP_MARGIN above the highest
        frequency read (no further: a sweep that drove the loop into its current limit
        beyond the band would spread that distortion over the band)."""
        every = self.frequencies_Hz + self.stiffness_frequencies_Hz
        return min(every) / CHIRP_MARGIN, max(every) * CHIRP_MARGIN

    def periods(self, frequency_Hz: float) -> tuple[float, float]:
        """(settling time, measured window) of a stepped sine: whole periods for the window."""
        period = 1.0 / frequency_Hz
        window = period * max(self.measure_cycles, math.ceil(self.measure_min_s / period))
        return self.settle_s + self.settle_cycles * period, window


@dataclass(frozen=True)
class Drive:
    """What the battery derives from the plant: stroke (m), theoretical stall force
    kt I_max / K (N), rated load (N), the drive's speed limit (rpm, and at the rod in m/s), and
    how to read the controlled output (m)."""

    stroke_m: float
    stall_force_N: float
    rated_load_N: float
    max_speed_rpm: float  # the drive's speed-command limit
    max_rate_m_s: float  # ... at the rod
    rudder_grid: tuple[np.ndarray, np.ndarray] | None = field(repr=False)  # angle -> rod map

    @classmethod
    def of(cls, scenario: Scenario) -> "Drive":
        plant = scenario.plant
        kt, k = plant.torque_constant_Nm_per_A, plant.ratio_m_per_rad
        stall = kt * plant.motor.max_current_A / k
        rated = (
            kt * plant.ratings.continuous_current_A / k if plant.ratings is not None else stall / 2
        )
        grid = rudder_rod_grid(plant) if scenario.loop.position_feedback == "rudder" else None
        speed = plant.motor.max_speed_rpm
        stroke = plant.drivetrain.stroke_mm * MM
        return cls(stroke, stall, rated, speed, speed / RPM_PER_RAD_S * k, grid)

    def output_m(self, result) -> np.ndarray:
        if self.rudder_grid is None:
            return result["actuator_position_m"]
        return np.interp(result["rudder_angle_rad"], *self.rudder_grid)

    def outputs(self, result) -> dict[str, np.ndarray]:
        """Every output of OUTPUTS a response is read on, from a run's result."""
        return {
            "position": self.output_m(result),
            "motor_speed_rad_s": result["motor_speed_rad_s"],
            "iq_A": result["iq_A"],
        }


@dataclass(frozen=True)
class Response:
    """One frequency response: ``output`` (an OUTPUTS key) over ``input`` (an INPUTS key) at
    ``frequencies_Hz``, complex, in the output's unit per the input's. ``excitation`` is the
    battery's run: "small" or "large" (the command), "force" (the rod force), or "model" (the
    linear model, which has no amplitude); ``amplitude`` the excitation's peak (m or N);
    ``source`` how it was read: "stepped" or "chirp" (measured), or "linear model"."""

    input: str
    excitation: str
    amplitude: float | None
    output: str
    frequencies_Hz: np.ndarray
    h: np.ndarray
    source: str

    @property
    def input_unit(self) -> str:
        return INPUTS[self.input]

    @property
    def output_unit(self) -> str:
        return OUTPUTS[self.output][0]


# --- the figures' forms --------------------------------------------------------------------

FIGURE_FORMS = (
    'a figure is a number, or where the battery cannot state one, {"bound": "<" or ">", '
    '"value": x}: it lies below or above x (a crossing outside the measured band, or past '
    'where the phase turns back up, then with "why"; a threshold below the detection level), or '
    '{"not_measurable": what, "why": why} (a phase level past the bandwidth at the lowest '
    "frequency; a threshold or hysteresis the loop's own limit cycle swamps)"
)


def bound(side: str, value: float, why: str | None = None) -> dict:
    """A figure known only to lie below (``"<"``) or above (``">"``) ``value``, and why where
    the band's edge is not the reason (FIGURE_FORMS)."""
    out = {"bound": side, "value": float(value)}
    return out if why is None else out | {"why": why}


def unmeasurable(what: str, why: str) -> dict:
    """A figure the battery cannot read on this loop, what stops it and why (FIGURE_FORMS)."""
    return {"not_measurable": what, "why": why}


def crossing(frequencies_Hz: np.ndarray, values: np.ndarray, level: float) -> float | dict:
    """The first frequency where ``values`` fall to ``level`` (dB or deg), interpolated in log
    frequency (:func:`emasim.analysis.frequency.first_crossing`) where it lies inside the
    measured band; else a bound: ``< f_min`` where the first value is already below the level,
    ``> f_max`` where none reaches it."""
    if values[0] < level:
        return bound("<", frequencies_Hz[0])
    found = fr.first_crossing(frequencies_Hz, values, level)
    return bound(">", frequencies_Hz[-1]) if found is None else found


PHASE_TURN_DEG = 10.0  # a lag shrinking by more from one frequency to the next: no smooth loop


def phase_crossing(frequencies_Hz: np.ndarray, phases: np.ndarray, level: float):
    """:func:`crossing` of the phase, read only up to where it turns back up: where the lag
    shrinks by more than PHASE_TURN_DEG from one measured frequency to the next, the response
    is no smooth linear loop's (a minimum-phase loop's lag shrinks only where its gain rises),
    and past that the grid can miss a crossing: on bench-step's industrial PID at ±2.5 mm the
    drive's current limit makes the response collapse between 18.3 and 18.6 Hz, its phase
    dipping to -94 deg between the battery's 17.8 and 23.7 Hz, read -46 and -9 deg. A level
    not reached before the turn is the bound ``>`` the last frequency before it, with why."""
    rises = np.flatnonzero(np.diff(phases) > PHASE_TURN_DEG)
    if rises.size == 0:
        return crossing(frequencies_Hz, phases, level)
    k = int(rises[0])
    found = crossing(frequencies_Hz[: k + 1], phases[: k + 1], level)
    if not isinstance(found, dict) or found["bound"] == "<":
        return found
    f, ph = frequencies_Hz, phases
    return bound(
        ">",
        f[k],
        f"the phase turns back up between {f[k]:.4g} and {f[k + 1]:.4g} Hz ({ph[k]:.3g} to "
        f"{ph[k + 1]:.3g} deg): past that, a crossing may lie between measured frequencies",
    )


def band_figures(frequencies_Hz, h) -> dict:
    """The closed loop's figures from its response H(f) over the measured band: the -3 dB
    bandwidth, the frequencies of -45 and -90 deg phase (each a value or a bound:
    :func:`crossing`, :func:`phase_crossing`) and the peak gain (dB).

    The phase is unwrapped from the lowest frequency, taken there in (-180, 180]: right where
    the lag there is under 180 deg, as it is where the loop still follows (gain above -3 dB).
    Where the lowest frequency is already beyond the bandwidth, a lag of more than 180 deg
    there reads as a lead, so a phase level its first reading has not reached is not
    measurable (one it has reached is ``< f_min`` on any turn of the phase)."""
    f = np.asarray(frequencies_Hz, dtype=float)
    gains, phases = fr.gain_dB(h), fr.phase_deg(h)
    figures = {"bandwidth_Hz": crossing(f, gains, -3.0)}
    for level, key in ((-45.0, "phase_45_Hz"), (-90.0, "phase_90_Hz")):
        if gains[0] < -3.0 and phases[0] > level:
            figures[key] = unmeasurable(
                f"the lowest frequency, {f[0]:.4g} Hz, is beyond the bandwidth",
                f"the gain there is {gains[0]:.3g} dB: a lag of more than 180 deg there "
                f"reads as a lead ({phases[0]:.3g} deg)",
            )
        else:
            figures[key] = phase_crossing(f, phases, level)
    figures["peak_gain_dB"] = float(np.max(gains))
    return figures


# --- the runs -----------------------------------------------------------------------------


def battery_scenario(
    base: Scenario,
    duration_s: float,
    position_mm: list[dict],
    rod_force_N: list[dict] | None = None,
    no_standing_load: bool = False,
) -> Scenario:
    """``base`` with this command and rod force, its load signals removed, recording only what
    the battery reads; validated again (a command beyond the stroke is refused)."""
    raw = base.model_dump(mode="json", exclude_none=True)
    raw.update(duration_s=duration_s, compare=[], reference={"position_mm": position_mm})
    raw["load"] = {"rod_force_N": rod_force_N or []}
    raw["solver"]["record_signals"] = list(RECORDED)
    if no_standing_load and raw["plant"].get("load_motor"):
        raw["plant"]["load_motor"]["preload_Nm"] = 0.0
    try:
        return Scenario.model_validate(raw)
    except ValidationError as err:  # a Battery whose run this plant cannot take: one line
        lines = "; ".join(describe_errors(err))
        raise InputError(
            f"Battery: these settings make a run {base.name} refuses: {lines}"
        ) from None


def sine_job(base, drive, battery, frequency_Hz, amplitude_m, force_N=0.0):
    """One stepped sine: of the command (amplitude_m) or of a rod force (force_N)."""
    settle, window = battery.periods(frequency_Hz)
    if force_N:
        command = [{"type": "constant", "value": 0.0}]
        force = [{"type": "sine", "amplitude": force_N, "frequency_Hz": frequency_Hz}]
    else:
        command = [{"type": "sine", "amplitude": amplitude_m / MM, "frequency_Hz": frequency_Hz}]
        force = None
    return _job("sine", battery_scenario(base, settle + window, command, force))


def measure_sine(scenario, drive, battery) -> dict:
    """The fundamental of the output over the command (or over the rod force), and the
    drive's RMS current and electrical energy per period over the measured window."""
    result = simulate(scenario.setup())
    term = (scenario.load.rod_force_N or scenario.reference.position_mm)[0]
    f = term.frequency_Hz
    settle, _ = battery.periods(f)
    t = result.t
    keep = t >= settle - 1e-9
    excitation = result["rod_load_N"] if scenario.load.rod_force_N else result["position_ref_m"]
    outputs = drive.outputs(result)
    responses = {
        name: fr.response(t[keep], excitation[keep], y[keep], f) for name, y in outputs.items()
    }
    i_d, i_q = result["id_A"][keep], result["iq_A"][keep]
    power = 1.5 * (result["ud_V"][keep] * i_d + result["uq_V"][keep] * i_q)
    span = t[keep][-1] - t[keep][0]
    return {
        "frequency_Hz": f,
        "responses": responses,
        "output_amplitude_m": abs(fr.phasor(t[keep], outputs["position"][keep], f)),
        "rms_current_A": float(np.sqrt(np.mean(i_d**2 + i_q**2))),
        "energy_per_cycle_J": float(np.trapezoid(power, t[keep]) / (span * f)),
    }


def chirp_job(base, drive, battery, amplitude_m, force_N=0.0):
    """One logarithmic sweep over the battery's band, of the command (amplitude_m) or of a rod
    force (force_N): settle_s at rest, the sweep, then settle_s for the response to die out."""
    low, high = battery.band_Hz
    start = battery.settle_s
    sweep = {"type": "chirp", "start_Hz": low, "end_Hz": high, "start_s": start}
    sweep["duration_s"] = battery.chirp_s
    if force_N:
        command = [{"type": "constant", "value": 0.0}]
        force = [sweep | {"amplitude": force_N}]
    else:
        command, force = [sweep | {"amplitude": amplitude_m / MM}], None
    duration = start + battery.chirp_s + battery.settle_s
    return _job("chirp", battery_scenario(base, duration, command, force))


def measure_chirp(scenario, drive, battery) -> dict:
    """Every output's response to the sweep at the battery's frequencies (the stiffness
    frequencies for a rod-force sweep), deviations from the rest before it."""
    result = simulate(scenario.setup())
    forced = bool(scenario.load.rod_force_N)
    sweep = (scenario.load.rod_force_N or scenario.reference.position_mm)[0]
    t = result.t
    rest = (t >= 0.5 * sweep.start_s) & (t < sweep.start_s)
    keep = t >= sweep.start_s
    excitation = result["rod_load_N"] if forced else result["position_ref_m"]
    u = excitation[keep] - np.mean(excitation[rest])
    f = np.array(battery.stiffness_frequencies_Hz if forced else battery.frequencies_Hz)
    responses = {
        name: fr.sweep_response(t[keep], u, y[keep] - np.mean(y[rest]), f)
        for name, y in drive.outputs(result).items()
    }
    return {"frequencies_Hz": f, "responses": responses}


def triangle_job(base, drive, battery):
    """Hold mid stroke for settle_s, then a slow triangle of the command about it, upwards."""
    a = battery.triangle_amplitude * drive.stroke_m / MM
    quarter, hold = battery.triangle_period_s / 4, battery.settle_s
    n = 4 * battery.triangle_cycles
    times = [0.0, hold, *(hold + quarter * (2 * k + 1) for k in range(n // 2)), hold + quarter * n]
    values = [0.0, 0.0, *(a if k % 2 == 0 else -a for k in range(n // 2)), 0.0]
    command = [{"type": "table", "time_s": times, "values": values}]
    return _job("triangle", battery_scenario(base, times[-1], command))


def measure_triangle(scenario, drive, battery) -> dict:
    """The triangle run's readings (m), before the datasheet judges them
    (:func:`triangle_figures`): each reversal's threshold reading (inf where the output never
    moved ``detection_mm`` the new way before the next one) and the command's travel after it,
    the hysteresis width read, and the loop's own motion (:func:`limit_cycle`)."""
    result = simulate(scenario.setup())
    t, command, output = result.t, result["position_ref_m"], drive.output_m(result)
    term = scenario.reference.position_mm[0]
    hold, reversals, end = term.time_s[1], list(term.time_s[2:-1]), term.time_s[-1]
    delta = battery.detection_mm * MM
    readings, travels = [], []
    for k, t_rev in enumerate(reversals):
        sign = -1.0 if k % 2 == 0 else 1.0  # the command's new direction
        after = t >= t_rev
        if k + 1 < len(reversals):
            after &= t < reversals[k + 1]
        y, c = output[after], command[after]
        extreme = np.maximum.accumulate(-sign * y) * -sign  # the output's turn-around
        moved = np.flatnonzero(sign * (y - extreme) >= delta)
        readings.append(abs(c[moved[0]] - c[0]) - delta if moved.size else math.inf)
        travels.append(float(abs(c[-1] - c[0])))
    a = battery.triangle_amplitude * drive.stroke_m
    grid = np.linspace(-0.9 * a, 0.9 * a, 361)
    rising, falling = _branches(t, command, output, reversals)
    width = float(np.max(np.interp(grid, *falling) - np.interp(grid, *rising)))
    shown = t >= reversals[0]
    return {
        "threshold_readings_m": [float(x) for x in readings],
        "threshold_travels_m": travels,
        "hysteresis_m": width,
        "limit_cycle_m": limit_cycle(t, command, output, [hold, *reversals, end], a),
        "loop": (command[shown], output[shown]),
    }


SWEEP_MIDDLE = 0.6  # the part of a sweep read for the loop's own motion: |command| <= 0.6 a


def limit_cycle(t, command, output, corners, amplitude_m) -> float:
    """The loop's own motion during the triangle run (m): half the largest swing of the output
    against the command's direction while the command sweeps between two corners (the hold's
    end, the reversals, the end), read where the command is within SWEEP_MIDDLE of the
    amplitude (away from the reversals, where the threshold and the loop's transient are), or
    half the output's peak-to-peak about its mean over the second half of the hold, whichever
    is larger. A loop that follows the slow sweep never moves against it: 0 (a dead band
    stops the output, it does not reverse it). A loop that hunts does, by about its
    oscillation's peak-to-peak: the bench's loops rest still in the hold and hunt only once
    the command moves, which is why the sweeps are read."""
    hold = corners[0]
    resting = (t >= 0.5 * hold) & (t < hold)
    swings = [0.5 * float(np.ptp(output[resting]))] if resting.any() else [0.0]
    for start, stop in itertools.pairwise(corners):
        inside = (t >= start) & (t < stop) & (np.abs(command) <= SWEEP_MIDDLE * amplitude_m)
        if np.count_nonzero(inside) < 2:
            continue
        c, y = command[inside], output[inside]
        sign = 1.0 if c[-1] >= c[0] else -1.0  # the sweep's direction
        ahead = np.maximum.accumulate(sign * y)  # the output's furthest point so far
        swings.append(0.5 * float(np.max(ahead - sign * y)))
    return max(swings)


LIMIT_CYCLE_FRACTION = 0.2  # of the triangle's amplitude: beyond, neither figure is read
WIDTH_SHARE = 0.2  # the most of a hysteresis width read that the loop's swing may account for


def triangle_figures(triangle: dict, amplitude_m: float, detection_m: float) -> dict:
    """The datasheet's threshold, hysteresis and limit cycle (mm) from the triangle's readings
    (:func:`measure_triangle`), judged against the loop's own motion: its limit cycle, ±A (A
    half its swing, :func:`limit_cycle`), and the battery's resolution, the detection level d.

    * 2A below d: the loop is quiet at the battery's resolution; both figures are read. A
      threshold is the median of the reversals' readings; it is never negative: a negative
      median means the output moved d the new way with less than d of command travel, faster
      than the command (a transient, not a dead band), so the threshold is stated as below the
      battery's resolution, the bound ``< d``. Where most reversals left the output unmoved,
      it is the bound ``>`` the least command travel (less d) that did not move it.
    * A above LIMIT_CYCLE_FRACTION (a fifth) of the triangle's amplitude: the loop
      limit-cycles, its own swing comparable to the test's; the output's reversals are the
      loop's, not the command's, and the branches are the oscillation's envelope: neither
      figure is read (``not measurable``, with A).
    * In between: the threshold is not measurable (the loop's own swing, 2A, is over the
      detection level: it triggers the detection whatever the command does). The hysteresis
      width is read with an error of up to 2A (each branch moved by up to A); it is reported
      where 2A is at most WIDTH_SHARE (a fifth) of the width read, else not measurable.

    A figure that is not a number is ``{"bound": "<" or ">", "value": x}`` or
    ``{"not_measurable": what, "why": why}`` (FIGURE_FORMS)."""
    a, d = amplitude_m, detection_m
    swing = triangle["limit_cycle_m"]
    width = triangle["hysteresis_m"]
    lc = f"the loop limit-cycles ±{swing / MM:.3g} mm"
    out = {"limit_cycle_mm": swing / MM}
    if 2 * swing < d:
        readings = np.array(triangle["threshold_readings_m"])
        median = float(np.median(readings))
        if math.isinf(median):
            travels = np.array(triangle["threshold_travels_m"])[np.isinf(readings)]
            out["threshold_mm"] = bound(">", float(np.min(travels) - d) / MM)
        elif median < 0:
            out["threshold_mm"] = bound("<", d / MM)
        else:
            out["threshold_mm"] = median / MM
        out["hysteresis_mm"] = width / MM
    elif swing > LIMIT_CYCLE_FRACTION * a:
        why = f"more than a fifth of the triangle's amplitude, ±{a / MM:.3g} mm"
        out["threshold_mm"] = out["hysteresis_mm"] = unmeasurable(lc, why)
    else:
        why = f"its swing, {2 * swing / MM:.3g} mm, is over the detection level, {d / MM:.3g} mm"
        out["threshold_mm"] = unmeasurable(lc, why)
        if 2 * swing > WIDTH_SHARE * width:
            why = (
                f"its swing, {2 * swing / MM:.3g} mm, is over a fifth of the width read, "
                f"{width / MM:.3g} mm"
            )
            out["hysteresis_mm"] = unmeasurable(lc, why)
        else:
            out["hysteresis_mm"] = width / MM
    return {key: out[key] for key in ("threshold_mm", "hysteresis_mm", "limit_cycle_mm")}


def _branches(t, command, output, reversals):
    """(command, output) of the last whole rising and falling sweeps (reversal to reversal),
    command ascending."""
    sweeps = []
    for k in range(1, len(reversals)):
        inside = (t >= reversals[k - 1]) & (t < reversals[k])
        sweeps.append((command[inside], output[inside], k % 2 == 0))
    rising = [(c, y) for c, y, up in sweeps if up][-1]
    falling = [(c[::-1], y[::-1]) for c, y, up in sweeps if not up][-1]
    return rising, falling


def load_step_job(base, drive, battery):
    """Hold mid stroke, a rod-force step at settle_s, hold load_hold_s."""
    force = battery.load_step * drive.stall_force_N
    step = [{"type": "step", "time_s": battery.settle_s, "final": force}]
    command = [{"type": "constant", "value": 0.0}]
    duration = battery.settle_s + battery.load_hold_s
    return _job("load_step", battery_scenario(base, duration, command, step))


def measure_load_step(scenario, drive, battery) -> dict:
    """Force over the output's peak deflection, and over the deflection left at the end (the
    mean of the last fifth of the hold, against the jitter before the step)."""
    result = simulate(scenario.setup())
    t, y = result.t, drive.output_m(result)
    step_time = scenario.load.rod_force_N[0].time_s
    force = scenario.load.rod_force_N[0].final
    before = (t > step_time - 0.2 * battery.load_hold_s) & (t < step_time)
    rest = float(np.mean(y[before]))
    jitter = float(np.ptp(y[before]))
    after = t >= step_time
    deflection = y[after] - rest
    peak = float(np.max(np.abs(deflection)))
    end = float(abs(np.mean(deflection[t[after] >= t[-1] - 0.2 * battery.load_hold_s])))
    resolved = end > jitter
    return {
        "load_step_N": force,
        "peak_deflection_m": peak,
        "steady_deflection_m": end,
        "peak_stiffness_N_per_m": force / peak,
        "static_stiffness_N_per_m": force / max(end, jitter, 1e-12),
        "static_stiffness_lower_bound": not resolved,
    }


def rate_job(base, drive, battery, load_N):
    """A step of rate_step_fraction of the stroke at settle_s / 2, against a constant rod force
    (or unloaded: load_N = 0, the standing loads removed)."""
    start = 0.5 * battery.settle_s
    travel = battery.rate_step_fraction * drive.stroke_m / MM
    command = [{"type": "step", "time_s": start, "final": travel}]
    force = [{"type": "constant", "value": load_N}] if load_N else None
    duration = start + 3.0 * travel * MM / drive.max_rate_m_s + battery.settle_s
    scenario = battery_scenario(base, duration, command, force, no_standing_load=not load_N)
    return _job("rate", scenario)


def measure_rate(scenario, drive, battery) -> dict:
    """The output's mean rate (m/s) from 10 % to 90 % of the step's travel, the slope of the
    stroke's constant-rate part (first crossings, interpolated), and the motor's peak speed
    (rad/s: the drive limits the speed command, the speed loop may overshoot it)."""
    result = simulate(scenario.setup())
    travel = scenario.reference.position_mm[0].final * MM
    rise = rise_time(result.t, drive.output_m(result), initial=0.0, final=travel)
    return {
        "rate_m_s": 0.8 * travel / rise if math.isfinite(rise) else None,
        "peak_speed_rad_s": float(np.max(np.abs(result["motor_speed_rad_s"]))),
    }


def stall_job(base, drive, battery):
    """Hold mid stroke; from settle_s an opposing rod force ramps up at stall_ramp_per_s of the
    theoretical stall force per second, to 1.5 times it."""
    slope = battery.stall_ramp_per_s * drive.stall_force_N
    start = battery.settle_s
    end = start + 1.5 / battery.stall_ramp_per_s
    ramp = [{"type": "ramp", "slope_per_s": slope, "start_s": start, "end_s": end}]
    command = [{"type": "constant", "value": 0.0}]
    return _job("stall", battery_scenario(base, end, command, ramp))


STALL_CHUNK_S = 0.01


def measure_stall(scenario, drive, battery) -> dict:
    """The rod force at which the output has been pushed back stall_deflection_mm (N), the run
    stopped there (past the stall the load drives the motor away); None if it held."""
    setup = scenario.setup()
    run = EngineRun(setup, stream=False)  # its trace is read as the run goes
    chunk = max(1, round(STALL_CHUNK_S / setup.sample_period_s))
    limit = battery.stall_deflection_mm * MM
    start = scenario.load.rod_force_N[0].start_s
    rest, checked = None, 0
    while run.tick < setup.n_ticks:
        run.advance(min(setup.n_ticks, run.tick + chunk))
        rows = run.tick // setup.record_every
        result = run.result()
        t = result.t[:rows]
        if t[-1] <= start:
            continue
        if rest is None:  # once: where the output rests before the ramp
            before = (t > 0.8 * start) & (t < start)
            rest = float(np.mean(drive.output_m(result)[:rows][before]))
            checked = int(np.searchsorted(t, start))
        y = drive.output_m(result)[checked:rows]  # only the rows not checked yet
        pushed = np.flatnonzero(rest - y >= limit)
        if pushed.size:
            return {"stall_force_N": float(result["rod_load_N"][checked + pushed[0]])}
        checked = rows
    return {"stall_force_N": None}


MEASURES = {
    "sine": measure_sine,
    "chirp": measure_chirp,
    "triangle": measure_triangle,
    "load_step": measure_load_step,
    "rate": measure_rate,
    "stall": measure_stall,
}


MEASURE = "measure"  # a battery job's tag: which of MEASURES reads its run
# ... and what it measures, the point: ("small", f), ("chirp", "large"), ("triangle",), ...
POINT, POINT_HZ, POINT_OF = "point", "point_Hz", "point_of"  # its parts, each a column
MEASURED_FILE = "measured.json"  # in each run folder of the store: the whole measurement
STORE_ROOT = RUNS_ROOT / "acceptance"


def _job(kind: str, scenario: Scenario) -> Job:
    """A battery run: its scenario, tagged with the MEASURES entry that reads it."""
    return Job(scenario, tags={MEASURE: kind})


def measure(job: Job, drive: "Drive", battery: "Battery") -> dict:
    """Run a battery job and read it (its MEASURES entry)."""
    return MEASURES[job.tags[MEASURE]](job.scenario, drive, battery)


def measure_point(battery: "Battery", job: Job) -> Measured:
    """The store's ``measure`` of a battery job: its numbers for the table and the whole
    measurement (:func:`encoded`) for its run folder."""
    values = measure(job, Drive.of(job.scenario), battery)
    numbers = {
        k: v for k, v in values.items() if v is None or isinstance(v, bool | int | float | str)
    }
    return Measured(numbers, {MEASURED_FILE: json.dumps(encoded(values))})


def point_tags(point: tuple) -> dict:
    """A point's tags, each a plain column: its name, its frequency or what it sweeps."""
    name, *rest = point
    detail = rest[0] if rest else None
    of = detail if isinstance(detail, str) else None
    return {POINT: name, POINT_HZ: None if detail is None or of else float(detail), POINT_OF: of}


def point_of(job: Job) -> tuple:
    """The point a battery job measures, from its tags (:func:`point_tags`)."""
    detail = job.tags[POINT_HZ] if job.tags[POINT_HZ] is not None else job.tags[POINT_OF]
    return (job.tags[POINT],) if detail is None else (job.tags[POINT], detail)


def encoded(value):
    """``value`` (a measurement: dicts, tuples, lists, numbers, complex numbers, numpy arrays)
    as JSON data that :func:`decoded` turns back exactly: a complex number, an array, a
    tuple and a float that is not finite become one-key objects naming what they are."""
    if isinstance(value, dict):
        return {key: encoded(v) for key, v in value.items()}
    if isinstance(value, tuple):
        return {"tuple": [encoded(v) for v in value]}
    if isinstance(value, list):
        return [encoded(v) for v in value]
    if isinstance(value, np.ndarray):
        return {"array": encoded(value.tolist()), "dtype": value.dtype.str}
    if isinstance(value, complex | np.complexfloating):
        return {"complex": [encoded(float(value.real)), encoded(float(value.imag))]}
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else {"float": repr(float(value))}
    return value.item() if isinstance(value, np.generic) else value


def decoded(value):
    """The value :func:`encoded` made ``value`` of."""
    if isinstance(value, list):
        return [decoded(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "tuple" in value:
        return tuple(decoded(v) for v in value["tuple"])
    if "array" in value:
        return np.array(decoded(value["array"]), dtype=np.dtype(value["dtype"]))
    if "complex" in value:
        return complex(*decoded(value["complex"]))
    if "float" in value:
        return float(value["float"])
    return {key: decoded(v) for key, v in value.items()}


# --- the battery ----------------------------------------------------------------------------

DEFINITIONS = {
    "small_amplitude_mm": "the small-signal command's peak amplitude (a fraction of the stroke)",
    "large_amplitude_mm": "the large-signal command's peak amplitude (a fraction of the stroke)",
    "bandwidth_small_Hz": "first frequency where |x/x_cmd| falls to -3 dB, small signal; "
    "'< f' or '> f' where that lies outside the measured band",
    "bandwidth_large_Hz": "first frequency where |x/x_cmd| falls to -3 dB, large signal; "
    "'< f' or '> f' where that lies outside the measured band",
    "phase_45_small_Hz": "first frequency of -45 deg phase of x/x_cmd, small signal; a bound "
    "outside the measured band or past where the phase turns back up",
    "phase_90_small_Hz": "first frequency of -90 deg phase of x/x_cmd, small signal; a bound "
    "outside the measured band or past where the phase turns back up",
    "phase_45_large_Hz": "first frequency of -45 deg phase of x/x_cmd, large signal; a bound "
    "outside the measured band or past where the phase turns back up",
    "phase_90_large_Hz": "first frequency of -90 deg phase of x/x_cmd, large signal; a bound "
    "outside the measured band or past where the phase turns back up",
    "peak_gain_small_dB": "largest |x/x_cmd| over the band, small signal (resonance peak)",
    "peak_gain_large_dB": "largest |x/x_cmd| over the band, large signal",
    "threshold_mm": "command travel after a reversal of a slow triangle before the output moves "
    "(less the detection level), median over the reversals; '< detection level' where the "
    "output moved faster than the command; not measurable where the loop's own swing is over "
    "the detection level",
    "hysteresis_mm": "largest gap between the output's falling and rising branches at equal "
    "command, over the middle 90 % of the slow triangle; not measurable where the loop "
    "limit-cycles more than a fifth of the triangle's amplitude, or its swing is over a fifth "
    "of the width read",
    "limit_cycle_mm": "the loop's own oscillation in the slow triangle, half its swing against "
    "the command's direction mid sweep (or at rest in the hold); 0 for a loop that follows",
    "static_stiffness_N_per_mm": "rod-force step over the deflection left at the end of the hold; "
    "a lower bound (force over the output's jitter) where integral action leaves none",
    "static_stiffness_lower_bound": "true when static_stiffness_N_per_mm is that lower bound",
    "load_step_stiffness_N_per_mm": "rod-force step over the output's peak deflection",
    "dynamic_stiffness_min_N_per_mm": "least |F/x| over the band of rod-force sines",
    "dynamic_stiffness_min_Hz": "where that least dynamic stiffness occurs",
    "no_load_rate_mm_s": "mean output rate from 10 % to 90 % of a step, standing loads removed",
    "no_load_peak_speed_rpm": "the motor's peak speed in that step (the drive limits the speed "
    "command to max_speed_rpm; the speed loop can overshoot it)",
    "max_speed_rpm": "the drive's speed-command limit, motor.max_speed_rpm",
    "rated_load_N": "the rated load: kt I_continuous / K with the drive's ratings, else half "
    "the theoretical stall force",
    "rate_at_rated_load_mm_s": "the same rate against a constant rod force of the rated load",
    "stall_force_N": "opposing rod force, ramped slowly, at which the output has been pushed "
    "back by the stall deflection",
    "theoretical_stall_force_N": "kt I_max / K, the drive's peak current through the screw",
    "rms_current_A": "RMS of the dq current magnitude over the large-signal sine at the cycle "
    "frequency",
    "energy_per_cycle_J": "net electrical energy 3/2 (ud id + uq iq) over one period of that sine",
}


@dataclass
class Acceptance:
    """The battery's outcome: ``figures`` label -> the datasheet's figures (DEFINITIONS, in
    the units their names carry; a bound or a figure not measurable is a dict: FIGURE_FORMS),
    ``curves`` label -> its curves (``responses``: every frequency response,
    :class:`Response`, measured and the linear model's; ``loop``: the hysteresis loop), and
    what ran."""

    scenario: Scenario
    battery: Battery
    figures: dict[str, dict]
    curves: dict[str, dict]
    meta: dict

    def datasheet(self) -> dict:
        """What DIR/datasheet.json holds: the sets side by side, the definitions, the forms a
        figure takes where it is not a number (FIGURE_FORMS: a bound, or not measurable), the
        battery, what the output is, and each set's linear model (what it is, or why there is
        none)."""
        described = ("output", "linear_model")
        return {
            "scenario": self.scenario.name,
            "sets": self.figures,
            "definitions": DEFINITIONS,
            "figure_forms": FIGURE_FORMS,
            "battery": asdict(self.battery),
            "output": self.meta["output"],
            "linear_model": self.meta["linear_model"],
            "frequency_response": "frequency_response.csv",
            "meta": {k: v for k, v in self.meta.items() if k not in described},
        }

    def frequency_response(
        self,
        label: str,
        input: str = "position_command",
        output: str = "position",
        amplitude: str | None = None,
        linear: bool = False,
    ) -> control.FrequencyResponseData:
        """One set's frequency response as python-control data (omega in rad/s).

        Parameters
        ----------
        label : the controller set.
        input : "position_command" (m) or "rod_force_N" (N, positive opposing extension).
        output : "position" (the controlled output, m), "motor_speed_rad_s" or "iq_A".
        amplitude : for the command, "small" (default) or "large"; the rod force has one.
        linear : the linear model's response at the same frequencies instead of the
            measured one.

        Raises
        ------
        InputError : a name out of its range, or a linear model the set has none of.
        """
        choices = (("label", label, self.curves), ("input", input, INPUTS))
        for what, value, allowed in (*choices, ("output", output, OUTPUTS)):
            choice(f"frequency_response: {what}", value, allowed)
        sizes = ("small", "large") if input == "position_command" else ()
        if amplitude is not None and (not isinstance(amplitude, str) or amplitude not in sizes):
            allowed = f"one of {', '.join(sizes)}" if sizes else "None (the rod force has one)"
            raise InputError(
                f"frequency_response: amplitude for {input} must be {allowed}, got {amplitude!r}"
            )
        linear = flag("frequency_response: linear", linear)
        responses = self.curves[label]["responses"]
        if linear and not any(r.source == "linear model" for r in responses):
            raise InputError(f"{label} has no linear model: {self.meta['linear_model'][label]}")
        excitation = "model" if linear else amplitude or ("small" if sizes else "force")
        chosen = response_of(self.curves[label], input, excitation, output)
        return control.frd(
            chosen.h,
            2 * np.pi * chosen.frequencies_Hz,
            inputs=[input],
            outputs=[output],
            name=f"{self.scenario.name}-{label}-{chosen.source}",
        )

    def save(self, folder=None, force: bool = False):
        """Write datasheet.json, report.html and the figures into ``folder`` (default a fresh
        runs/acceptance/SCENARIO-TIME), atomically and never over anything emasim did not
        write; return where."""
        from ..analysis.datasheet import write_datasheet
        from ..naming import RUNS_ROOT, fresh_folder
        from ..output import write_folder

        unique = folder is None
        if unique:
            folder = fresh_folder(RUNS_ROOT / "acceptance", self.scenario.name)
        return write_folder(
            folder,
            lambda tmp: write_datasheet(self, tmp),
            force=force,
            unique=unique,
            kind="acceptance",
        )


def output_description(scenario: Scenario) -> str:
    feedback = scenario.loop.position_feedback
    if feedback == "rudder":
        return "the rudder angle through the rigid kinematics, in rod mm (rudder feedback)"
    return f"the rod position ({feedback} feedback)"


def plan_battery(variant: Scenario, battery: Battery) -> list[tuple[tuple, Job]]:
    """(point, job) of every run of one controller set: the point names what the run measures
    (("small", f), ("triangle",), ...)."""
    drive = Drive.of(variant)
    small, large = (
        battery.small_amplitude * drive.stroke_m,
        battery.large_amplitude * drive.stroke_m,
    )
    force = battery.dynamic_force * drive.stall_force_N
    if battery.excitation == "chirp":
        jobs = [
            (("chirp", "small"), chirp_job(variant, drive, battery, small)),
            (("chirp", "large"), chirp_job(variant, drive, battery, large)),
            (("chirp", "stiffness"), chirp_job(variant, drive, battery, 0.0, force_N=force)),
        ]
    else:
        jobs = [
            (("small", f), sine_job(variant, drive, battery, f, small))
            for f in battery.frequencies_Hz
        ]
        jobs += [
            (("large", f), sine_job(variant, drive, battery, f, large))
            for f in battery.frequencies_Hz
        ]
        jobs += [
            (("stiffness", f), sine_job(variant, drive, battery, f, 0.0, force_N=force))
            for f in battery.stiffness_frequencies_Hz
        ]
    if battery.excitation == "chirp" or battery.cycle_frequency_Hz not in battery.frequencies_Hz:
        jobs.append(
            (
                ("cycle", battery.cycle_frequency_Hz),
                sine_job(variant, drive, battery, battery.cycle_frequency_Hz, large),
            )
        )
    jobs += [
        (("triangle",), triangle_job(variant, drive, battery)),
        (("load_step",), load_step_job(variant, drive, battery)),
        (("no_load",), rate_job(variant, drive, battery, 0.0)),
        (("rated",), rate_job(variant, drive, battery, drive.rated_load_N)),
        (("stall",), stall_job(variant, drive, battery)),
    ]
    return jobs


def check_acceptance(
    scenario: Scenario, labels: list[str] | None = None, battery: "Battery | None" = None
) -> None:
    """Every rule of the battery on ``scenario``, checked before anything is compiled or run;
    InputError names the first. The battery runs the coupled plant in the compiled loop and
    records what it reads: a co-simulation (``solver.communication_step_s``, an FMU mechanism)
    and ``solver.record_signals`` are refused, not ignored. With ``battery``, its frequencies
    must lie below the Nyquist frequency of each set's recording (:func:`check_nyquist`)."""
    solver = scenario.solver
    if solver.mechanism_fmu is not None:
        raise InputError(
            "solver.mechanism_fmu: acceptance runs the built-in coupled plant, not an FMU; "
            "remove solver.mechanism_fmu and solver.communication_step_s"
        )
    if solver.communication_step_s is not None:
        raise InputError(
            "solver.communication_step_s: acceptance runs the coupled plant; "
            "remove solver.communication_step_s"
        )
    if solver.record_signals is not None:
        raise InputError(
            "solver.record_signals: acceptance records what its battery reads and writes no "
            "traces; remove solver.record_signals"
        )
    if scenario.reference.loop != "position":
        raise InputError(
            f"acceptance: {scenario.name} is a speed-loop scenario; the battery needs a position "
            "loop (a position_mm or rudder_deg reference)"
        )
    variants = dict(scenario.variants())
    unknown = [label for label in labels or () if label not in variants]
    if unknown:
        raise InputError(
            f"--label: {unknown[0]!r} is no controller set of {scenario.name}; "
            f"choose from: {', '.join(variants)}"
        )
    if battery is not None:
        for label in labels or variants:
            check_nyquist(variants[label], battery)


def check_nyquist(variant: Scenario, battery: "Battery") -> None:
    """InputError, one line, where a frequency the battery reads (a chirp: its band, up to
    CHIRP_MARGIN beyond them) is not below the Nyquist frequency of ``variant``'s recording,
    the battery's samples (solver.record_period_s, never shorter than the control period)."""
    period = variant.solver.record_period_s
    nyquist = 0.5 / period
    swept = battery.excitation == "chirp"
    for name in ("frequencies_Hz", "stiffness_frequencies_Hz", "cycle_frequency_Hz"):
        value = getattr(battery, name)
        highest = max(value) if isinstance(value, tuple) else value
        margin = CHIRP_MARGIN if swept and isinstance(value, tuple) else 1.0
        if highest * margin >= nyquist:
            beyond = f", and the chirp sweeps {margin:.3g} times higher" if margin > 1 else ""
            raise InputError(
                f"Battery: {name} reaches {highest:g} Hz{beyond}: give frequencies below "
                f"{nyquist / margin:.4g} Hz, as {variant.name} records every {period:g} s "
                f"(solver.record_period_s: its Nyquist frequency is {nyquist:g} Hz)"
            )


def battery_store(scenario: Scenario, chosen: list[str], battery: "Battery"):
    """The job store of the battery's runs for the ``chosen`` controller sets (each tagged
    with what measures it and its point), under ``runs/acceptance/``, named by what it holds
    (emasim.experiments.store.keyed)."""
    variants = dict(scenario.variants())
    jobs = []
    for label in chosen:
        for point, job in plan_battery(variants[label], battery):
            run_id = slug("-".join(map(str, [label, *point])))
            jobs.append(Job(job.scenario, label, {RUN_ID: run_id, **job.tags, **point_tags(point)}))
    record = {"acceptance": {"scenario": scenario.name, "labels": chosen}}
    record["battery"] = json.loads(json_text(asdict(battery)))
    return keyed(STORE_ROOT, jobs, record, measure=partial(measure_point, battery))


def run_acceptance(
    scenario: Scenario,
    labels: list[str] | None = None,
    battery: Battery | None = None,
    client: "Client | None" = None,
    progress: Callable[[int, int], None] | None = None,
) -> Acceptance:
    """Run the battery for each controller set of ``scenario`` (or those named in ``labels``)
    in parallel on its job store (:func:`battery_store`); ``progress(done, total)`` after
    each run. Every argument is checked first (InputError, one line naming it)."""
    if not isinstance(scenario, Scenario):
        raise InputError(
            f"run_acceptance: scenario must be a Scenario (emasim.scenarios.loader."
            f"load_scenario), got {scenario!r}"
        )
    labels = None if labels is None else strings("run_acceptance: labels", labels)
    if battery is not None and not isinstance(battery, Battery):
        raise InputError(f"run_acceptance: battery must be a Battery or None, got {battery!r}")
    client_or_none("run_acceptance: client", client)
    function_or_none("run_acceptance: progress", progress, "a function (done, total)")
    battery = battery or Battery()
    check_acceptance(scenario, labels, battery)
    variants = dict(scenario.variants())
    chosen = list(labels or variants)
    store = battery_store(scenario, chosen, battery)
    start = time.perf_counter()
    rows = store.run(client, progress=progress)
    wall = time.perf_counter() - start
    store.require_ok(rows)
    values = [decoded(json.loads(store.read(job, MEASURED_FILE))) for job in store.jobs]
    jobs = store.jobs
    figures, curves, linear = {}, {}, {}
    for label in chosen:
        measured = {
            point_of(job): value
            for job, value in zip(jobs, values, strict=True)
            if job.label == label
        }
        figures[label], curves[label] = summarize(measured, Drive.of(variants[label]), battery)
        models, linear[label] = linear_responses(variants[label], battery)
        curves[label]["responses"] += models
    from .runs import meta_of

    meta = meta_of(scenario, wall)
    meta.update(
        runs=len(jobs),
        simulated_s=sum(job.scenario.duration_s for job in jobs),
        output=output_description(scenario),
        linear_model=linear,
    )
    return Acceptance(scenario, battery, figures, curves, meta)


LINEAR_MODEL = (
    "linearize: plays closed, friction dropped, about the battery's rest state (mid stroke, "
    "standing loads on, after settle_s)"
)


def linear_responses(variant: Scenario, battery: Battery) -> tuple[list[Response], str]:
    """The linearised loop's responses (emasim.linearize, LINEAR_MODEL) of every output from
    the command and from the rod force at the battery's frequencies, and a line saying what
    they are; none, and the reason, where the loop has no linear model or the model's position
    is not the battery's (a loop closed on the motor encoder: the battery reads the rod). The
    operating point is the state every run of the battery starts its excitation from: at rest
    at mid stroke after settle_s, the standing loads (a load motor's preload) on."""
    if variant.loop.position_feedback == "motor":
        return [], "none: the loop closes on the motor encoder, the battery reads the rod"
    rest = battery_scenario(variant, battery.settle_s, [{"type": "constant", "value": 0.0}])
    excitations = (
        ("reference", "position_command", battery.frequencies_Hz),
        ("rod_force_N", "rod_force_N", battery.stiffness_frequencies_Hz),
    )
    out = []
    try:
        for port, name, frequencies in excitations:
            f = np.array(frequencies)
            for output, (_, reading) in OUTPUTS.items():
                model = linearize(rest, at_s=battery.settle_s, input=port, output=reading)
                h = control.frequency_response(model, 2 * np.pi * f).complex.ravel()
                out.append(Response(name, "model", None, output, f, h, "linear model"))
    except InputError as err:
        return [], f"none: {err}"
    return out, LINEAR_MODEL


def response_of(curves: dict, input: str, excitation: str, output="position") -> Response:
    """One set's response (its curves: ``summarize``) to ``input`` at ``excitation`` ("small",
    "large", "force", or "model": the linear model's), on ``output``."""
    (found,) = [
        r
        for r in curves["responses"]
        if (r.input, r.excitation, r.output) == (input, excitation, output)
    ]
    return found


def spread_sweeps(measured: dict) -> dict:
    """The chirps' responses, each frequency under the tag of its stepped sine (size, f),
    so that the figures read them alike."""
    out = dict(measured)
    for tag, m in measured.items():
        if tag[0] == "chirp":
            for k, f in enumerate(m["frequencies_Hz"]):
                responses = {name: h[k] for name, h in m["responses"].items()}
                out[(tag[1], float(f))] = {"responses": responses}
    return out


def summarize(measured: dict, drive: Drive, battery: Battery) -> tuple[dict, dict]:
    """The datasheet's figures (DEFINITIONS) and the curves of one set's measurements."""
    measured = spread_sweeps(measured)
    curves = {"responses": []}
    figures = {
        "small_amplitude_mm": battery.small_amplitude * drive.stroke_m / MM,
        "large_amplitude_mm": battery.large_amplitude * drive.stroke_m / MM,
    }
    command, force = drive.stroke_m, drive.stall_force_N
    excitations = (  # (the runs' tag, the response's input and excitation, f, peak)
        ("small", "position_command", "small", battery.small_amplitude * command),
        ("large", "position_command", "large", battery.large_amplitude * command),
        ("stiffness", "rod_force_N", "force", battery.dynamic_force * force),
    )
    for tag, name, excitation, amplitude in excitations:
        f = np.array(
            battery.stiffness_frequencies_Hz if tag == "stiffness" else battery.frequencies_Hz
        )
        for output in OUTPUTS:
            h = np.array([measured[(tag, x)]["responses"][output] for x in f])
            curves["responses"].append(
                Response(name, excitation, amplitude, output, f, h, battery.excitation)
            )
    for size in ("small", "large"):
        response = response_of(curves, "position_command", size)
        bode = band_figures(response.frequencies_Hz, response.h)
        figures[f"bandwidth_{size}_Hz"] = bode["bandwidth_Hz"]
        figures[f"phase_45_{size}_Hz"] = bode["phase_45_Hz"]
        figures[f"phase_90_{size}_Hz"] = bode["phase_90_Hz"]
        figures[f"peak_gain_{size}_dB"] = bode["peak_gain_dB"]
    triangle = measured[("triangle",)]
    curves["loop"] = triangle["loop"]
    amplitude = battery.triangle_amplitude * drive.stroke_m
    figures.update(triangle_figures(triangle, amplitude, battery.detection_mm * MM))
    step = measured[("load_step",)]
    figures["static_stiffness_N_per_mm"] = step["static_stiffness_N_per_m"] * MM
    figures["static_stiffness_lower_bound"] = step["static_stiffness_lower_bound"]
    figures["load_step_stiffness_N_per_mm"] = step["peak_stiffness_N_per_m"] * MM
    compliance = response_of(curves, "rod_force_N", "force")
    f, stiffness = compliance.frequencies_Hz, MM / np.abs(compliance.h)
    weakest = int(np.argmin(stiffness))
    figures["dynamic_stiffness_min_N_per_mm"] = float(stiffness[weakest])
    figures["dynamic_stiffness_min_Hz"] = float(f[weakest])
    for key, tag in (("no_load_rate_mm_s", "no_load"), ("rate_at_rated_load_mm_s", "rated")):
        rate = measured[(tag,)]["rate_m_s"]
        figures[key] = rate / MM if rate is not None else None
        if tag == "no_load":
            figures["no_load_peak_speed_rpm"] = measured[(tag,)]["peak_speed_rad_s"] * RPM_PER_RAD_S
            figures["max_speed_rpm"] = drive.max_speed_rpm
    figures["rated_load_N"] = drive.rated_load_N
    figures["stall_force_N"] = measured[("stall",)]["stall_force_N"]
    figures["theoretical_stall_force_N"] = drive.stall_force_N
    cycle = (
        measured.get(("cycle", battery.cycle_frequency_Hz))
        or measured[("large", battery.cycle_frequency_Hz)]
    )
    figures["rms_current_A"] = cycle["rms_current_A"]
    figures["energy_per_cycle_J"] = cycle["energy_per_cycle_J"]
    return figures, curves
