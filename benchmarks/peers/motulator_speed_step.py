"""emasim's speed-step on motulator 0.5.0: the peer's wall seconds per simulated second.

    python motulator_speed_step.py EXPERIMENT_JSON      # prints one JSON line

Run by ``benchmarks/bench_peers.py`` in the peers' own virtual environment, never emasim's.
EXPERIMENT_JSON is the experiment bench_peers.py reads from emasim's ``speed-step`` scenario
(``bench_peers.experiment``). Built as motulator's PMSM examples build a drive
(``motulator.drive.model`` and ``motulator.drive.control.sm.CurrentVectorControl``), with
the position sensor (``sensorless=False``).

Matches emasim: the PMSM (pole pairs, Rs, Ld, Lq, flux linkage), the total inertia on the
shaft (motor and the load reflected), the viscous friction (motor, friction model and rod,
reflected) and the 0.3 N*m Coulomb friction (``B_L`` of the speed, smoothed below 0.1 rad/s
as emasim's friction is), the 560 V bus, the 58 A current limit, the 10 kHz control rate
(``T_s``), the 1000 rpm speed step at 0, the 10 N*m load step at 0.4 s (``tau_L``) and the
simulated duration; a PI speed loop with emasim's gains (in N*m: times kt; motulator's
``PIController`` with k_t = k_p, the plain PI) over motulator's current controller at
emasim's 500 Hz bandwidth, id* = 0 (the MTPA table replaced by zero, as emasim commands).

Differs: the mechanics are one rigid inertia (no backlash, no LuGre bristle state, no rod and
rudder masses of their own); motulator's current controller is its flux-linkage-based
complex-vector PI (emasim: a dq PI with decoupling, the same bandwidth); motulator models one
sample of computational delay and its angle compensation (emasim applies the voltage at
once); scipy's ``solve_ivp`` (RK45) over each sampling period, as ``Simulation.simulate``
does (emasim: fixed 10 us steps).

Timed: ``Simulation.simulate`` over the whole duration (its post-processing included), after
the same drive was built and simulated for a few samples once (imports and caches warm) and
built again.
"""

import json
import math
import sys
import time
from importlib.metadata import version

import motulator.drive.control.sm as control
import numpy as np
from motulator.common.control import PIController
from motulator.drive import model
from motulator.drive.utils import Step, SynchronousMachinePars

SMOOTHING_SPEED_RAD_S = 0.1  # emasim's friction smoothing speed (presets.motor_lugre_friction)
WARM_UP_S = 1e-3


def build(x: dict):
    par = SynchronousMachinePars(
        n_p=x["pole_pairs"],
        R_s=x["resistance_ohm"],
        L_d=x["inductance_d_H"],
        L_q=x["inductance_q_H"],
        psi_f=x["flux_linkage_Wb"],
    )
    b, coulomb = x["viscous_Nms_per_rad"], x["coulomb_Nm"]
    mechanics = model.StiffMechanicalSystem(
        J=x["inertia_kgm2"],
        B_L=lambda w: b + coulomb / np.maximum(w, SMOOTHING_SPEED_RAD_S),
        tau_L=Step(x["load_step_s"], x["load_torque_Nm"]),
    )
    converter = model.VoltageSourceConverter(u_dc=x["dc_bus_V"])
    drive = model.Drive(converter, model.SynchronousMachine(par), mechanics)
    cfg = control.CurrentReferenceCfg(
        par, max_i_s=x["max_current_A"], nom_w_m=x["pole_pairs"] * x["max_speed_rad_s"]
    )
    cfg.mtpa_i_sd = lambda tau_M: 0.0 * tau_M  # id* = 0, as emasim
    ctrl = control.CurrentVectorControl(
        par,
        cfg,
        T_s=x["sample_period_s"],
        alpha_c=x["current_bandwidth_rad_s"],
        sensorless=False,
    )
    kt = 1.5 * x["pole_pairs"] * x["flux_linkage_Wb"]
    ctrl.speed_ctrl = PIController(
        k_p=x["speed_kp_A_s_per_rad"] * kt,
        k_i=x["speed_ki_A_per_rad"] * kt,
        max_u=x["max_current_A"] * kt,
    )
    ctrl.ref.w_m = Step(0.0, x["pole_pairs"] * x["speed_ref_rad_s"])  # electrical rad/s
    return model.Simulation(drive, ctrl)


def main() -> None:
    x = json.loads(sys.argv[1])
    build(x).simulate(t_stop=WARM_UP_S)
    sim = build(x)
    start = time.perf_counter()
    sim.simulate(t_stop=x["duration_s"])
    wall = time.perf_counter() - start
    speed = float(np.real(sim.mdl.mechanics.data.w_M[-1]))
    print(
        json.dumps(
            {
                "peer": "motulator",
                "version": version("motulator"),
                "duration_s": x["duration_s"],
                "wall_s": wall,
                "s_per_s": wall / x["duration_s"],
                "final_speed_rpm": speed * 30 / math.pi,
            }
        )
    )


if __name__ == "__main__":
    main()
