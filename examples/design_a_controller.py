"""Design a position loop: pick the PI bandwidth whose closed loop, linearised with
python-control, reaches a target -3 dB bandwidth, then check the design on the simulated
drive, with friction and backlash back in, by its small-signal frequency response.

    python examples/design_a_controller.py
"""

import control
import numpy as np
from scipy.optimize import brentq

from emasim import linearize
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
figures = next(iter(sheet.figures.values()))
print(
    f"simulated small-signal bandwidth {figures['bandwidth_small_Hz']:.2f} Hz "
    f"(+-{figures['small_amplitude_mm']:g} mm), threshold {figures['threshold_mm']:.4f} mm"
)
