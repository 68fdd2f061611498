"""Sensors: what the controllers see of the plant, sampled and held at each channel's rate.

Each measurement channel (layout in :mod:`emasim.interface`) reads its true value v and reports

    y = quantise(v + offset + e(v) + noise_std * N(0, 1), resolution)
    e(v) = a sin(2 pi v / lambda)

optionally through a gap of half-width b (the play operator, for a position read across
backlash). quantise(v, q) = q * round(v / q); q = 0 means no quantisation. e(v) is a smooth,
position-dependent accuracy error of amplitude a and period lambda (in v), zero at v = 0: the
deviation of an encoder's reading from the true angle that its accuracy class bounds (an
incremental encoder is referenced at the rudder's neutral, so its reading is right there). It
is systematic, not noise: the same angle reads the same every time. A channel samples
every n-th control tick (its own sample period n Ts) and holds its reading in between.

A **derived** channel (the motor speed from the encoder's angle, the rod velocity from its
position) differentiates its source channel's readings over its own sample period T and
filters the difference through a first-order lag of time constant tau, discretised exactly:

    d(k) = (y_src(k) - y_src(k-1)) / T,   f(k) = f(k-1) + (1 - exp(-T / tau)) (d(k) - f(k-1))

so an encoder of resolution q gives speeds in steps of q / T before the filter. Its own
offset, noise and quantum then apply to f. Noise draws come from numba's generator, seeded
once per run, so a run is reproducible from its seed.

The rod's displacement sensor sits on the actuator body, so it reads the rod's extension
x_L - x_h (emasim.plant.elements.anchorage).
"""

import math

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
from .elements.backlash import play_operator

# columns of the sensor table built by emasim.plant.parameters.SensorParams.pack
S_RESOLUTION = 0
S_NOISE = 1
S_OFFSET = 2
S_HALF_GAP = 3
S_EVERY = 4  # samples every n-th tick
S_SOURCE = 5  # the channel a derived channel differentiates, -1 for none
S_PERIOD = 6  # the channel's sample period T (s)
S_ALPHA = 7  # the filter's 1 - exp(-T / tau) (1: no filter)
S_ERROR = 8  # the accuracy error's amplitude a (0: none)
S_WAVENUMBER = 9  # the accuracy error's 2 pi / lambda (1/unit of the channel)
N_SENSOR_COLUMNS = 10

# columns of the sensors' state (emasim.sim.core.Data.sensor_state)
ST_GAP = 0  # the play operator's output
ST_HELD = 1  # the reading held between samples
ST_SOURCE = 2  # a derived channel: its source's reading at its previous sample
ST_FILTER = 3  # a derived channel: the filter's output
N_SENSOR_STATE = 4


def ideal_table() -> np.ndarray:
    """The sensor table of ideal channels, every one sampled at every tick."""
    table = np.zeros((N_MEAS, N_SENSOR_COLUMNS))
    table[:, S_EVERY] = 1.0
    table[:, S_SOURCE] = -1.0
    table[:, S_ALPHA] = 1.0
    return table


@njit(cache=True, error_model="numpy")
def true_values(x, p, values):
    """Write the noiseless value of every measurement channel of state x into ``values``."""
    values[M_SPEED] = x[A.X_WM]
    values[M_ANGLE] = x[A.X_THETA]
    values[M_POSITION], values[M_VELOCITY] = A.rod_extension(x)
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
def accuracy_error(v, amplitude, wavenumber):
    """The reading's systematic error at the true value v, e(v) = a sin(k v), k = 2 pi / lambda
    (module docstring); 0 where a is 0."""
    if amplitude == 0.0:
        return 0.0
    return amplitude * math.sin(wavenumber * v)


@njit(cache=True, error_model="numpy")
def _sample(i, v, table, state):
    """Channel i's reading of v: through its play operator, then accuracy error, offset,
    noise, quantum."""
    if table[i, S_HALF_GAP] > 0.0:
        v = play_operator(v, state[i, ST_GAP], table[i, S_HALF_GAP], 1.0)
        state[i, ST_GAP] = v
    v += accuracy_error(v, table[i, S_ERROR], table[i, S_WAVENUMBER])
    reading = read_sensor(v, table[i, S_RESOLUTION], table[i, S_NOISE], table[i, S_OFFSET])
    state[i, ST_HELD] = reading
    return reading


@njit(cache=True, error_model="numpy")
def read_series(values, table, channel):
    """Channel ``channel``'s readings of the true values ``values``, one sample each, by the
    law of every reading (:func:`_sample`: play operator from the first value, accuracy
    error, offset, noise from the compiled generator (:func:`seed_noise`), quantum): what the
    sensor makes of a given signal, such as a perfect follower's (the measurement floor,
    emasim.experiments.replicas). ``table`` is a sensor table (module docstring)."""
    state = np.zeros((table.shape[0], N_SENSOR_STATE))
    out = np.empty(values.size)
    if values.size:
        state[channel, ST_GAP] = values[0]
    for k in range(values.size):
        out[k] = _sample(channel, values[k], table, state)
    return out


@njit(cache=True, error_model="numpy")
def measure(x, p, table, state, meas, tick):
    """Fill ``meas`` with every channel's reading at control tick ``tick`` (module docstring).

    table is the (N_MEAS x N_SENSOR_COLUMNS) sensor table, state the (N_MEAS x
    N_SENSOR_STATE) sensors' state (initial_state). A channel not due at this tick gives its
    held reading. Direct channels are read first, then the derived ones from their sources'
    readings of this tick.
    """
    true_values(x, p, meas)
    for derived in (False, True):
        for i in range(N_MEAS):
            if (table[i, S_SOURCE] >= 0.0) != derived:
                continue
            if tick % int(table[i, S_EVERY]) != 0:
                meas[i] = state[i, ST_HELD]
                continue
            v = meas[i]
            if derived:
                source = meas[int(table[i, S_SOURCE])]
                if tick == 0:  # no earlier reading to difference: the filter's initial value
                    v = state[i, ST_FILTER]
                else:
                    rate = (source - state[i, ST_SOURCE]) / table[i, S_PERIOD]
                    v = state[i, ST_FILTER] + table[i, S_ALPHA] * (rate - state[i, ST_FILTER])
                state[i, ST_SOURCE] = source
                state[i, ST_FILTER] = v
            meas[i] = _sample(i, v, table, state)


def initial_state(x0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The sensors' state at the start of a run: every play operator, held reading and filter
    at its channel's true value. A derived channel's first sample (tick 0) reads its filter's
    initial value, the true rate (a plant at rest reads zero), and stores its source's first
    reading to difference the next one against."""
    values = np.zeros(N_MEAS)
    true_values(x0, p, values)
    state = np.zeros((N_MEAS, N_SENSOR_STATE))
    state[:, ST_GAP] = state[:, ST_HELD] = state[:, ST_FILTER] = values
    return state
