"""Cost of the FMI layer: the plant FMU's doStep against the same work in process.

    python benchmarks/bench_fmu.py

Builds the plant FMU (drive + linkage, pythonfmu), loads it with fmpy and steps it open loop
(constant voltages) one control tick (1e-4 s, 10 RK4 sub-steps) at a time; then runs the same
sub-steps in process. Reports microseconds per tick, the FMI layer's share and the ratio, best
of five runs of 2000 ticks.
"""

import tempfile
import time

import numpy as np

from emasim.plant import actuator as A
from emasim.plant.presets import sea805_linkage
from emasim.signals import ZERO
from emasim.sim.fmi import FmuSlave, export_plant_fmu, plant_substeps

TS, SUBSTEPS, TICKS = 1e-4, 10, 2000


def per_tick_fmu(path) -> float:
    with FmuSlave(path) as fmu:
        fmu.set_real(fmu.refs("ud_V", "uq_V"), [0.0, 20.0])
        start = time.perf_counter()
        for k in range(TICKS):
            fmu.do_step(k * TS, TS)
        return (time.perf_counter() - start) / TICKS


def per_tick_in_process(plant) -> float:
    p, x = plant.pack(), plant.initial_state()
    work = np.zeros((5, A.N_STATE))
    h = TS / SUBSTEPS
    plant_substeps(0.0, x, 0.0, 20.0, p, ZERO, ZERO, h, SUBSTEPS, work)  # compiled, cached
    start = time.perf_counter()
    for k in range(TICKS):
        plant_substeps(k * TS, x, 0.0, 20.0, p, ZERO, ZERO, h, SUBSTEPS, work)
    return (time.perf_counter() - start) / TICKS


def main() -> None:
    plant = sea805_linkage()
    with tempfile.TemporaryDirectory() as folder:
        path = export_plant_fmu(f"{folder}/plant.fmu", plant)
        fmu = min(per_tick_fmu(path) for _ in range(5))
    direct = min(per_tick_in_process(plant) for _ in range(5))
    print(f"plant FMU doStep (1 tick, 10 sub-steps): {1e6 * fmu:.1f} us")
    print(f"same sub-steps in process:               {1e6 * direct:.1f} us")
    print(f"FMI layer per step: {1e6 * (fmu - direct):.1f} us ({fmu / direct:.2f}x)")


if __name__ == "__main__":
    main()
