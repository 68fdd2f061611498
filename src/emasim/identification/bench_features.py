"""What the bench's sensor readings say of its friction, backlash and hinge clearance: the
features that the bench's identification fits (emasim.identification.bench_model).

A sample-by-sample comparison of the bench's readings with a simulation is chaotic in its
parameters (stick-slip, the play, the hinge contacts: benchmarks/identify_sensitivity.py). Each
feature below is instead an average over thousands of samples of a quantity that one fault
moves, read from the sensors alone (the drive's motor encoder angle theta, q current iq, the rod
sensor's extension x and force F, the rudder encoder's angle), with the experiment's load
command T(t) known (the loader's set-point). Samples within ``SETTLE_S`` of a change of the
load command are left out, and so are those at a motor speed below ``SLOW_SPEEDS`` Stribeck
speeds (reversals, where the friction passes its stiction peak).

* **Friction torque** in each direction: the mean, over the samples that turn that way, of
  the torque the motor gives less the one the rod takes, tau = K_t iq - K F (N m), K the
  screw's lead / 2 pi (m/rad), K_t = 3/2 p psi_f; at a steady speed it is the motor and screw's
  friction (the motor's viscous term included).
* **Lost motion in the drive train** (m): the coefficient b of sign(T) in the least-squares fit
  of the nut's travel less the rod's, K theta - x = a + b sign(T) + c sign(w) + d w: half of
  what the nut travels, relative to the rod, when the load reverses (the backlash, and the
  screw's elastic give under the load: the load's one magnitude cannot tell the two apart,
  the simulation holds both), besides the rod sensor's hold (c, d).
* **Lost motion at the rudder** (rad): the coefficient of sign(T) in the fit of the rudder's
  reading on the same terms and a cubic in the rod's reading (the linkage's kinematics): what
  the hinges' clearances and contacts give way when the load reverses.

The same features of a simulated run with candidate values are what the fit compares.
"""

from dataclasses import dataclass

import numpy as np

SETTLE_S = 0.25  # s: the loader's 200 Hz torque loop and the position loop, after a switch
SLOW_SPEEDS = 3.0  # the friction's Stribeck speeds: below, the stiction peak
SPEED_WINDOW_S = 0.051  # s: the moving mean of the encoder's differenced angle
READINGS = ("angle_rad", "rod_position_m", "iq_A", "force_N", "rudder_rad")
TRACE_COLUMNS = {f"measured_{name}": name for name in READINGS}  # a run's trace -> READINGS
FEATURES = (
    "friction_forward_Nm",
    "friction_backward_Nm",
    "drive_lost_motion_m",
    "rudder_lost_motion_rad",
)


@dataclass(frozen=True)
class Constants:
    """The bench's known constants the features use: K (m/rad), K_t (N m/A) and the friction's
    Stribeck speed (rad/s)."""

    lead_per_rad_m: float
    torque_constant_Nm_per_A: float
    stribeck_speed_rad_s: float


def _moving_mean(values: np.ndarray, n: int) -> np.ndarray:
    kernel = np.ones(n) / n
    padded = np.pad(values, n // 2, mode="edge")
    return np.convolve(padded, kernel, mode="valid")


def settled(t: np.ndarray, load: np.ndarray) -> np.ndarray:
    """True where the load command has not changed for SETTLE_S and is not zero."""
    changed = np.r_[False, np.diff(load) != 0.0]
    last = np.maximum.accumulate(np.where(changed, t, -np.inf))
    return (t - last >= SETTLE_S) & (load != 0.0)


def features(t: np.ndarray, readings: dict, load: np.ndarray, known: Constants) -> np.ndarray:
    """The FEATURES (module docstring) of the readings (READINGS, by name, on the time base
    ``t``, s) under the load command ``load`` (N m at t)."""
    dt = float(t[1] - t[0])
    angle = readings["angle_rad"]
    rod = readings["rod_position_m"]
    rudder = readings["rudder_rad"]
    window = max(int(round(SPEED_WINDOW_S / dt)) | 1, 1)
    speed = _moving_mean(np.gradient(angle, dt), window)
    torque = (
        known.torque_constant_Nm_per_A * readings["iq_A"]
        - known.lead_per_rad_m * readings["force_N"]
    )
    steady = settled(t, load)
    moving = steady & (np.abs(speed) > SLOW_SPEEDS * known.stribeck_speed_rad_s)
    forward, backward = moving & (speed > 0.0), moving & (speed < 0.0)
    if forward.sum() < 2 or backward.sum() < 2 or len(np.unique(np.sign(load[steady]))) < 2:
        raise ValueError("the trace needs steady motion both ways under a load of both signs")
    span = max(float(np.ptp(rod[steady])), 1e-9)
    centred = (rod[steady] - float(np.mean(rod[steady]))) / span
    sign_load, s = np.sign(load[steady]), speed[steady]
    common = [sign_load, np.sign(s), s, np.ones(s.size)]
    drive = np.linalg.lstsq(
        np.column_stack(common), known.lead_per_rad_m * angle[steady] - rod[steady], rcond=None
    )[0]
    linkage = np.linalg.lstsq(
        np.column_stack([*common, centred, centred**2, centred**3]), rudder[steady], rcond=None
    )[0]
    return np.array(
        [float(np.mean(torque[forward])), -float(np.mean(torque[backward])), drive[0], linkage[0]]
    )
