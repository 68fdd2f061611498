"""The metrics a run reports, chosen by the loop it closes (SPEC section 4 definitions)."""

import math

import numpy as np

from . import metrics as m

RPM_PER_RAD_S = 30.0 / math.pi
STEADY_FRACTION = 0.2  # steady-state windows: the last 20 % before the load step / the end
DEAD_ZONE_MM = 0.01  # the output has "moved" once it is 10 um from where it started


def load_step_time(scenario: dict) -> float | None:
    """Time of the first load step of a resolved scenario, or None."""
    for terms in scenario.get("load", {}).values():
        for term in terms:
            if term.get("type") == "step" and term.get("final", 0.0) != term.get("initial", 0.0):
                return float(term["time_s"])
    return None


def run_metrics(result) -> dict:
    """Metrics of a run, keys named with their unit, windows stated in the keys' docs.

    Step response (of motor speed in rpm, or rod position in mm): rise time 10-90 %, 2 %
    settling time, overshoot, dead-zone time (position: first 10 um of motion), all computed on
    the interval before the load step. Steady-state error mean/std/RMS over the last 20 % of
    that interval. Load rejection: the dip and the time to return within the 2 % band.
    Chattering of the current command (half peak-to-peak, dominant frequency) over the last
    20 % of the run.
    """
    t = result.t
    position_run = bool(np.isfinite(result["position_ref_m"]).any())
    if position_run:
        unit, y, ref = "mm", 1e3 * result["actuator_position_m"], 1e3 * result["position_ref_m"]
    else:
        unit = "rpm"
        y = RPM_PER_RAD_S * result["motor_speed_rad_s"]
        ref = RPM_PER_RAD_S * result["speed_ref_rad_s"]
    t_end = t[-1]
    t_load = load_step_time(result.scenario)
    if t_load is not None and not t[0] < t_load < t_end:
        t_load = None  # the load comes after the end of the run
    t_step_end = t_load if t_load is not None else t_end
    before = t < t_step_end
    final = ref[before][-1]
    info = m.step_info(
        t[before],
        y[before],
        initial=y[0],
        final=final,
        dead_zone_threshold=DEAD_ZONE_MM if position_run else None,
    )
    out = {f"{k}": v for k, v in info.items() if k != "peak"}
    out[f"peak_{unit}"] = info["peak"]
    steady = (t_step_end - STEADY_FRACTION * (t_step_end - t[0]), t_step_end - 1e-12)
    stats = m.error_stats(t, ref - y, steady)
    out[f"steady_error_mean_{unit}"] = stats.mean
    out[f"steady_error_std_{unit}"] = stats.std
    out[f"steady_error_rms_{unit}"] = stats.rms
    if t_load is not None:
        rec = m.load_recovery(t, y, ref, t_load, band=0.02 * abs(final), t_end=t_end)
        out[f"load_dip_{unit}"] = rec.dip
        out["load_recovery_time_s"] = rec.recovery_time
    tail = (t_end - STEADY_FRACTION * (t_end - t[0]), t_end)
    chat = m.chattering(t, result["iq_ref_A"], tail)
    out["iq_chattering_A"] = chat.amplitude
    out["iq_chattering_frequency_Hz"] = chat.frequency_Hz
    return {k: float(v) for k, v in out.items()}
