"""The controllers' laws in continuous time, as python-control blocks (emasim.linear).

The current PI with its decoupling, linearised at (w0, iq0); the PID of emasim.control.pid
(the speed PI being the same law with Kd = 0); the sample-and-hold and computation delay as a
Pade approximant of order PADE_ORDER; and the combination of a loop's responses to the
reference and its rates, T(s) = sum_k s^k T_k(s) (:func:`with_rates`).
"""

import control
import numpy as np

from . import current as cur
from . import pid

PADE_ORDER = 3  # of the delay's approximant: within 1e-5 rad of its phase up to 1 / (Td + Ts/2)


def current_loop(params: np.ndarray, w0: float, iq0: float) -> control.StateSpace:
    """The current PI with its decoupling, linearised: (iq*, id, iq, wm) -> (ud*, uq*)."""
    kp_d, kp_q, ki_d, ki_q = params[[cur.KP_D, cur.KP_Q, cur.KI_D, cur.KI_Q]]
    ld, lq, psi, n_p = params[[cur.LD, cur.LQ, cur.PSI, cur.NP]]
    b = [[0.0, -ki_d, 0.0, 0.0], [ki_q, 0.0, -ki_q, 0.0]]
    d = [
        [0.0, -kp_d, -n_p * lq * w0, -n_p * lq * iq0],
        [kp_q, n_p * ld * w0, -kp_q, n_p * psi],
    ]
    return control.ss(
        np.zeros((2, 2)),
        b,
        np.eye(2),
        d,
        inputs=["iq_ref", "id_A", "iq_A", "motor_speed_rad_s"],
        outputs=["ud", "uq"],
        states=["integral_d", "integral_q"],
        name="current_pi",
    )


def pade_delay(seconds: float, axis: str) -> control.StateSpace:
    """The Pade approximant of the delay from the commanded to the applied voltage: that of
    a unit delay, P1(s), in time scaled by the delay, P(s) = P1(s T) (a well-scaled
    realisation: its matrices are of order 1/T, not 1/T^n)."""
    unit = control.ss(control.tf(*control.pade(1.0, PADE_ORDER)))
    return control.ss(
        unit.A / seconds,
        unit.B / seconds,
        unit.C,
        unit.D,
        inputs=[f"u{axis}"],
        outputs=[f"v{axis}"],
        name=f"delay_{axis}",
    )


def pid_law(
    params: np.ndarray, ref: str, measured: str, command: str, name: str
) -> control.StateSpace:
    """The law of emasim.control.pid.pid in continuous time: inputs (ref, its rate and its
    acceleration, the measurement), outputs (command, its rate). The filtered derivative of
    v = c r - y (c the set-point weight), Kd s / (1 + Tf s) v, is Kd/Tf v + xi with
    Tf dxi/dt = -Kd/Tf v - xi."""
    kp, ki, kd, tf, kff, w = params[[pid.KP, pid.KI, pid.KD, pid.TF, pid.KFF, pid.D_WEIGHT]]
    a = [[0.0, 0.0], [0.0, -1.0 / tf]]
    b = [[ki, 0.0, 0.0, -ki], [-w * kd / tf**2, 0.0, 0.0, kd / tf**2]]
    c = [[1.0, 1.0], [0.0, 0.0]]
    d = [[kp + w * kd / tf, kff, 0.0, -kp - kd / tf], [0.0, 0.0, kff, 0.0]]
    states = ["integral", "derivative"]
    if kd == 0.0:  # a PI: no derivative state
        a, b, c, states = [[0.0]], [b[0]], [[1.0], [0.0]], states[:1]
    return control.ss(
        a,
        b,
        c,
        d,
        inputs=[ref, f"{ref}_rate", f"{ref}_accel", measured],
        outputs=[command, f"{command}_rate"],
        states=states,
        name=name,
    )


def with_rates(loop: control.StateSpace) -> tuple[np.ndarray, ...]:
    """(A, B, C, D) of T(s) = sum_k s^k T_k(s), T_k the loop from its input k (the k-th
    derivative of the reference) to its one output.

    With T_k = C (sI - A)^-1 b_k + d_k, s^k C (sI - A)^-1 b_k = sum_{j<k} s^(k-1-j) C A^j b_k
    + C A^k (sI - A)^-1 b_k, so T has the same A and C, B = sum_k A^k b_k and
    D = d_0 + sum_{k>=1} C A^(k-1) b_k, provided the rest of the polynomial vanishes: d_k = 0
    and C A^j b_k = 0 for j < k - 1 (the output lags the reference's derivatives by the
    current loop and the inertia; checked).
    """
    a, b, c, d = loop.A, loop.B, loop.C, loop.D
    b_total, d_total = b[:, :1].copy(), d[:, :1].copy()
    for k in range(1, b.shape[1]):
        powers = [np.linalg.matrix_power(a, j) for j in range(k + 1)]
        rest = [d[0, k]] + [(c @ powers[j] @ b[:, k]).item() for j in range(k - 1)]
        if any(value != 0.0 for value in rest):
            raise ArithmeticError(f"the loop's response to d^{k}r/dt^{k} is not proper")
        b_total += powers[k] @ b[:, k : k + 1]
        d_total += c @ powers[k - 1] @ b[:, k : k + 1]
    return a, b_total, c, d_total
