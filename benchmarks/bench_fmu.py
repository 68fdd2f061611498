"""Cost of the FMI layer: the plant FMU's doStep against the same work in process.

    python benchmarks/bench_fmu.py [--quick]

Builds the plant FMU (drive + linkage, pythonfmu), loads it with fmpy and steps it open loop
(constant voltages) one control tick (1e-4 s, 10 RK4 sub-steps) at a time; then runs the same
sub-steps in process. Reports microseconds per tick, the FMI layer's share and the ratio, best
of five runs of 2000 ticks (``--quick``: one run of 100 ticks, for CI). ``bench_engine.py``'s
full run calls :func:`fmu_figures` and stores the figures in ``results.json`` for docs/speed.md.
"""

import argparse
import tempfile
import time

from emasim.plant.presets import sea805_linkage
from emasim.signals import ZERO
from emasim.sim.core import new_workspace
from emasim.sim.fmi import FmuSlave, export_plant_fmu, plant_substeps

TS, SUBSTEPS = 1e-4, 10


def per_tick_fmu(path, ticks: int) -> float:
    with FmuSlave(path) as fmu:
        fmu.set_real(fmu.refs("ud_V", "uq_V"), [0.0, 20.0])
        fmu.do_step(0.0, TS)  # the first step loads the compiled plant in the FMU's Python
        start = time.perf_counter()
        for k in range(1, ticks + 1):
            fmu.do_step(k * TS, TS)
        return (time.perf_counter() - start) / ticks


def per_tick_in_process(plant, ticks: int) -> float:
    p, x = plant.pack(), plant.initial_state()
    work = new_workspace()
    h = TS / SUBSTEPS
    loads = (ZERO, ZERO, ZERO)  # none on the motor, the rod or the rudder
    plant_substeps(0.0, x, 0.0, 20.0, p, loads, h, SUBSTEPS, work)  # compiled, cached
    start = time.perf_counter()
    for k in range(ticks):
        plant_substeps(k * TS, x, 0.0, 20.0, p, loads, h, SUBSTEPS, work)
    return (time.perf_counter() - start) / ticks


def fmu_figures(runs: int, ticks: int) -> dict:
    """Microseconds per tick through the FMU and in process, the FMI layer's share, the ratio."""
    plant = sea805_linkage()
    with tempfile.TemporaryDirectory() as folder:
        path = export_plant_fmu(f"{folder}/plant.fmu", plant)
        fmu = min(per_tick_fmu(path, ticks) for _ in range(runs))
    direct = min(per_tick_in_process(plant, ticks) for _ in range(runs))
    return {
        "fmu_us": 1e6 * fmu,
        "in_process_us": 1e6 * direct,
        "layer_us": 1e6 * (fmu - direct),
        "ratio": fmu / direct,
        "runs": runs,
        "ticks": ticks,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one run of 100 ticks")
    quick = parser.parse_args().quick
    figures = fmu_figures(*((1, 100) if quick else (5, 2000)))
    print(f"plant FMU doStep (1 tick, 10 sub-steps): {figures['fmu_us']:.1f} us")
    print(f"same sub-steps in process:               {figures['in_process_us']:.1f} us")
    print(f"FMI layer per step: {figures['layer_us']:.1f} us ({figures['ratio']:.2f}x)")


if __name__ == "__main__":
    main()
