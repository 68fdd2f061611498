"""emasim's speed-step on gym-electric-motor 3.0.3: the peer's wall seconds per simulated second.

    python gem_speed_step.py EXPERIMENT_JSON      # prints one JSON line

Run by ``benchmarks/bench_peers.py`` in the peers' own virtual environment, never emasim's.
EXPERIMENT_JSON is the experiment bench_peers.py reads from emasim's ``speed-step`` scenario
(``bench_peers.experiment``).

Matches emasim: the PMSM (pole pairs, Rs, Ld, Lq, flux linkage), the motor's inertia and the
load's reflected onto the shaft, the viscous friction (motor, friction model and rod,
reflected) and the 0.3 N*m Coulomb friction (the static load's ``a``), the 560 V bus, the
58 A current limit, the 10 kHz control rate (``tau``), the 1000 rpm speed step at 0, the
10 N*m load step at 0.4 s (``a`` raised by 10 N*m between two steps) and the simulated
duration; the controllers are emasim's laws with emasim's gains, written out here in plain
Python: a PI speed loop (back-calculation anti-windup, iq* limited to 58 A) over a dq PI
current loop with decoupling (500 Hz internal-model gains, id* = 0), acting in dq through
gem's ``DqToAbcActionProcessor``.

Differs: the mechanics are one rigid inertia (no backlash, no LuGre bristle state, no rod and
rudder masses of their own); the dq voltage is limited to |u| <= Udc/2, what gem's B6 bridge
gives without zero-sequence injection (emasim's SVPWM: Udc/sqrt(3); the run needs far
less); the episode's current constraint is off so that no transient ends the run; gem's
default ODE solver (scipy's dopri5, one call per step).
gem_controllers (shipped with 3.0.3) cannot be used: ``GemController.make`` fails for every
PMSM speed or torque environment (its squared clipping stage has no action range).

Timed: ``controller`` and ``env.step`` over the whole duration, after the environment is built
and warmed up by a few steps and reset.
"""

import json
import math
import sys
import time
from importlib.metadata import version

import gym_electric_motor as gem
import numpy as np
from gym_electric_motor.physical_system_wrappers import DqToAbcActionProcessor
from gym_electric_motor.physical_systems.mechanical_loads import PolynomialStaticLoad
from gym_electric_motor.reference_generators import ConstReferenceGenerator

ENV_ID = "Cont-SC-PMSM-v0"
WARM_UP_STEPS = 10


def build(x: dict):
    omega_max = x["max_speed_rad_s"]
    load = PolynomialStaticLoad(
        load_parameter=dict(
            a=x["coulomb_Nm"], b=x["viscous_Nms_per_rad"], c=0.0, j_load=x["load_inertia_kgm2"]
        ),
        limits=dict(omega=omega_max),
    )
    limits = dict(i=x["max_current_A"], omega=omega_max, u=x["dc_bus_V"])
    motor = dict(
        motor_parameter=dict(
            p=x["pole_pairs"],
            r_s=x["resistance_ohm"],
            l_d=x["inductance_d_H"],
            l_q=x["inductance_q_H"],
            psi_p=x["flux_linkage_Wb"],
            j_rotor=x["motor_inertia_kgm2"],
        ),
        limit_values=limits,
        nominal_values=limits,
    )
    env = gem.make(
        ENV_ID,
        motor=motor,
        load=load,
        supply=dict(u_nominal=x["dc_bus_V"]),
        tau=x["sample_period_s"],
        reference_generator=ConstReferenceGenerator("omega", x["speed_ref_rad_s"] / omega_max),
        physical_system_wrappers=(DqToAbcActionProcessor.make("PMSM"),),
        constraints=(),
    )
    return env, load


def make_controller(env, x: dict):
    """emasim's speed PI over its current PI (src/emasim/control/pid.py, current.py), on gem's
    normalised state; returns control(state) -> the normalised dq voltage action."""
    names, limits = env.get_wrapper_attr("state_names"), env.get_wrapper_attr("limits")
    w_i, d_i, q_i = (names.index(n) for n in ("omega", "i_sd", "i_sq"))
    w_lim, i_lim, u_lim = limits[w_i], limits[d_i], limits[names.index("u_sd")]
    ts, ref, i_max = x["sample_period_s"], x["speed_ref_rad_s"], x["max_current_A"]
    kp, ki = x["speed_kp_A_s_per_rad"], x["speed_ki_A_per_rad"]
    alpha, ld, lq = x["current_bandwidth_rad_s"], x["inductance_d_H"], x["inductance_q_H"]
    kp_d, kp_q, ki_c = alpha * ld, alpha * lq, alpha * x["resistance_ohm"]
    psi, p = x["flux_linkage_Wb"], x["pole_pairs"]
    integral = [0.0, 0.0, 0.0]  # speed, d, q

    def control(state):
        w, i_d, i_q = state[w_i] * w_lim, state[d_i] * i_lim, state[q_i] * i_lim
        e = ref - w
        u = kp * e + integral[0]
        iq_ref = min(max(u, -i_max), i_max)
        integral[0] += ts * (ki * e + ki / kp * (iq_ref - u))
        w_e = p * w
        e_d, e_q = -i_d, iq_ref - i_q
        ud_req = kp_d * e_d + integral[1] - w_e * lq * i_q
        uq_req = kp_q * e_q + integral[2] + w_e * (ld * i_d + psi)
        scale = min(1.0, u_lim / max(math.hypot(ud_req, uq_req), 1e-12))
        u_d, u_q = scale * ud_req, scale * uq_req
        integral[1] += ts * ki_c * (e_d + (u_d - ud_req) / kp_d)
        integral[2] += ts * ki_c * (e_q + (u_q - uq_req) / kp_q)
        return np.array([u_d / u_lim, u_q / u_lim])

    def reset():
        integral[:] = [0.0, 0.0, 0.0]

    return control, reset


def set_load(load, torque_Nm: float) -> None:
    """The static load's constant term (N*m), with its smoothing about zero speed."""
    load._a = torque_Nm
    load._omega_lim = torque_Nm / load._j_total * load.tau_decay


def run(env, load, control, reset, x: dict, steps: int) -> float:
    """``steps`` control periods from rest, the load stepping up on the way; the final speed
    in rad/s."""
    (state, _), _ = env.reset()
    reset()
    set_load(load, x["coulomb_Nm"])
    load_step = round(x["load_step_s"] / x["sample_period_s"])
    for k in range(steps):
        if k == load_step:
            set_load(load, x["coulomb_Nm"] + x["load_torque_Nm"])
        (state, _), _, _, _, _ = env.step(control(state))
    return float(state[0] * x["max_speed_rad_s"])


def main() -> None:
    x = json.loads(sys.argv[1])
    env, load = build(x)
    control, reset = make_controller(env, x)
    run(env, load, control, reset, x, WARM_UP_STEPS)
    steps = round(x["duration_s"] / x["sample_period_s"])
    start = time.perf_counter()
    speed = run(env, load, control, reset, x, steps)
    wall = time.perf_counter() - start
    simulated = steps * x["sample_period_s"]
    print(
        json.dumps(
            {
                "peer": "gym-electric-motor",
                "version": version("gym-electric-motor"),
                "duration_s": simulated,
                "wall_s": wall,
                "s_per_s": wall / simulated,
                "final_speed_rpm": speed * 30 / math.pi,
            }
        )
    )


if __name__ == "__main__":
    main()
