"""Speed-step with PI: emasim's command line against gym-electric-motor and motulator.

    python benchmarks/bench_peers.py [--pairs 5] [--peer-python PATH] [--quick] [--write]

The experiment is emasim's ``speed-step`` with ``--controller speed=pi``: a 1000 rpm step, a
10 N*m load step at 0.4 s, 2 s, a PI speed loop over a PI current loop at 10 kHz, on the
sea805-stand plant. :func:`experiment` reads it from the scenario and hands it, as JSON, to
each peer's script in ``benchmarks/peers/``, which builds the same experiment with that
library as closely as it allows (each script's docstring says what matches and what differs),
times its simulation alone and prints one JSON line.

The peers are not emasim's dependencies: they live in a virtual environment of their own,
with the versions that pyproject.toml's ``peers`` extra pins (never in emasim's: they bring
gymnasium and their own pins), whose interpreter ``--peer-python`` names (default:
``$EMASIM_PEERS_PYTHON``)::

    python3 -m venv /tmp/peers-venv
    /tmp/peers-venv/bin/pip install gym-electric-motor==3.0.3 motulator==0.5.0
    python benchmarks/bench_peers.py --peer-python /tmp/peers-venv/bin/python --write

Without one, the benchmark says so in one line and times emasim alone (CI, which runs every
``bench_*.py --quick``, has no peers).

Protocol (the machine is shared and noisy): one warm-up process of each side, then
``--pairs`` rounds, each a fresh ``python -m emasim run speed-step --controller speed=pi
--no-plot --out TMP`` (its figure: meta.json's ``simulation_wall_s`` per simulated second,
the compile never counted) and a fresh process of each peer's script, the order reversed in
odd rounds. Reported: the median seconds per simulated second of each, the median of the
paired ratios peer / emasim, and the median wall time of each whole process (start-up,
imports and construction included). ``--write`` stores them in ``benchmarks/results.json``
under ``peers`` and rewrites docs/speed.md's table (``speed_figures.py``). ``--quick`` (CI):
QUICK_S simulated, one round, no warm-up.
"""

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import time
from pathlib import Path

from commands import run_meta, user_environment
from speed_figures import RESULTS, write_page

from emasim.control import pid
from emasim.scenarios.loader import load_scenario

SCENARIO, CONTROLLER = "speed-step", "speed=pi"
PEERS = Path(__file__).resolve().parent / "peers"
SCRIPTS = {  # peer -> its script in benchmarks/peers/
    "gym-electric-motor": PEERS / "gem_speed_step.py",
    "motulator": PEERS / "motulator_speed_step.py",
}
SETUPS = {  # peer -> its controllers, in a few words (the script's docstring says the rest)
    "gym-electric-motor": "gem's environment driven by emasim's PI laws written out in Python "
    "(gem_controllers 3.0.3 cannot build a PMSM speed loop)",
    "motulator": "motulator's current-vector control, its speed PI given emasim's gains",
}
QUICK_S = 0.05
SECTION = "peers"


def experiment(duration_s: float | None = None) -> dict:
    """The speed-step experiment in SI units, what the peers' scripts build. The load's
    inertia and viscous friction are reflected onto the motor shaft (the screw's efficiency
    aside); the LuGre friction gives its Coulomb level and its viscous term."""
    scenario = load_scenario(SCENARIO, controllers=[CONTROLLER])
    setup, plant = scenario.setup(), scenario.plant
    (speed_step,) = scenario.reference.speed_rpm
    (load_step,) = scenario.load.motor_torque_Nm
    if speed_step.initial or speed_step.time_s or load_step.initial:
        raise ValueError("the peers' scripts build a speed step at 0 from rest and one load step")
    facts, k = setup.facts, setup.facts.ratio_m_per_rad
    return {
        "pole_pairs": facts.pole_pairs,
        "resistance_ohm": facts.resistance_ohm,
        "inductance_d_H": facts.inductance_d_H,
        "inductance_q_H": facts.inductance_q_H,
        "flux_linkage_Wb": facts.flux_linkage_Wb,
        "inertia_kgm2": facts.inertia_kgm2,
        "motor_inertia_kgm2": plant.motor.inertia_kgm2,
        "load_inertia_kgm2": facts.inertia_kgm2 - plant.motor.inertia_kgm2,
        "viscous_Nms_per_rad": plant.motor.viscous_Nms_per_rad
        + plant.friction.viscous_Nms_per_rad
        + plant.load.viscous_Ns_per_m * k**2,
        "coulomb_Nm": plant.friction.coulomb_Nm,
        "dc_bus_V": facts.dc_bus_V,
        "max_current_A": facts.max_current_A,
        "max_speed_rad_s": facts.max_speed_rad_s,
        "sample_period_s": setup.sample_period_s,
        "duration_s": duration_s if duration_s is not None else setup.duration_s,
        "speed_ref_rad_s": speed_step.final * math.pi / 30,
        "load_step_s": load_step.time_s,
        "load_torque_Nm": load_step.final,
        "speed_kp_A_s_per_rad": float(setup.speed.params[pid.KP]),
        "speed_ki_A_per_rad": float(setup.speed.params[pid.KI]),
        "current_bandwidth_rad_s": 2 * math.pi * scenario.controllers.current.bandwidth_Hz,
    }


