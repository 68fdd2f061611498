"""Sensor models: quantisation, seeded Gaussian noise, offset, reading through a gap."""

import numpy as np

from emasim.interface import M_POSITION, M_RUDDER, M_SPEED, N_MEAS
from emasim.plant import actuator as A
from emasim.plant.parameters import SensorChannel, SensorParams
from emasim.plant.presets import bench_sensors, sea805
from emasim.plant.sensors import initial_state, measure, read_sensor, seed_noise


def test_quantisation_offset_and_noise_statistics():
    assert read_sensor(0.123456, 1e-3, 0.0, 0.0) == 0.123
    assert read_sensor(1.0, 0.0, 0.0, 0.25) == 1.25
    seed_noise(3)  # numba's own generator, as the engine seeds it
    samples = np.array([read_sensor(2.0, 0.0, 0.1, 0.0) for _ in range(20000)])
    assert abs(samples.mean() - 2.0) < 0.005  # 5 standard errors
    assert abs(samples.std() / 0.1 - 1.0) < 0.03


def test_measure_reads_every_channel_and_the_gap():
    plant = sea805()
    p = plant.pack()
    x = np.zeros(A.N_STATE)
    x[A.X_WM], x[A.X_XL] = 50.0, 0.01
    sensors = SensorParams(position=SensorChannel(gap_width=1e-3)).pack(1e-4)
    state = initial_state(x, p)
    meas = np.zeros(N_MEAS)
    measure(x, p, sensors, state, meas, 0)
    assert meas[M_SPEED] == 50.0
    assert meas[M_RUDDER] == 0.01 / (plant.load.rudder_arm_mm * 1e-3)
    assert meas[M_POSITION] == 0.01  # inside the play: the reading holds
    x[A.X_XL] = 0.0112  # moves 1.2 mm: the reading follows at 0.5 mm behind
    measure(x, p, sensors, state, meas, 1)
    assert np.isclose(meas[M_POSITION], 0.0112 - 0.5e-3)


def test_bench_preset_matches_the_papers_sensor_figures():
    bench = bench_sensors()
    arcsec = np.pi / 180 / 3600
    # the HEIDENHAIN TTL encoder: 1024 lines (+-1/20 of a grating period = +-63"), counted on
    # all four quadrature edges, its +-60" accuracy a deviation over each period, not noise
    assert np.isclose(bench.rudder.resolution, 2 * np.pi / 4096)
    assert np.isclose(bench.rudder.accuracy_error, 60 * arcsec)
    assert np.isclose(bench.rudder.accuracy_period, 2 * np.pi / 1024)
    assert bench.rudder.noise_std == 0.0
    assert np.isclose(bench.position.resolution, 0.250 / 2**16)  # 16 bit over 250 mm
    assert np.isclose(bench.force.noise_std * np.sqrt(3), 0.002 * 50e3)  # 0.2 % of 50 kN


def test_the_ttl_encoder_reads_the_count_of_the_angle_plus_its_accuracy_error():
    """Each angle reads q round((theta + a sin(2 pi theta / lambda)) / q), the same every time
    (no noise), within a + q/2 of the truth, and exactly at the neutral it is referenced at."""
    plant = sea805()
    p = plant.pack()
    sensors = SensorParams(rudder=bench_sensors().rudder)
    channel = sensors.rudder
    table = sensors.pack(1e-4)
    arm = plant.load.rudder_arm_mm * 1e-3
    angles = np.linspace(-0.3, 0.3, 2001)
    readings = []
    for tick, theta in enumerate(np.concatenate([angles, angles])):
        x = np.zeros(A.N_STATE)
        x[A.X_XL] = theta * arm  # the lumped rudder: theta = x_L / arm
        meas = np.zeros(N_MEAS)
        measure(x, p, table, initial_state(x, p), meas, tick)
        readings.append(meas[M_RUDDER])
    first, again = np.split(np.array(readings), 2)
    assert np.array_equal(first, again)  # systematic: the same angle reads the same
    q, a, lam = channel.resolution, channel.accuracy_error, channel.accuracy_period
    theta = angles * arm / arm  # the true angle as the plant computes it from x_L
    expected = q * np.round((theta + a * np.sin(2 * np.pi * theta / lam)) / q)
    assert np.allclose(first, expected, rtol=0, atol=1e-15)
    assert np.max(np.abs(first - theta)) <= a + q / 2 + 1e-15
    assert first[np.argmin(np.abs(angles))] == 0.0
