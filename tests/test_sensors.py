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
    assert np.isclose(bench.rudder.noise_std * np.sqrt(3), 60 * arcsec)  # +-60"
    assert np.isclose(bench.position.resolution, 0.250 / 2**16)  # 16 bit over 250 mm
    assert np.isclose(bench.force.noise_std * np.sqrt(3), 0.002 * 50e3)  # 0.2 % of 50 kN