def emasim_run(x: dict, quick: bool) -> dict:
    """One fresh ``python -m emasim run`` process: its simulation's s/s (meta.json) and its
    whole wall time."""
    args = [SCENARIO, "--controller", CONTROLLER, "--no-plot", "--out", "{out}/run"]
    if quick:
        args += ["--set", f"duration_s={x['duration_s']}"]
    start = time.perf_counter()
    meta = run_meta(args)
    process = time.perf_counter() - start
    return {
        "s_per_s": meta["simulation_wall_s"] / x["duration_s"],
        "process_s": process,
        "source": meta["emasim_source_sha256"],
        "commit": meta.get("git_commit"),
    }


def peer_run(python: str, script: Path, x: dict) -> dict:
    """One fresh process of a peer's script: its printed figures and its whole wall time."""
    start = time.perf_counter()
    proc = subprocess.run(
        [python, "-W", "ignore", str(script), json.dumps(x)],
        env=user_environment(),
        capture_output=True,
        text=True,
    )
    process = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{script.name}: exit code {proc.returncode}\n{proc.stderr}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process_s"] = process
    return out


def measure(python: str | None, pairs: int, quick: bool) -> dict:
    """Interleaved rounds (module docstring): side -> [one run's figures per round]."""
    x = experiment(QUICK_S if quick else None)
    sides = {"emasim": lambda: emasim_run(x, quick)}
    if python is not None:
        for peer, script in SCRIPTS.items():
            sides[peer] = lambda script=script: peer_run(python, script, x)
    if not quick:
        for run in sides.values():
            run()  # warm-up: numba's cache, the bytecode, the file cache
    runs = {side: [] for side in sides}
    for i in range(pairs):
        for side in list(sides) if i % 2 == 0 else list(sides)[::-1]:
            runs[side].append(sides[side]())
    return {"experiment": x, "runs": runs}


def summary(measured: dict, peer_python: str | None) -> dict:
    """The section stored under ``peers``: medians, paired ratios and each run's figures."""
    x, runs = measured["experiment"], measured["runs"]
    emasim = [run["s_per_s"] for run in runs["emasim"]]
    out = {
        "date": datetime.date.today().isoformat(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "scenario": SCENARIO,
        "controller": CONTROLLER,
        "duration_s": x["duration_s"],
        "pairs": len(emasim),
        "emasim": {
            "s_per_s": statistics.median(emasim),
            "process_s": statistics.median(run["process_s"] for run in runs["emasim"]),
            "runs_s_per_s": emasim,
            "source_sha256": runs["emasim"][0]["source"],
            "commit": runs["emasim"][0]["commit"],
        },
        "peers": {},
    }
    if peer_python is not None:
        out["peer_python"] = subprocess.run(
            [peer_python, "-c", "import platform; print(platform.python_version())"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    for peer in SCRIPTS:
        if peer not in runs:
            continue
        times = [run["s_per_s"] for run in runs[peer]]
        out["peers"][peer] = {
            "version": runs[peer][0]["version"],
            "script": f"benchmarks/peers/{SCRIPTS[peer].name}",
            "setup": SETUPS[peer],
            "s_per_s": statistics.median(times),
            "process_s": statistics.median(run["process_s"] for run in runs[peer]),
            "ratio": statistics.median(p / e for p, e in zip(times, emasim, strict=True)),
            "runs_s_per_s": times,
            "final_speed_rpm": runs[peer][-1]["final_speed_rpm"],
        }
    return out


def report(section: dict) -> None:
    emasim = section["emasim"]
    print(
        f"{SCENARIO} -c {CONTROLLER}, {section['duration_s']:g} s simulated, "
        f"{section['pairs']} interleaved rounds; medians (s per simulated s; whole process s)"
    )
    print(
        f"{'emasim (command line)':24s} {emasim['s_per_s']:9.4f} s/s  {emasim['process_s']:6.2f} s"
    )
    for peer, figures in section["peers"].items():
        print(
            f"{peer + ' ' + figures['version']:24s} {figures['s_per_s']:9.4f} s/s  "
            f"{figures['process_s']:6.2f} s  paired ratio peer/emasim {figures['ratio']:.1f}x"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=5, help="interleaved rounds")
    parser.add_argument(
        "--peer-python",
        default=os.environ.get("EMASIM_PEERS_PYTHON"),
        help="interpreter of the peers' environment (default: $EMASIM_PEERS_PYTHON)",
    )
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_S} s simulated, one round")
    parser.add_argument(
        "--write",
        action="store_true",
        help="store the figures in benchmarks/results.json and rewrite docs/speed.md's table",
    )
    args = parser.parse_args()
    if args.write and (args.quick or args.peer_python is None):
        parser.error("--write stores a full measurement with the peers: no --quick, a peer")
    if args.peer_python is None:
        print("no peers' interpreter (--peer-python or $EMASIM_PEERS_PYTHON): timing emasim alone")
    section = summary(
        measure(args.peer_python, 1 if args.quick else args.pairs, args.quick), args.peer_python
    )
    report(section)
    if args.write:
        results = json.loads(RESULTS.read_text())
        results[SECTION] = section
        RESULTS.write_text(json.dumps(results, indent=2) + "\n")
        write_page(results)
        print(f"wrote {RESULTS} and docs/speed.md's table")


if __name__ == "__main__":
    main()
