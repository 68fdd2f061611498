"""What the paper's report judges: the rows of the bench tables, the abstract's headline
figures with their definitions, and the labels of the sets compared.

Read by the report (:mod:`emasim.analysis.paper_report`), the component tables
(:mod:`emasim.analysis.components`) and the experiments that run the verdicts.
"""

from .report import BENCH_STEADY_S, RATE_WINDOW_S

# paper table key -> (our metric key, unit); lower magnitude is better for every one of them
BENCH_STEP_ROWS = {
    "settling_s": ("settling_time_s", "s"),
    "rise_s": ("rise_time_s", "s"),
    "chatter_amplitude_deg": ("chatter_amplitude_deg", "deg"),
    "steady_error_mean_deg": ("steady_error_mean_deg", "deg"),
    "steady_error_std_deg": ("steady_error_std_deg", "deg"),
    "steady_error_rms_deg": ("steady_error_rms_deg", "deg"),
    "peak_velocity_deg_s": ("peak_velocity_deg_s", "deg/s"),
    "velocity_fluctuation_deg_s": ("velocity_fluctuation_deg_s", "deg/s"),
    "velocity_error_mean_deg_s": ("velocity_error_mean_deg_s", "deg/s"),
    "velocity_error_std_deg_s": ("velocity_error_std_deg_s", "deg/s"),
    "velocity_error_rms_deg_s": ("velocity_error_rms_deg_s", "deg/s"),
}
BENCH_SINE_ROWS = {
    "tracking_error_deg": ("tracking_error_deg", "deg"),
    "initial_reverse_motion": ("initial_reverse_motion", "yes/no"),
    "reverse_motion_deg": ("reverse_motion_deg", "deg"),  # not in the paper: how far back
    "peak_velocity_deg_s": ("peak_velocity_deg_s", "deg/s"),
    "velocity_fluctuation_deg_s": ("velocity_fluctuation_deg_s", "deg/s"),
}
HEADLINE = {  # abstract figure -> (experiment, paper row, definition)
    "step_steady_error_reduction": (
        "bench_step",
        "steady_error_rms_deg",
        f"RMS of the rudder angle error from {BENCH_STEADY_S:g} s to the end of the 4.72 deg "
        "step (the RMS, not the mean: the mean of a limit cycle about the target is near zero "
        "and depends on where the window cuts the cycle)",
    ),
    "step_vibration_amplitude_reduction": (
        "bench_step",
        "chatter_amplitude_deg",
        f"half peak-to-peak of the rudder angle from {BENCH_STEADY_S:g} s to the end of the step",
    ),
    "step_speed_fluctuation_reduction": (
        "bench_step",
        "velocity_fluctuation_deg_s",
        f"half peak-to-peak of the rudder rate about its linear trend from {BENCH_STEADY_S:g} s",
    ),
    "sine_displacement_lag_reduction": (
        "bench_sine",
        "tracking_error_deg",
        f"max |rudder angle error| from {BENCH_STEADY_S:g} s on (the paper's 'lag angle')",
    ),
    "sine_speed_fluctuation_reduction": (
        "bench_sine",
        "velocity_fluctuation_deg_s",
        f"half peak-to-peak of the rudder rate about its fitted sine from {BENCH_STEADY_S:g} s",
    ),
}
# headline figure -> (multiple, unit, why): what one step of the bench's reading changes the
# measured figure by, its resolution and so the least of its tie band
# (emasim.analysis.verdict_rule), in rudder-encoder counts q ("count", deg) or in the rate's
# quanta q / RATE_WINDOW_S ("rate", deg/s: the reading differenced over RATE_WINDOW_S)
RESOLUTION = {
    "step_steady_error_reduction": (
        1.0,
        "count",
        "an RMS of readings moves by up to one count when the readings move by one",
    ),
    "step_vibration_amplitude_reduction": (
        0.5,
        "count",
        "half peak-to-peak: one count more at either extreme moves it by half a count",
    ),
    "step_speed_fluctuation_reduction": (
        0.5,
        "rate",
        f"half peak-to-peak of a rate read in quanta of q / {RATE_WINDOW_S:g} s",
    ),
    "sine_displacement_lag_reduction": (
        1.0,
        "count",
        "the largest |error| moves by one count when the reading does",
    ),
    "sine_speed_fluctuation_reduction": (
        0.5,
        "rate",
        f"half peak-to-peak of a rate read in quanta of q / {RATE_WINDOW_S:g} s",
    ),
}
PID_LABEL, HYBRID_LABEL = "PID", "hybrid"
INDUSTRIAL_LABEL = "industrial PID"  # velocity and acceleration feed-forward
ABLATED_TABLES = {"bench_step": BENCH_STEP_ROWS, "bench_sine": BENCH_SINE_ROWS}


def headline_metric(key: str) -> tuple[str, str]:
    """(our metric key, unit) of a headline figure (a key of HEADLINE)."""
    experiment, row, _ = HEADLINE[key]
    return ABLATED_TABLES[experiment][row]


def figure_words(key: str) -> str:
    """How the reports name a headline figure: its key in words ('sine displacement lag' for
    'sine_displacement_lag_reduction')."""
    return key.removesuffix("_reduction").replace("_", " ")


def resolution(key: str, count_deg: float) -> float:
    """The measured headline figure ``key``'s resolution (RESOLUTION) for a rudder encoder of
    ``count_deg`` degrees a count: deg, or deg/s for a rate figure."""
    multiple, unit, _ = RESOLUTION[key]
    return multiple * count_deg / (RATE_WINDOW_S if unit == "rate" else 1.0)
