"""Design a position loop: pick the PI bandwidth whose closed loop, linearised with
python-control, reaches a target -3 dB bandwidth, then check the design on the simulated
drive, with friction and backlash back in, by its small-signal frequency response.

    python examples/design_a_controller.py [FIGURE_FOLDER]

It draws the linear model's Bode plot with the simulated points on it into
FIGURE_FOLDER/design-bode.png (default: the current folder).
"""

import sys
from pathlib import Path

import control
import numpy as np
from matplotlib.figure import Figure  # files only: no window, no pyplot
from scipy.optimize import brentq

from emasim import linearize
from emasim.analysis.datasheet import cell
from emasim.experiments.acceptance import Battery, run_acceptance
from emasim.scenarios.loader import load_scenario

TARGET_HZ = 4.0  # the closed loop's -3 dB bandwidth we want
SPEED = 'controllers.speed={name = "pi", bandwidth_Hz = 50}'  # both loops by bandwidth alone


def design(bandwidth_Hz: float):
    position = f"name = 'pi', bandwidth_Hz = {bandwidth_Hz}, velocity_feedforward = false"
    settings = [SPEED, f"controllers.position={{{position}}}"]
    return load_scenario(
        "position-step", controllers=["position=pi", "speed=pi"], settings=settings
    )


def closed_loop_bandwidth_Hz(bandwidth_Hz: float) -> float:
    return float(control.bandwidth(linearize(design(bandwidth_Hz)))) / (2 * np.pi)


chosen = brentq(lambda b: closed_loop_bandwidth_Hz(b) - TARGET_HZ, 0.5, 10.0, xtol=1e-3)
print(f"position PI bandwidth {chosen:.3f} Hz -> linear closed loop {TARGET_HZ:g} Hz at -3 dB")

# the design on the simulated drive (friction, backlash 0.1 mm, end stops): small signal only
battery = Battery(frequencies_Hz=(1.0, 2.0, 4.0, 8.0), stiffness_frequencies_Hz=(1.0,))
sheet = run_acceptance(design(chosen), battery=battery)
label = next(iter(sheet.figures))
figures = sheet.figures[label]
amplitude = figures["small_amplitude_mm"]
threshold = figures["threshold_mm"]  # a number, a bound, or not measurable where the loop hunts
unit = "" if isinstance(threshold, dict) and "not_measurable" in threshold else " mm"
print(
    f"simulated small-signal bandwidth {figures['bandwidth_small_Hz']:.2f} Hz "
    f"(+-{amplitude:g} mm), threshold {cell(threshold)}{unit}"
)

# the Bode plot: the linear model's line, the simulated drive's measured points on it
f = np.geomspace(0.2, 40.0, 300)
linear = linearize(design(chosen))(2j * np.pi * f)  # measured position / position command
small = sheet.frequency_response(label)  # position over command, small signal (FRD)
measured_f, measured = small.omega / (2 * np.pi), small.complex.ravel()
fig = Figure(figsize=(7, 5.5), layout="constrained")
gain, phase = fig.subplots(2, 1, sharex=True)
gain.semilogx(f, 20 * np.log10(np.abs(linear)), label="linear model (no friction, no backlash)")
gain.semilogx(measured_f, 20 * np.log10(np.abs(measured)), "o", label="simulated drive")
phase.semilogx(f, np.angle(linear, deg=True))
phase.semilogx(measured_f, np.angle(measured, deg=True), "o")
gain.axhline(-3.0, color="0.6", lw=0.8, label="-3 dB")
for ax in (gain, phase):
    ax.axvline(TARGET_HZ, color="0.6", lw=0.8, ls="--", label=f"target {TARGET_HZ:g} Hz")
    ax.grid(True, which="both", alpha=0.3)
gain.set_ylabel("gain (dB)")
phase.set_ylabel("phase (deg)")
phase.set_xlabel("frequency (Hz)")
phase.xaxis.set_major_formatter("{x:g}")
gain.legend(loc="lower left", fontsize="small")
gain.set_title(f"Position PI at {chosen:.2f} Hz: the closed loop, simulated at ±{amplitude:g} mm")
folder = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
folder.mkdir(parents=True, exist_ok=True)
fig.savefig(folder / "design-bode.png", dpi=120)
