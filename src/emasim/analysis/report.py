"""The metrics a run reports, chosen by the experiment it is (SPEC section 4 definitions).

The kind follows from the scenario's reference: a motor speed, a rod position or a rudder
angle, as a step or a sine. Every window and band is stated here, once:

* step of speed (rpm) or rod position (mm): rise time 10-90 %, 2 % settling time, overshoot,
  dead-zone time (position: until the rod has moved 10 um), on the interval before the load
  step; steady-state error mean/std/RMS over the last 20 % of that interval; the load
  response (below) from the load step to the end of the run; chattering of the current
  command (half peak-to-peak, dominant frequency; frequency 0 below 1 uA) over the last 20 %
  of the run;
* sine of speed: max |error| and phase lag (fitted sine) over the whole run, and the load
  response (below) from the load step to the reference's next reversal (its next sign
  change, or the end of the run): at a reversal the friction changes sign and disturbs the
  loop by itself, which is not the load's doing;
* the load response, in the unit of the output: the dip (the signed output-minus-set-point
  error of largest magnitude after the load step); the recovery time, from the load step
  until the error stays within the recovery band, ``max(RECOVERY_FRACTION * |dip|, floor)``
  with RECOVERY_FRACTION = 10 % of the dip and the floor RECOVERY_FLOOR_RPM = 1 rpm or
  RECOVERY_FLOOR_MM = 10 um (nan when the error is outside it at the end of the interval: a
  loop that stays off by more than a tenth of its dip has not recovered); the band itself
  (load_recovery_band); and the steady error under load, set point minus output, mean and
  RMS over the last STEADY_FRACTION of the interval (load_steady_error_mean/rms). A band
  sized to the disturbance reads the same on a 1000 rpm step as on a 120 mm one, and a
  tenth of the dip is what a plot scaled to the dip shows as "back"; the floor keeps a dip
  below the resolution of a speed or position sensor from asking for a return finer than
  that resolution;
* the bench's figures (rudder step and sine) are computed on what the bench measures, the
  rudder encoder's reading and its rate differenced over RATE_WINDOW_S (differenced_rate),
  with the same figure of the true rudder angle beside each, keyed true_<figure>;
* rudder step (the bench, tables 2-5), in deg and deg/s: rise time 10-90 %, settling time
  into a 5 % band (the paper's PID oscillates +-0.2 deg about 4.72 deg, over 4 %), and over the
  steady window from BENCH_STEADY_S to the end: chattering of the rudder angle, error
  mean/std/RMS, velocity fluctuation (half peak-to-peak about its trend) and velocity error
  statistics; the peak rudder velocity over the run;
* rudder sine (tables 6-7): max tracking error and phase lag after the first BENCH_STEADY_S,
  whether the rudder first moves against the command (below -REVERSE_DEG in the first second)
  and how far (reverse_motion_deg, 0 when it never goes below 0),
  the peak velocity in the first second, the velocity fluctuation (half peak-to-peak of the
  velocity about its best-fitting sine) after BENCH_STEADY_S;
* every steady rate figure of the bench (fluctuation, rate error), true and measured, leaves
  out the last RATE_WINDOW_S / 2 of the run (:func:`centred`), where the differenced rate
  is one-sided.

Every run also reports the time the drive spent at each of its limits (current, voltage,
speed: the limit_flags the engine records at each recorded row, times the recording period)
and, on a plant with end stops, the time in contact with the rod's and the rudder's stops and
the largest stop force; :func:`run_warnings` turns a stop contact into a warning line, and
:func:`limits_crossed` finds the physical limits it went past (motor speed, current, and the
rod's stroke on a plant without stops), each a warning line (:func:`limit_warnings`); and
``tuning_cost``, the cost every controller set was tuned for (:func:`tuning_cost`).
"""

import math

import numpy as np
from pydantic import TypeAdapter

from ..interface import LIMIT_CURRENT, LIMIT_SPEED, LIMIT_VOLTAGE
from ..signals import Term, encode, signal_values
from . import metrics as m
from . import passes

