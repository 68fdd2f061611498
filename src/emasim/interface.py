"""The vectors exchanged between the plant's sensors and the controllers (index constants).

Plant code and control code never import each other; both import this module.

Measurement vector ``meas`` (what sensors report at a tick, SI units):
    M_SPEED     motor mechanical speed wm (rad/s)
    M_ANGLE     motor shaft angle theta_m (rad)
    M_POSITION  actuator rod position x (m)
    M_VELOCITY  actuator rod velocity (m/s)
    M_ID, M_IQ  dq stator currents (A)
    M_FORCE     actuator rod force, the drive-train contact force (N)
    M_RUDDER    rudder (control-surface) angle (rad)

Reference vector ``ref`` given to a controller: R_VALUE, R_RATE (first derivative) and
R_ACCEL (second derivative) of its set-point, in the units of the loop.

The drive's limit flags ``LIMIT_*``: bits of the trace column limit_flags, the drive's limits
that a command sat at in a tick, whether the drive cut it or the law had limited it already
(emasim.plant.elements.ratings, emasim.sim.engine.control_tick).

Output vector ``out`` written by a controller: O_VALUE, the command for the inner loop, and
O_RATE, its time derivative as far as the controller knows it (used as feed-forward). The
current loop's slot gets the q-axis current command as its reference (R_VALUE; the d-axis
command is 0) and writes the stator voltages it asks for, O_UD and O_UQ (V).
"""

M_SPEED = 0
M_ANGLE = 1
M_POSITION = 2
M_VELOCITY = 3
M_ID = 4
M_IQ = 5
M_FORCE = 6
M_RUDDER = 7
N_MEAS = 8
MEASUREMENT_NAMES = (
    "speed",
    "angle",
    "position",
    "velocity",
    "id",
    "iq",
    "force",
    "rudder",
)

R_VALUE = 0
R_RATE = 1
R_ACCEL = 2
N_REF = 3

O_VALUE = 0
O_RATE = 1
O_UD = 0  # the current loop's out: d-axis voltage
O_UQ = 1  # ... and q-axis voltage
N_OUT = 2

LIMIT_CURRENT = 1  # the current command at the current limit in force
LIMIT_VOLTAGE = 2  # the voltage at the inverter's Udc / sqrt(3)
LIMIT_SPEED = 4  # the speed command at max_speed, or the current at the rated-speed fold-back
