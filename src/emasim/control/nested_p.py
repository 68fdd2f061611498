"""Two nested proportional loops on a position encoder: the EMPS benchmark's controller.

    u_k = kv (kp (r_k - q_k) - qdot_k),    qdot_k = (qf_k - qf_{k-1}) / Ts,
    qf_k = 0.5 q_k + 0.5 q_{k-1}    so    qdot_k = (q_k - q_{k-2}) / (2 Ts)

(Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*, 2019, eq. 6 and section 2.2:
an outer position loop of gain kp (1/s) over an inner velocity loop of gain kv (V/(m/s)), the
velocity from the encoder through the 0.5/0.5 FIR and a backward difference). The command u
is in V; the drive's range limits it (emasim.sim.axis_loop).
"""

from ..jit import njit

FIR_HISTORY = 2  # the readings q_{k-1}, q_{k-2} the velocity estimate keeps


@njit(cache=True, inline="always", error_model="numpy")
def nested_p_command(history, q, r, kp, kv, ts):
    """The command u_k (V) for the reading q (m) and the reference r (m); ``history`` holds
    (q_{k-1}, q_{k-2}) and is shifted in place."""
    velocity = (q - history[1]) / (2.0 * ts)
    history[1] = history[0]
    history[0] = q
    return kv * (kp * (r - q) - velocity)