RPM_PER_RAD_S = 30.0 / math.pi
DEG_PER_RAD = 180.0 / math.pi
STEADY_FRACTION = 0.2  # steady-state windows: the last 20 % before the load step / the end
DEAD_ZONE_MM = 0.01  # the output has "moved" once it is 10 um from where it started
BENCH_STEADY_S = 2.0  # bench experiments: steady-state statistics from this time on
BENCH_SETTLING_BAND = 0.05
REVERSE_DEG = 0.01
RATE_WINDOW_S = 0.1  # the bench's rudder rate: the encoder reading differenced over this
CHATTER_WEIGHT = 2e-3  # of the tuning cost: the price of current-command chattering
CHECK_TOLERANCE = 0.01  # a tuned optimum with a neighbour better by more than this: not converged
COST_FORMULA = (  # the tuning cost in words, for the tuned file's record and the report
    f"IAE(e)/(T*R) + RMS_s(e)/R + A_s(e)/R + {CHATTER_WEIGHT:g} * TV(iq*)/I_max, e = the "
    "reference - the loop's reading, s = the steady window (emasim.analysis.report.tuning_cost)"
)
RECOVERY_FRACTION = 0.1  # load recovery: back within 10 % of the load step's dip ...
RECOVERY_FLOOR_RPM = 1.0  # ... or within this absolute band, whichever is wider (speed) ...
RECOVERY_FLOOR_MM = 0.01  # ... (rod position: 10 um, the DEAD_ZONE_MM resolution)
# every trace column a run's figure reads (emasim.analysis.plots: plot_result and
# plot_comparison, the rudder's command through rudder_traces): a spooled trace's figure reads
# only these (Result.drawn)
FIGURE_COLUMNS = (
    "t_s",
    "motor_speed_rad_s",
    "speed_ref_rad_s",
    "iq_A",
    "iq_ref_A",
    "torque_Nm",
    "friction_torque_Nm",
    "load_torque_Nm",
    "actuator_position_m",
    "actuator_velocity_m_s",
    "position_ref_m",
    "rudder_angle_rad",
    "linkage_rudder_rate_rad_s",
)
# every trace column the metrics and the plots read: a run that records chosen signals
# (solver.record_signals) records these too (the linkage's only with a linkage)
ANALYSIS_COLUMNS = (
    *FIGURE_COLUMNS,
    "measured_rudder_rad",
    "measured_position_m",
    "measured_speed_rad_s",
    "limit_flags",
    "end_stop_force_N",
    "rudder_stop_torque_Nm",
)
LIMITS = (("current", LIMIT_CURRENT), ("voltage", LIMIT_VOLTAGE), ("speed", LIMIT_SPEED))


def undefined_metrics(metrics: dict) -> dict[str, str]:
    """Why each non-finite metric is undefined (saved as null in metrics.json, this in meta)."""
    reasons = {}
    for key, value in metrics.items():
        if isinstance(value, float) and not math.isfinite(value):
            reasons[key] = (
                "never reached within the run (its band or level was not entered by the end)"
                if key.endswith("_time_s")
                else "not defined for this run (a window without data, or a level never reached)"
            )
    return reasons


def experiment_of(result):
    """The experiment the run made (emasim.sim.result.Experiment), from its description."""
    description = result.description
    if description is None or description.experiment is None:
        raise ValueError("the run's description holds no experiment (a bare Setup's run)")
    return description.experiment


TERM = TypeAdapter(Term)  # a reference term's validator, built once (a few ms each time)


def rudder_traces(result, measured: bool = False) -> tuple[np.ndarray, ...]:
    """Rudder angle, its reference (deg), rudder rate and reference rate (deg/s).

    The reference is the scenario's rudder command itself. The true angle is the rudder's;
    its rate the rudder shaft's (with the linkage) or the rod velocity through the lumped arm.
    ``measured``: what the bench measures instead, the rudder encoder's reading
    (``measured_rudder_rad``) and its differenced rate (:func:`differenced_rate`).
    """
    t = result.t
    experiment = experiment_of(result)
    reference, reference_rate = command_traces(experiment, t)
    if measured:
        angle = DEG_PER_RAD * result["measured_rudder_rad"]
        return angle, reference, differenced_rate(t, angle), reference_rate
    angle = DEG_PER_RAD * result["rudder_angle_rad"]
    if experiment.rudder_arm_m is None:  # the linkage: the rudder's rate is a state
        rate = DEG_PER_RAD * result["linkage_rudder_rate_rad_s"]
    else:
        rate = DEG_PER_RAD * result["actuator_velocity_m_s"] / experiment.rudder_arm_m
    return angle, reference, rate, reference_rate


