"""Sensors: what the controllers see of the plant, sampled at each control tick.

Each measurement channel (layout in :mod:`emasim.interface`) reads its true value v and reports

    y = quantise(v + offset + noise_std * N(0, 1), resolution)

optionally through a gap of half-width b (the play operator, for a position read across
backlash). quantise(v, q) = q * round(v / q); q = 0 means no quantisation. Sampling and
zero-order hold come from the tick itself. Noise draws come from numba's generator, seeded once
per run, so a run is reproducible from its seed.
"""

import numpy as np

from ..interface import (
    M_ANGLE,
    M_FORCE,
    M_ID,
    M_IQ,
    M_POSITION,
    M_RUDDER,
    M_SPEED,
    M_VELOCITY,
    N_MEAS,
)
from ..jit import njit
from . import actuator as A
from .backlash import play_operator

# columns of the sensor table built by emasim.plant.parameters.SensorParams.pack
S_RESOLUTION = 0
S_NOISE = 1
S_OFFSET = 2
S_HALF_GAP = 3


@njit(cache=True, error_model="numpy")
def true_values(x, p, values):
    """Write the noiseless value of every measurement channel of state x into ``values``."""
    values[M_SPEED] = x[A.X_WM]
    values[M_ANGLE] = x[A.X_THETA]
    values[M_POSITION] = x[A.X_XL]
    values[M_VELOCITY] = x[A.X_VL]
    values[M_ID] = x[A.X_ID]
    values[M_IQ] = x[A.X_IQ]
    values[M_FORCE] = A.drivetrain_force(x, p)
    values[M_RUDDER] = A.rudder_angle(x, p)


@njit(cache=True, error_model="numpy")
def seed_noise(seed):
    """Seed the generator of compiled code (numba keeps its own, apart from numpy's)."""
    np.random.seed(seed)


@njit(cache=True, error_model="numpy")
def read_sensor(value, resolution, noise_std, offset):
    """One sample of a sensor: offset, Gaussian noise, then quantisation."""
    y = value + offset
    if noise_std > 0.0:
        y += noise_std * np.random.standard_normal()
    if resolution > 0.0:
        y = resolution * np.round(y / resolution)
    return y


@njit(cache=True, error_model="numpy")
def measure(x, p, table, gap_state, meas):
    """Fill ``meas`` with every channel's reading; ``gap_state`` holds each play operator's output.

    table is the (N_MEAS x 4) sensor parameter table; a channel with S_HALF_GAP > 0 is read
    through the play operator (its state must start at the channel's initial true value).
    """
    true_values(x, p, meas)
    for i in range(N_MEAS):
        v = meas[i]
        if table[i, S_HALF_GAP] > 0.0:
            v = play_operator(v, gap_state[i], table[i, S_HALF_GAP], 1.0)
            gap_state[i] = v
        meas[i] = read_sensor(v, table[i, S_RESOLUTION], table[i, S_NOISE], table[i, S_OFFSET])