def command_traces(experiment, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The experiment's command at times ``t`` and its rate (np.gradient), in its unit."""
    command = encode([TERM.validate_python(term) for term in experiment.reference])
    reference = signal_values(command, t)
    return reference, np.gradient(reference, t)


def differenced_rate(t: np.ndarray, reading: np.ndarray) -> np.ndarray:
    """The rate a bench computes from an encoder reading: its change over RATE_WINDOW_S,
    centred on each row, (y(t + T/2) - y(t - T/2)) / T (one-sided within T/2 of the ends,
    which no rate figure reads: :func:`centred`).

    An encoder of quantum q reads rates in steps of q / T: with the rudder's TTL encoder
    (0.088 deg) and T = 0.1 s, 0.88 deg/s, finer than the paper's smallest PID rate figures
    (1.3 deg/s on the step, 2 deg/s on the sine), which its bench resolved.
    """
    if t.size < 2:
        return np.zeros_like(reading)
    half = max(1, round(0.5 * RATE_WINDOW_S / (t[1] - t[0])))
    rows = np.arange(t.size)
    ahead, behind = np.minimum(rows + half, t.size - 1), np.maximum(rows - half, 0)
    return (reading[ahead] - reading[behind]) / (t[ahead] - t[behind])


def centred(t: np.ndarray, window: tuple[float, float]) -> tuple[float, float]:
    """``window`` less the first and last RATE_WINDOW_S / 2 of the run: where the differenced
    rate (:func:`differenced_rate`) is centred. Every steady rate figure of the bench, true
    and measured alike, reads this window: a one-sided difference at the end divides the last
    counts' change by as little as half the window, up to twice the rate, and made a third of
    the hybrid's step rate fluctuation. A window with no centred row (a run shorter than the
    difference's window) is kept whole."""
    half = 0.5 * RATE_WINDOW_S
    start, end = max(window[0], t[0] + half), min(window[1], t[-1] - half)
    return (start, end) if start < end else window  # no centred rate: a run shorter than T


def steady_window(t_end: float) -> tuple[float, float]:
    """Bench steady-state window: from BENCH_STEADY_S (or half the run, if shorter) to the run's
    end ``t_end`` (s)."""
    return (min(BENCH_STEADY_S, 0.5 * t_end), t_end)


def run_metrics(result) -> dict:
    """Metrics of a run, keyed with their unit (see the module docstring for definitions)."""
    experiment = experiment_of(result)
    quantity, shape = experiment.quantity, experiment.shape
    if quantity == "rudder":
        out = bench_sine_metrics(result) if shape == "sine" else bench_step_metrics(result)
    elif shape == "sine":
        out = sine_metrics(result, quantity)
    else:
        out = step_metrics(result, quantity)
    cost = tuning_cost(result, experiment.max_current_A)
    return {**out, **limit_metrics(result), "tuning_cost": cost}


def tuning_cost(result, max_current_A: float) -> float:
    """The cost every controller set is tuned for (emasim.tuning), dimensionless:

        J = IAE(e) / (T R) + RMS_s(e) / R + A_s(e) / R + CHATTER_WEIGHT * TV(iq*) / I_max

    on the controlled output as the loop measures it, against its own reference: the position
    loop's reading (``measured_position_m``: the rod sensor, the motor encoder as K theta, or the
    rudder encoder through the rigid kinematics) against ``position_ref_m``, or the speed
    reading against the speed command; e = reference - reading, T the duration, R the largest
    |reference|. RMS_s and A_s (half peak-to-peak) are over the steady window the headline
    figures judge (:func:`cost_window`), the IAE over the whole run (the transient); TV(iq*) is
    the total variation per second of the current command (A/s) and I_max the drive's current
    limit (A)."""
    return weighted_cost(*tuning_terms(result, max_current_A))


def weighted_cost(tracking: float, chatter: float) -> float:
    """The tuning cost from its two terms (:func:`tuning_terms`)."""
    return tracking + CHATTER_WEIGHT * chatter


def tuning_terms(result, max_current_A: float) -> tuple[float, float]:
    """The two terms of :func:`tuning_cost`, before the weight: tracking, IAE(e) / (T R) +
    RMS_s(e) / R + A_s(e) / R (dimensionless), and chattering TV(iq*) / I_max (1/s). One pass
    over the trace's blocks (Result.blocks): the trapezoids and differences sum across them,
    the window's extremes and R are the blocks' extremes."""
    if result.outer_loop == "position":
        names = ("position_ref_m", "measured_position_m")
    else:
        names = ("speed_ref_rad_s", "measured_speed_rad_s")
    window = cost_window(result)
    steady = passes.Interval(*window)
    scale, iae, squares, variation = 0.0, 0.0, 0.0, 0.0
    low, high, last = np.inf, -np.inf, None
    for block in result.blocks("t_s", *names, "iq_ref_A"):
        t, reference, output, iq_ref = block.columns
        error = reference - output
        for name, values in (("error", error), ("iq_ref_A", iq_ref)):
            passes.finite(name, values)
        scale = max(scale, float(np.max(np.abs(reference))))
        iae += np.trapezoid(np.abs(error), t)
        variation += np.sum(np.abs(np.diff(iq_ref)))
        cut = steady.piece(t, block.own_from)
        if cut is not None:  # the window's rows, with the seam row when the window holds it
            tw, ew = t[cut[0]], error[cut[0]]
            squares += np.trapezoid(ew**2, tw)
            low, high = min(low, np.min(ew)), max(high, np.max(ew))
            last = tw[-1]
    if steady.rows < 2:
        raise ValueError(
            f"window {window!r} selects {steady.rows} sample(s); at least 2 are needed"
        )
    first = steady.first_t
    scale = max(scale, 1e-12)
    t0, t1 = result.span
    tracking = (
        iae / ((t1 - t0) * scale)
        + float(np.sqrt(squares / (last - first))) / scale
        + 0.5 * float(high - low) / scale
    )
    chatter = float(variation / (t1 - t0)) / max_current_A
    return tracking, chatter


def cost_window(result) -> tuple[float, float]:
    """The steady window of the tuning cost: the bench's (:func:`steady_window`) for a rudder
    command, else the last STEADY_FRACTION of the run before its load step, as the step
    metrics' steady-state error."""
    if experiment_of(result).quantity == "rudder":
        return steady_window(result.span[1])
    t_end = _load_window(result)[1]
    return (t_end - STEADY_FRACTION * (t_end - result.span[0]), t_end - 1e-12)


def limit_metrics(result) -> dict:
    """Time (s) the drive spent at each limit and, with end stops, in contact with them: counts
    of recorded rows times the recording period, over the trace's blocks (Result.blocks)."""
    flags, stops = "limit_flags" in result.columns, "end_stop_force_N" in result.columns
    names = (
        ("t_s",)
        + (("limit_flags",) if flags else ())
        + (("end_stop_force_N", "rudder_stop_torque_Nm") if stops else ())
    )
    saturated = dict.fromkeys((name for name, _ in LIMITS), 0)
    force_rows = torque_rows = 0
    peak_force = peak_torque = -np.inf
    dt = 0.0  # the recording period, the time each recorded row stands for: the first two rows'
    for block in result.blocks(*names):
        if not dt and block.columns[0].size > 1:
            dt = float(block.columns[0][1] - block.columns[0][0])
        t, *columns = (column[block.own_from :] for column in block.columns)
        if flags:
            bits = np.nan_to_num(columns.pop(0)).astype(np.int64)
            for name, bit in LIMITS:
                saturated[name] += np.count_nonzero(bits & bit)
        if stops:
            force, torque = np.abs(columns[0]), np.abs(columns[1])
            force_rows += np.count_nonzero(force > 0.0)
            torque_rows += np.count_nonzero(torque > 0.0)
            peak_force = np.max([peak_force, force.max()])  # NaN stays NaN
            peak_torque = np.max([peak_torque, torque.max()])
    out = {}
    if flags:
        for name, _ in LIMITS:
            out[f"{name}_saturation_time_s"] = float(saturated[name]) * dt
    if stops:
        out["end_stop_contact_time_s"] = float(force_rows) * dt
        out["end_stop_peak_force_N"] = float(peak_force)
        out["rudder_stop_contact_time_s"] = float(torque_rows) * dt
        out["rudder_stop_peak_torque_Nm"] = float(peak_torque)
    return out


def run_warnings(metrics: dict) -> list[str]:
    """One line for each stop a run touched (empty when it stayed inside its travel)."""
    lines = []
    for what, prefix, peak, unit in (
        ("the rod's end stops", "end_stop", "end_stop_peak_force_N", "N"),
        ("the rudder's travel stops", "rudder_stop", "rudder_stop_peak_torque_Nm", "N m"),
    ):
        contact = metrics.get(f"{prefix}_contact_time_s", 0.0)
        if contact > 0.0:
            lines.append(
                f"the run touched {what} for {contact:.4g} s (peak {metrics[peak]:.4g} {unit}): "
                "the command or an overshoot leaves the travel"
            )
    return lines


# beyond a limit by more than 0.2 %: more than the integration adds where the drive holds it
# (its current chopping, checked once a sub-step, holds the current within 0.10 % of its limit
# at the shipped three sub-steps a tick, 0.03 % at ten: tests/test_limits.py), not a choice
LIMIT_TOLERANCE = 2e-3


def limits_crossed(result) -> dict:
    """Each physical limit the run went past, name -> {``peak``, ``peak_s`` (when), ``limit``
    (there), ``unit``, ``first_s`` (when it first went past), ``what``}:

    * ``motor_speed``: |motor speed| above the drive's max_speed_rpm. The drive holds every
      speed command within it, so a crossing is the load or an overshoot driving the motor
      past it (a back-driven overspeed is physical; the drive would trip);
    * ``current``: |iq| above the current limit in force (``current_limit_A``: max_current_A,
      or the rated limit). Every current command is held within it and the inverter holds
      |i_dq| at max_current_A (emasim.plant.elements.motor.inverter_current_rates), so a
      crossing is a back-EMF beyond what the bus can oppose driving the current past (physical: the
      inverter's diodes conduct; emasim models no trip, so it reports it), or the current
      loop's overshoot past a rated limit below max_current_A;
    * ``rod_stroke``: on a plant without end stops, the rod beyond half its stroke from mid
      stroke (a real actuator would have hit its stops; with stops, :func:`run_warnings`
      reports the contact).
    """
    experiment = experiment_of(result)
    checks = []  # (name, column, scale, limit: a number or a column, unit, what)
    if "motor_speed_rad_s" in result.columns:
        speed_limit = experiment.max_speed_rpm
        checks.append(("motor_speed", "motor_speed_rad_s", RPM_PER_RAD_S, speed_limit, "rpm",
                       "the motor's speed"))  # fmt: skip
    if "iq_A" in result.columns and "current_limit_A" in result.columns:
        checks.append(("current", "iq_A", 1.0, "current_limit_A", "A", "the q-axis current"))
    if experiment.stroke_mm is not None and "actuator_position_m" in result.columns:
        half = 0.5 * experiment.stroke_mm
        checks.append(("rod_stroke", "actuator_position_m", 1e3, half, "mm",
                       "the rod's travel from mid stroke"))  # fmt: skip
    columns = ["t_s", *dict.fromkeys(c for check in checks for c in (check[1], check[3])
                                     if isinstance(c, str))]  # fmt: skip
    first, peak = {}, {}  # name -> when first past it; -> (the largest value, when, its limit)
    for block in result.blocks(*columns):
        read = dict(zip(columns, (c[block.own_from :] for c in block.columns), strict=True))
        t = read["t_s"]
        for name, column, scale, given, _, _ in checks:
            value = np.abs(read[column]) * scale
            limit = read[given] if isinstance(given, str) else given
            over = np.flatnonzero(value > np.asarray(limit) * (1.0 + LIMIT_TOLERANCE))
            if over.size:
                first.setdefault(name, float(t[over[0]]))
                at = int(over[np.argmax(value[over])])
                if name not in peak or value[at] > peak[name][0]:
                    limit_there = np.broadcast_to(limit, value.shape)[at]
                    peak[name] = (float(value[at]), float(t[at]), float(limit_there))
    return {
        name: dict(zip(("peak", "peak_s", "limit"), peak[name], strict=True))
        | {"unit": unit, "first_s": first[name], "what": what}
        for name, _, _, _, unit, what in checks
        if name in peak
    }


LIMIT_CAUSES = {
    "motor_speed": "driven past the drive's speed limit (the load, or an overshoot)",
    "current": "its commands are held within the limit and the inverter holds the current at "
    "max_current_A, so a back-EMF the bus cannot oppose drove it past (through the inverter's "
    "diodes; a real drive would trip), or, under a rated limit, the current loop overshot it",
    "rod_stroke": "the plant has no end stops; a real actuator would have hit them",
}


def limit_warnings(limits: dict) -> list[str]:
    """One line for each limit of :func:`limits_crossed`."""
    return [
        f"{entry['what']} reached {entry['peak']:.4g} {entry['unit']} at "
        f"{entry['peak_s']:.4g} s, beyond its {entry['limit']:.4g} {entry['unit']} limit "
        f"(first past it at {entry['first_s']:.4g} s): {LIMIT_CAUSES[name]}"
        for name, entry in limits.items()
    ]


def _load_window(result) -> tuple[float | None, float]:
    """(load step time if inside the run, end of the interval before it)."""
    t_first, t_last = result.span
    t_load = experiment_of(result).load_step_s
    if t_load is not None and not t_first < t_load < t_last:
        t_load = None  # the load comes after the end of the run
    return t_load, (t_load if t_load is not None else t_last)


def next_reversal(t: np.ndarray, reference: np.ndarray, t_from: float) -> float:
    """Time of the last sample before the reference next changes sign after ``t_from`` (the
    end of the run when it keeps its sign, or is 0, from there on)."""
    after = np.flatnonzero(t >= t_from)
    signs = np.sign(reference[after])
    nonzero = np.flatnonzero(signs)
    if nonzero.size == 0:
        return float(t[-1])
    flipped = np.flatnonzero(signs[nonzero[0] :] == -signs[nonzero[0]])
    if flipped.size == 0:
        return float(t[-1])
    return float(t[after[nonzero[0] + flipped[0] - 1]])


def load_response(read, t_load: float, t_end: float, floor: float, unit: str) -> dict:
    """The load step's dip, recovery time and band, and the steady error under load, over
    ``[t_load, t_end]`` (see the module docstring), of ``read()``: a new iterable at each call
    of blocks (own_from, (t, output, reference)), as Result.blocks gives them; read twice."""
    window = passes.Rows(passes.Interval(t_end - STEADY_FRACTION * (t_end - t_load), t_end))
    rec = passes.load_recovery(read, t_load, t_end, floor, RECOVERY_FRACTION, window)
    if rec is None:
        return {}  # no interval to measure
    out = {
        f"load_dip_{unit}": rec.dip,
        "load_recovery_time_s": rec.recovery_time,
        f"load_recovery_band_{unit}": rec.band,
    }
    tw, ew = window.joined() or (np.empty(0), np.empty(0))
    if tw.size >= 2:
        stats = m.error_stats(tw, ew)
        mean, rms = stats.mean, stats.rms
    else:
        mean = rms = math.nan
    out[f"load_steady_error_mean_{unit}"] = mean
    out[f"load_steady_error_rms_{unit}"] = rms
    return out


STEP_SIGNALS = {  # quantity: (unit, scale from SI, output column, reference column)
    "position": ("mm", 1e3, "actuator_position_m", "position_ref_m"),
    "speed": ("rpm", RPM_PER_RAD_S, "motor_speed_rad_s", "speed_ref_rad_s"),
}


def step_metrics(result, quantity: str) -> dict:
    """Step of motor speed (rpm) or rod position (mm). In passes over the trace's blocks
    (emasim.analysis.passes): the step's figures, and the rows of the windows whose figures
    are sums (the steady errors, the current's chattering); the load response reads the rows
    from the load step on twice."""
    unit, scale, column, reference = STEP_SIGNALS[quantity]

    def read(*more):
        """(own_from, (t, output, reference, *more)) of each block, in the figures' unit."""
        for block in result.blocks("t_s", column, reference, *more):
            t, y, ref, *rest = block.columns
            yield block.own_from, (t, scale * y, scale * ref, *rest)

    t_first, t_end = result.span
    t_load, t_step_end = _load_window(result)
    initial, final = _step_ends(read(), t_step_end)
    step = passes.StepInfo(
        initial, final, t_step_end, DEAD_ZONE_MM if quantity == "position" else None
    )
    steady = passes.Rows(
        passes.Interval(t_step_end - STEADY_FRACTION * (t_step_end - t_first), t_step_end - 1e-12)
    )
    tail = passes.Rows(passes.Interval(t_end - STEADY_FRACTION * (t_end - t_first), t_end))
    for own_from, (t, y, ref, iq_ref) in read("iq_ref_A"):
        step.add(t, y, own_from)
        steady.add(t, own_from, ref - y)
        tail.add(t, own_from, iq_ref)
    info = step.info()
    out = {k: v for k, v in info.items() if k != "peak"}
    out[f"peak_{unit}"] = info["peak"]
    stats = m.error_stats(*steady.joined())
    out[f"steady_error_mean_{unit}"] = stats.mean
    out[f"steady_error_std_{unit}"] = stats.std
    out[f"steady_error_rms_{unit}"] = stats.rms
    if t_load is not None:
        floor = RECOVERY_FLOOR_MM if quantity == "position" else RECOVERY_FLOOR_RPM
        out.update(load_response(read, t_load, t_end, floor, unit))
    chat = m.chattering(*tail.joined())
    out["iq_chattering_A"] = chat.amplitude
    # below a micro-ampere the "chattering" is round-off and its frequency means nothing
    out["iq_chattering_frequency_Hz"] = chat.frequency_Hz if chat.amplitude > 1e-6 else 0.0
    return {k: float(v) for k, v in out.items()}


def _step_ends(blocks, t_step_end: float) -> tuple[float, float]:
    """The output's first value, and the reference's last before ``t_step_end``: the step's
    initial and final levels, read from ``blocks`` (own_from, (t, output, reference)) up to
    the one that reaches ``t_step_end``."""
    initial = final = None
    for _, (t, y, ref) in blocks:
        initial = y[0] if initial is None else initial
        before = int(np.searchsorted(t, t_step_end, "left"))  # its rows t < t_step_end
        final = ref[before - 1] if before else final
        if before < t.size:
            break
    return initial, final


def _sine_frequency(result) -> float:
    """The frequency (Hz) of the run's sine reference: its one sine term's."""
    return _sine_frequency_of(experiment_of(result))


def _sine_frequency_of(experiment) -> float:
    """The frequency (Hz) of the experiment's sine reference: its one sine term's."""
    frequency = experiment.sine_frequency_Hz
    if frequency is None:
        raise ValueError("a sine's metrics need a reference with one sine term")
    return frequency


# quantity -> (output column, reference column, scale to the unit, unit, floor)
SINE_SIGNALS = {
    "speed": ("motor_speed_rad_s", "speed_ref_rad_s", RPM_PER_RAD_S, "rpm", RECOVERY_FLOOR_RPM),
    "position": ("actuator_position_m", "position_ref_m", 1e3, "mm", RECOVERY_FLOOR_MM),
}


def sine_metrics(result, quantity: str = "speed") -> dict:
    """Sine of motor speed (rpm, Fig. 6) or of rod position (mm): the largest error, the phase
    lag and the gain of the fundamental, and the load response. One pass over the trace's
    blocks (Result.blocks): the fit takes them one by one (emasim.analysis.metrics.SineFit),
    and the load response reads the rows from the load step to the reference's next reversal,
    kept as the pass goes by them."""
    column, reference, scale, unit, floor = SINE_SIGNALS[quantity]
    fit = m.SineFit(_sine_frequency(result))
    t_load, _ = _load_window(result)
    window = _LoadWindow(t_load)
    for block in result.blocks("t_s", column, reference):
        t, y, ref = block.columns[0], scale * block.columns[1], scale * block.columns[2]
        own = block.own_from
        fit.add(t[own:], y[own:], ref[own:])
        window.add(t, y, ref, own)
    track = fit.tracking()
    out = {
        f"max_error_{unit}": track.max_abs_error,
        "phase_lag_deg": track.phase_lag_deg,
        "gain": track.gain,
    }
    if t_load is not None:
        t, y, ref = window.rows()
        end = next_reversal(t, ref, t_load)
        out.update(load_response(lambda: [(0, (t, y, ref))], t_load, end, floor, unit))
    return {k: float(v) for k, v in out.items()}


class _LoadWindow:
    """The rows a sine's load response reads, kept block by block as a pass goes by them: from
    the last row before the load step ``t_load`` (None: none) up to the first row where the
    reference has the sign opposite to its first nonzero sign from the load step on (its next
    reversal, :func:`next_reversal`), or to the end of the run if it keeps its sign."""

    def __init__(self, t_load: float | None):
        self.t_load, self.parts, self.sign, self.done = t_load, [], 0.0, t_load is None

    def add(self, t, y, ref, own_from: int) -> None:
        """Keep what is wanted of a block (its own rows from ``own_from`` on)."""
        if self.done or t[-1] < self.t_load:
            return
        # the first block that reaches the load step begins with the last row before it
        start = own_from if self.parts else int(np.searchsorted(t, self.t_load)) - 1
        signs = np.sign(ref[start:])
        signs[t[start:] < self.t_load] = 0.0
        if not self.sign and np.any(signs):
            self.sign = signs[np.flatnonzero(signs)[0]]
        flipped = np.flatnonzero(signs == -self.sign) if self.sign else []
        stop = start + flipped[0] + 1 if len(flipped) else t.size
        self.parts.append((t[start:stop], y[start:stop], ref[start:stop]))
        self.done = len(flipped) > 0

    def rows(self):
        """(t, y, ref) of the rows kept."""
        return (np.concatenate(part) for part in zip(*self.parts, strict=True))


def bench_step_metrics(result) -> dict:
    """Rudder step on the bench (tables 2-5), deg and deg/s: every figure on what the bench
    measures (the encoder's reading and its differenced rate), and the same figure of the
    true rudder angle beside it, keyed ``true_<figure>`` (:func:`with_true_figures`)."""
    return with_true_figures(result, _rudder_step_figures)


def bench_sine_metrics(result) -> dict:
    """Rudder sine on the bench (tables 6-7), deg and deg/s, measured and true as
    :func:`bench_step_metrics`."""
    return with_true_figures(result, _rudder_sine_figures)


TRUE_PREFIX = "true_"  # a bench figure of the true rudder angle, beside the measured one


def with_true_figures(result, figures) -> dict:
    """``figures(experiment, t, angle, reference, rate, reference_rate)`` on the measured rudder
    traces, and under TRUE_PREFIX on the true ones; the true ones alone (unprefixed) for a
    trace that lacks the encoder's reading (a result written before it was recorded)."""
    t, experiment = result.t, experiment_of(result)
    true = figures(experiment, t, *rudder_traces(result))
    if "measured_rudder_rad" not in result.columns:
        return true
    measured = figures(experiment, t, *rudder_traces(result, measured=True))
    return measured | {TRUE_PREFIX + key: value for key, value in true.items()}


def reading_figures(experiment, t: np.ndarray, reading: np.ndarray) -> dict:
    """The measured figures of a rudder experiment computed on a given rudder encoder
    ``reading`` (deg) at times ``t`` (s), its rate differenced as the bench's
    (:func:`differenced_rate`); keys as the measured figures of :func:`bench_step_metrics`
    or :func:`bench_sine_metrics`. With the command itself read through the encoder, these
    are the measurement floor: what a perfect follower scores (emasim.experiments.replicas)."""
    reference, reference_rate = command_traces(experiment, t)
    figures = _rudder_sine_figures if experiment.shape == "sine" else _rudder_step_figures
    return figures(experiment, t, reading, reference, differenced_rate(t, reading), reference_rate)


def _rudder_step_figures(experiment, t, angle, reference, rate, reference_rate) -> dict:
    final = reference[-1]
    steady = steady_window(t[-1])
    rates = centred(t, steady)
    error = m.error_stats(t, reference - angle, steady)
    rate_error = m.error_stats(t, reference_rate - rate, rates)
    chat = m.chattering(t, angle, steady)
    out = {
        "rise_time_s": m.rise_time(t, angle, initial=0.0, final=final),
        "settling_time_s": m.settling_time(
            t, angle, final=final, initial=0.0, band=BENCH_SETTLING_BAND
        ),
        "chatter_amplitude_deg": chat.amplitude,
        "chatter_frequency_Hz": chat.frequency_Hz,
        "steady_error_mean_deg": error.mean,
        "steady_error_std_deg": error.std,
        "steady_error_rms_deg": error.rms,
        "peak_velocity_deg_s": m.peak_value(t, rate),
        "velocity_fluctuation_deg_s": m.fluctuation_amplitude(t, rate, rates),
        "velocity_error_mean_deg_s": rate_error.mean,
        "velocity_error_std_deg_s": rate_error.std,
        "velocity_error_rms_deg_s": rate_error.rms,
    }
    return {k: float(v) for k, v in out.items()}


def _rudder_sine_figures(experiment, t, angle, reference, rate, reference_rate) -> dict:
    frequency = _sine_frequency_of(experiment)
    steady = steady_window(t[-1])
    track = m.sine_tracking(t, angle, reference, frequency, steady)
    start = (t[0], t[0] + 1.0)
    first_second = m.window_mask(t, start)
    out = {
        "tracking_error_deg": track.max_abs_error,
        "phase_lag_deg": track.phase_lag_deg,
        "lag_s": track.lag_s,
        "initial_reverse_motion": float(angle[first_second].min() < -REVERSE_DEG),
        "reverse_motion_deg": float(max(0.0, -angle[first_second].min())),
        "peak_velocity_deg_s": m.peak_value(t, rate, start),
        "velocity_fluctuation_deg_s": m.sine_fluctuation(t, rate, frequency, centred(t, steady)),
    }
    return {k: float(v) for k, v in out.items()}
