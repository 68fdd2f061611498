"""The assembled actuator: state layout, parameter layout and right-hand side.

Bodies: the motor rotor (with screw and nut, angle theta_m) and the load side (rod plus the
lumped rudder stage, position x_L). Between them the total drive-train backlash acts at the nut,
where the nut position is x_h + K theta_m (K from :mod:`emasim.plant.drivetrain`, x_h the
actuator body's displacement on its anchorage, 0 without one):

    dx = x_h + K theta_m - x_L,  dv = v_h + K wm - v_L,  Fb = dead_zone_force(dx, dv)   (N)
    J dwm/dt   = Te - B wm - Tf(wm, z) - TL(t) - reflected_torque(Fb, wm)        (N*m)
    M_L dv_L/dt = Fb + F_stop - F_L(t) + T_r / r - c_L v_L                        (N)
    dz/dt       = LuGre bristle rate on wm                                        (rad/s)

plus the dq current equations of :mod:`emasim.plant.motor`. F_stop is the rod's end stops
(emasim.plant.stops) and T_r the torque on the rudder side: the rudder's stops, less the load
(the ideal T(t), or the load motor of emasim.plant.load_motor), or less the shaft's torque
when the rudder shaft's torsion (emasim.plant.shaft) carries the inertia disk. With the
clearance-joint linkage (emasim.plant.linkage) in place of the lumped rudder, M_L is the rod
alone, the rod feels the linkage's axial push and the centripetal term of the swinging
actuator, T_r acts on the linkage's rocker arm, and

    m_rod dv_L/dt = Fb + F_stop + F_axial - F_L(t) - c_L v_L + m_rod r phi'^2,

and the linkage's 16 states follow the drive's rod. The series compliance
(emasim.plant.compliance) and the anchorage (emasim.plant.anchorage) add their nodes. TL(t) is
a load torque on the motor shaft (the paper's TL), F_L(t) an external force on the rod and
T(t) the rudder load; all three are evaluated by the caller.

States and parameters are flat float64 arrays indexed by the constants below, which are looked
up by name in the elements' declarations (emasim.plant.element): the layouts are assembled from
:data:`ELEMENTS`, never kept by hand. An absent element's states stay zero.
"""

import numpy as np

from ..jit import njit
from . import friction as fr
from . import linkage as L
from .anchorage import ANCHORAGE, anchorage_force
from .backlash import BACKLASH, dead_zone_force
from .compliance import COMPLIANCE, spring_force
from .drivetrain import TRANSMISSION, reflected_torque
from .element import (
    Element,
    Quantity,
    State,
    assemble,
    rod_position_bound,
    rod_velocity_bound,
)
from .friction import FRICTION
from .load_motor import LOAD_MOTOR, load_motor_rate
from .motor import MOTOR, electromagnetic_torque, inverter_current_rates
from .ratings import RATINGS
from .shaft import RUDDER_SHAFT, shaft_torque
from .stops import END_STOPS, stop_force

ROD = Element(
    "rod",
    "the rod and the lumped rudder stage (rudder angle = rod position / arm), or the rod alone "
    "when the linkage carries the rudder",
    states=(
        State(
            "actuator_position_m",
            "m",
            "rod (load-side) position",
            atol=1e-14,
            bound=rod_position_bound,
        ),
        State("actuator_velocity_m_s", "m/s", "rod velocity", atol=1e-12, bound=rod_velocity_bound),
    ),
    params=(
        Quantity("load_mass_kg", "kg", "M_L: rod + lumped rudder, or the rod alone"),
        Quantity("load_viscous_Ns_per_m", "N s/m", "c_L"),
        Quantity("rudder_arm_m", "m", "lumped stage: rudder angle = x_L / arm"),
        Quantity("load_model", "1", "LOAD_LUMPED or LOAD_LINKAGE"),
    ),
    outputs=(Quantity("rudder_angle_rad", "rad", "rudder angle"),),
)

# the plant's elements, in the order of the state and parameter vectors (optional elements
# with states last, the linkage's 16 at the very end, so that a plant integrates only up to
# the end of its last element: active_states)
ELEMENTS = (
    MOTOR,
    FRICTION,
    TRANSMISSION,
    BACKLASH,
    ROD,
    END_STOPS,
    RATINGS,
    COMPLIANCE,
    ANCHORAGE,
    RUDDER_SHAFT,
    LOAD_MOTOR,
    L.LINKAGE,
)
PLANT = assemble(ELEMENTS)
STATE_NAMES = PLANT.states.names
N_STATE = len(PLANT.states)
N_PARAMS = len(PLANT.params)

# --- state vector: named index constants, looked up in the declarations -------------------
X_ID = PLANT.states.index("id_A")
X_IQ = PLANT.states.index("iq_A")
X_THETA = PLANT.states.index("motor_angle_rad")
X_WM = PLANT.states.index("motor_speed_rad_s")
X_Z = PLANT.states.index("bristle_state_rad")
X_XL = PLANT.states.index("actuator_position_m")
X_VL = PLANT.states.index("actuator_velocity_m_s")
X_DRIVE_END = PLANT.state_offset["compliance"]  # the states every plant integrates
X_XN = PLANT.states.index("compliance_node_position_m")
X_VN = PLANT.states.index("compliance_node_velocity_m_s")
X_XH = PLANT.states.index("housing_position_m")
X_VH = PLANT.states.index("housing_velocity_m_s")
X_DISK = PLANT.states.index("disk_angle_rad")
X_DISK_RATE = PLANT.states.index("disk_rate_rad_s")
X_TLM = PLANT.states.index("load_motor_torque_Nm")
# the rudder side (the shaft's disk, the load motor, the linkage), contiguous at the end: what
# a co-simulation's mechanism integrates (emasim.sim.mechanism)
X_MECHANISM = PLANT.state_offset["rudder_shaft"]
X_LINK = PLANT.state_offset["linkage"]  # the linkage's 16 states (idle with the lumped rudder)
X_LINK_END = X_LINK + L.N_LINK

# --- parameter vector (SI), filled by PlantParams.pack ------------------------------------
P_RS = PLANT.params.index("stator_resistance_ohm")
P_LD = PLANT.params.index("inductance_d_H")
P_LQ = PLANT.params.index("inductance_q_H")
P_PSI = PLANT.params.index("flux_linkage_Wb")
P_NP = PLANT.params.index("pole_pairs")
P_J = PLANT.params.index("rotor_inertia_kgm2")
P_B = PLANT.params.index("motor_viscous_Nms_per_rad")
P_UDC = PLANT.params.index("dc_bus_V")
P_IMAX = PLANT.params.index("max_current_A")
P_WMAX = PLANT.params.index("max_speed_rad_s")
P_K = PLANT.params.index("ratio_m_per_rad")
P_ETA = PLANT.params.index("efficiency")
P_FRICTION = PLANT.params.index("friction_model")
P_TC = PLANT.params.index("coulomb_Nm")
P_TS = PLANT.params.index("static_Nm")
P_WS = PLANT.params.index("stribeck_speed_rad_s")
P_SIGMA0 = PLANT.params.index("bristle_stiffness_Nm_per_rad")
P_SIGMA1 = PLANT.params.index("bristle_damping_Nms_per_rad")
P_SIGMA2 = PLANT.params.index("friction_viscous_Nms_per_rad")
P_W_SMOOTH = PLANT.params.index("smoothing_speed_rad_s")
P_HALF_GAP = PLANT.params.index("backlash_half_gap_m")
P_KB = PLANT.params.index("backlash_stiffness_N_per_m")
P_CB = PLANT.params.index("backlash_damping_Ns_per_m")
P_ML = PLANT.params.index("load_mass_kg")
P_CL = PLANT.params.index("load_viscous_Ns_per_m")
P_ARM = PLANT.params.index("rudder_arm_m")
P_LOAD_MODEL = PLANT.params.index("load_model")
P_COMPLIANCE = PLANT.params.index("compliance_present")
P_KS = PLANT.params.index("compliance_stiffness_N_per_m")
P_CS = PLANT.params.index("compliance_damping_Ns_per_m")
P_MN = PLANT.params.index("compliance_node_mass_kg")
P_STOPS = PLANT.params.index("end_stops_present")
P_HALF_STROKE = PLANT.params.index("stroke_half_m")
P_K_STOP = PLANT.params.index("stop_stiffness_N_per_m")
P_C_STOP = PLANT.params.index("stop_damping_Ns_per_m")
P_RUDDER_LIMIT = PLANT.params.index("rudder_limit_rad")
P_K_RUDDER_STOP = PLANT.params.index("rudder_stop_stiffness_Nm_per_rad")
P_C_RUDDER_STOP = PLANT.params.index("rudder_stop_damping_Nms_per_rad")
P_RATINGS = PLANT.params.index("ratings_present")
P_W_RATED = PLANT.params.index("rated_speed_rad_s")
P_I_CONT = PLANT.params.index("continuous_current_A")
P_HEAT_CAPACITY = PLANT.params.index("heat_capacity_A2s")
P_ANCHORAGE = PLANT.params.index("anchorage_present")
P_KA = PLANT.params.index("anchorage_stiffness_N_per_m")
P_CA = PLANT.params.index("anchorage_damping_Ns_per_m")
P_MH = PLANT.params.index("housing_mass_kg")
P_SHAFT = PLANT.params.index("shaft_present")
P_KT = PLANT.params.index("shaft_stiffness_Nm_per_rad")
P_CT = PLANT.params.index("shaft_damping_Nms_per_rad")
P_JD = PLANT.params.index("disk_inertia_kgm2")
P_LOAD_MOTOR = PLANT.params.index("load_motor_present")
P_LM_TAU = PLANT.params.index("load_motor_time_constant_s")
P_LM_SPRING = PLANT.params.index("load_motor_spring_Nm_per_rad")
P_LM_PRELOAD = PLANT.params.index("load_motor_preload_Nm")
P_LM_MAX = PLANT.params.index("load_motor_max_torque_Nm")
P_LINK = PLANT.param_offset["linkage"]  # the linkage's parameters (emasim.plant.linkage layout)
P_LINK_END = P_LINK + L.N_LINK_PARAMS

LOAD_LUMPED = 0
LOAD_LINKAGE = 1
LOAD_HELD = 2  # the rod alone; the rudder side is solved elsewhere (a co-simulation's mechanism)
# and its states are held in x between exchanges

FRICTION_NONE = 0
FRICTION_COULOMB = 1
FRICTION_LUGRE = 2


@njit(cache=True, inline="always", error_model="numpy")
def friction(w, z, p):
    """Friction torque on the motor shaft (N*m) and bristle rate dz/dt (rad/s).

    dz/dt is zero unless the LuGre model is selected.
    """
    model = int(p[P_FRICTION])
    if model == FRICTION_LUGRE:
        return fr.lugre_force(
            z, w, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0], p[P_SIGMA1], p[P_SIGMA2]
        )
    if model == FRICTION_COULOMB:
        return fr.coulomb_viscous_force(w, p[P_TC], p[P_W_SMOOTH], p[P_SIGMA2]), 0.0
    return 0.0, 0.0


@njit(cache=True, inline="always", error_model="numpy")
def bristle_step(z0, w, h, p):
    """Exact bristle update over h with the speed w held (see friction.bristle_update)."""
    if int(p[P_FRICTION]) != FRICTION_LUGRE:
        return z0
    return fr.bristle_update(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@njit(cache=True, inline="always", error_model="numpy")
def bristle_half_and_full_step(z0, w, h, p):
    """Exact bristle states after h/2 and h with the speed w held (LuGre only)."""
    if int(p[P_FRICTION]) != FRICTION_LUGRE:
        return z0, z0
    return fr.bristle_half_and_full_step(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@njit(cache=True, inline="always", error_model="numpy")
def backlash_force(x, p):
    """Contact force Fb across the backlash gap (N), positive when the screw pushes forward:
    on the rod, or on the compliance's node when the plant has one. The nut sits at
    x_h + K theta_m (x_h = 0 without the anchorage)."""
    k = p[P_K]
    if p[P_COMPLIANCE] != 0.0:
        far_x, far_v = x[X_XN], x[X_VN]
    else:
        far_x, far_v = x[X_XL], x[X_VL]
    return dead_zone_force(
        k * x[X_THETA] + x[X_XH] - far_x,
        k * x[X_WM] + x[X_VH] - far_v,
        p[P_HALF_GAP],
        p[P_KB],
        p[P_CB],
    )


@njit(cache=True, inline="always", error_model="numpy")
def compliance_force(x, p):
    """The series spring-damper's force on the rod (N); NaN without the element."""
    if p[P_COMPLIANCE] == 0.0:
        return np.nan
    return spring_force(x[X_XN], x[X_VN], x[X_XL], x[X_VL], p[P_KS], p[P_CS])


@njit(cache=True, inline="always", error_model="numpy")
def drivetrain_force(x, p):
    """The force the drive train puts on the rod (N): what a load cell on the rod reads (the
    spring's with the compliance, the gap's without)."""
    if p[P_COMPLIANCE] != 0.0:
        return compliance_force(x, p)
    return backlash_force(x, p)


@njit(cache=True, inline="always", error_model="numpy")
def rod_stop_force(x, p):
    """Force of the rod's end stops on the rod (N), on its extension relative to the body;
    0 without the stops."""
    if p[P_STOPS] == 0.0:
        return 0.0
    return stop_force(
        x[X_XL] - x[X_XH], x[X_VL] - x[X_VH], p[P_HALF_STROKE], p[P_K_STOP], p[P_C_STOP]
    )


@njit(cache=True, inline="always", error_model="numpy")
def rudder_motion(x, p):
    """Rudder (rocker arm) angle (rad) and rate (rad/s): the linkage's (integrated, or held by
    a co-simulation), or the rod's through the lumped stage's arm."""
    if p[P_LOAD_MODEL] != LOAD_LUMPED:
        return x[X_LINK + L.TD], x[X_LINK + L.N_POS + L.TD]
    return x[X_XL] / p[P_ARM], x[X_VL] / p[P_ARM]


@njit(cache=True, inline="always", error_model="numpy")
def rudder_stop_torque(theta, omega, p):
    """Torque of the rudder's stops on the rudder (N m); 0 without the stops."""
    if p[P_STOPS] == 0.0:
        return 0.0
    return stop_force(theta, omega, p[P_RUDDER_LIMIT], p[P_K_RUDDER_STOP], p[P_C_RUDDER_STOP])


@njit(cache=True, inline="always", error_model="numpy")
def shaft_torque_of(x, p):
    """Torque in the rudder shaft (N m, the torque sensor's reading); NaN without it."""
    if p[P_SHAFT] == 0.0:
        return np.nan
    theta, omega = rudder_motion(x, p)
    return shaft_torque(theta, omega, x[X_DISK], x[X_DISK_RATE], p[P_KT], p[P_CT])


@njit(cache=True, inline="always", error_model="numpy")
def rudder_side(x, t_rudder, p, dx):
    """Torque on the rocker arm (N m, driving positive deflection) from the rudder's stops
    and the load, through the shaft's torsion when the plant has it; writes the derivatives of
    the disk's and the load motor's states when the plant has any of the three (zero for an
    absent one; a plant with none leaves those rows as they are, zero in a fresh workspace).
    t_rudder is the scenario's rudder load T(t), opposing positive deflection."""
    if p[P_LOAD_MOTOR] == 0.0 and p[P_SHAFT] == 0.0 and p[P_STOPS] == 0.0:
        return -t_rudder  # the ideal load alone
    theta, omega = rudder_motion(x, p)
    if p[P_LOAD_MOTOR] != 0.0:
        at = x[X_DISK] if p[P_SHAFT] != 0.0 else theta
        dx[X_TLM] = load_motor_rate(
            x[X_TLM], t_rudder, at, p[P_LM_TAU], p[P_LM_SPRING], p[P_LM_PRELOAD], p[P_LM_MAX]
        )
        t_load = x[X_TLM]
    else:
        dx[X_TLM] = 0.0
        t_load = t_rudder
    t_stop = rudder_stop_torque(theta, omega, p)
    if p[P_SHAFT] != 0.0:
        t_shaft = shaft_torque(theta, omega, x[X_DISK], x[X_DISK_RATE], p[P_KT], p[P_CT])
        dx[X_DISK] = x[X_DISK_RATE]
        dx[X_DISK_RATE] = (t_shaft - t_load) / p[P_JD]
        return t_stop - t_shaft
    dx[X_DISK] = dx[X_DISK_RATE] = 0.0
    return t_stop - t_load


@njit(cache=True, inline="always", error_model="numpy")
def motor_torque(x, p):
    """Electromagnetic torque Te (N*m) of the state x."""
    return electromagnetic_torque(x[X_ID], x[X_IQ], p[P_NP], p[P_LD], p[P_LQ], p[P_PSI])


@njit(cache=True, inline="always", error_model="numpy")
def rhs(x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges):
    """Write dx/dt of the actuator into ``dx``.

    x state; (u_d, u_q) the stator voltages commanded of the inverter (V), applied through
    its current limit (motor.inverter_current_rates); t_load the load torque TL on the motor
    shaft (N*m); f_load the external force F_L on the rod (N); t_rudder the rudder load T(t)
    (N*m, opposing positive deflection: on the linkage's rudder shaft, or through the lumped
    stage's arm, or the load motor's command); p parameters. ``hinges`` (N_HINGES x 2)
    receives the linkage's hinge penetrations and normal forces (untouched with the lumped
    rudder).
    """
    w = x[X_WM]
    w_e = p[P_NP] * w
    did, diq = inverter_current_rates(
        x[X_ID], x[X_IQ], u_d, u_q, w_e, p[P_RS], p[P_LD], p[P_LQ], p[P_PSI], p[P_IMAX], p[P_UDC]
    )
    f_b = backlash_force(x, p)
    t_friction, z_rate = friction(w, x[X_Z], p)
    t_net = (
        motor_torque(x, p)
        - p[P_B] * w
        - t_friction
        - t_load
        - reflected_torque(f_b, w, p[P_K], p[P_ETA])
    )
    dx[X_ID] = did
    dx[X_IQ] = diq
    dx[X_THETA] = w
    dx[X_WM] = t_net / p[P_J]
    dx[X_Z] = z_rate
    f_rod = f_b
    if p[P_COMPLIANCE] != 0.0:
        f_rod = compliance_force(x, p)
        dx[X_XN] = x[X_VN]
        dx[X_VN] = (f_b - f_rod) / p[P_MN]
    else:
        dx[X_XN] = dx[X_VN] = 0.0
    f_stop = rod_stop_force(x, p)
    if p[P_ANCHORAGE] != 0.0:
        dx[X_XH] = x[X_VH]
        f_mount = anchorage_force(x[X_XH], x[X_VH], p[P_KA], p[P_CA])
        dx[X_VH] = (f_mount - f_b - f_stop) / p[P_MH]
    else:
        dx[X_XH] = dx[X_VH] = 0.0
    dx[X_XL] = x[X_VL]
    if p[P_LOAD_MODEL] == LOAD_HELD:
        for i in range(X_MECHANISM, N_STATE):
            dx[i] = 0.0
        dx[X_VL] = (f_rod + f_stop - f_load - p[P_CL] * x[X_VL]) / p[P_ML]
        return
    t_rocker = rudder_side(x, t_rudder, p, dx)
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        q = p[P_LINK:P_LINK_END]
        y, dy = x[X_LINK:X_LINK_END], dx[X_LINK:X_LINK_END]
        f_axial = L.linkage_rhs(y, x[X_XL], x[X_VL], t_rocker, q, dy, hinges)
        swing = x[X_LINK + L.N_POS + L.PHI]
        centripetal = (q[L.L0] + x[X_XL]) * swing * swing
        dx[X_VL] = (f_rod + f_stop + f_axial - f_load - p[P_CL] * x[X_VL]) / p[P_ML] + centripetal
    else:
        f_rudder = t_rocker / p[P_ARM]
        dx[X_VL] = (f_rod + f_stop - f_load + f_rudder - p[P_CL] * x[X_VL]) / p[P_ML]


@njit(cache=True, inline="always", error_model="numpy")
def active_states(p):
    """How many states move: up to the end of the plant's last element (the drive's
    X_DRIVE_END with none of the optional ones). The absent elements before it keep their
    states at zero: rhs sets their derivatives to zero. With LOAD_HELD the rudder side does
    not move in this loop: a co-simulation holds it."""
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        return N_STATE
    if p[P_LOAD_MODEL] == LOAD_LUMPED:
        if p[P_LOAD_MOTOR] != 0.0:
            return X_TLM + 1
        if p[P_SHAFT] != 0.0:
            return X_DISK_RATE + 1
    if p[P_ANCHORAGE] != 0.0:
        return X_VH + 1
    if p[P_COMPLIANCE] != 0.0:
        return X_VN + 1
    return X_DRIVE_END


@njit(cache=True, error_model="numpy")
def rudder_angle(x, p):
    """Rudder angle (rad): the linkage's rocker arm, or rod position / arm of the lumped stage."""
    return rudder_motion(x, p)[0]


@njit(cache=True, error_model="numpy")
def rod_extension(x):
    """The rod's extension relative to the actuator body (m): what its sensor reads."""
    return x[X_XL] - x[X_XH], x[X_VL] - x[X_VH]


# --- the element outputs of the trace (PLANT.outputs), written by plant_outputs ------------
O_TORQUE = PLANT.outputs.index("torque_Nm")
O_FRICTION = PLANT.outputs.index("friction_torque_Nm")
O_DRIVETRAIN = PLANT.outputs.index("drivetrain_force_N")
O_RUDDER = PLANT.outputs.index("rudder_angle_rad")
O_END_STOP = PLANT.outputs.index("end_stop_force_N")
O_RUDDER_STOP = PLANT.outputs.index("rudder_stop_torque_Nm")
O_COMPLIANCE = PLANT.outputs.index("compliance_force_N")
O_ANCHORAGE = PLANT.outputs.index("anchorage_force_N")
O_SHAFT = PLANT.outputs.index("shaft_torque_Nm")
O_LINKAGE = PLANT.outputs.index(L.LINKAGE.outputs[0].name)
N_OUTPUTS = len(PLANT.outputs)
N_LINKAGE_OUTPUTS = len(L.LINKAGE.outputs)


@njit(cache=True, error_model="numpy")
def linkage_outputs(x, p, out):
    """Rod force and hinge normal forces and penetrations (linkage.LINKAGE.outputs) of state x;
    NaN with the lumped rudder stage."""
    if p[P_LOAD_MODEL] == LOAD_LUMPED:
        out[:] = np.nan
        return
    hinges = np.empty((L.N_HINGES, 2))
    rates = np.empty(L.N_LINK)
    y, q = x[X_LINK:X_LINK_END], p[P_LINK:P_LINK_END]
    out[0] = L.linkage_rhs(y, x[X_XL], x[X_VL], 0.0, q, rates, hinges)
    for h in range(L.N_HINGES):  # hinge order in linkage.py: H1, H2, H3, H4 = 0..3
        out[1 + h] = hinges[h, 1]
        out[1 + L.N_HINGES + h] = hinges[h, 0]


@njit(cache=True, error_model="numpy")
def plant_outputs(x, p, out):
    """Write every element output of state x (layout PLANT.outputs) into ``out``; an absent
    element's outputs are NaN."""
    out[O_TORQUE] = motor_torque(x, p)
    out[O_FRICTION] = friction(x[X_WM], x[X_Z], p)[0]
    out[O_DRIVETRAIN] = drivetrain_force(x, p)
    out[O_RUDDER] = rudder_angle(x, p)
    if p[P_STOPS] != 0.0:
        theta, omega = rudder_motion(x, p)
        out[O_END_STOP] = rod_stop_force(x, p)
        out[O_RUDDER_STOP] = rudder_stop_torque(theta, omega, p)
    else:
        out[O_END_STOP] = out[O_RUDDER_STOP] = np.nan
    out[O_COMPLIANCE] = compliance_force(x, p)
    if p[P_ANCHORAGE] != 0.0:
        out[O_ANCHORAGE] = anchorage_force(x[X_XH], x[X_VH], p[P_KA], p[P_CA])
    else:
        out[O_ANCHORAGE] = np.nan
    out[O_SHAFT] = shaft_torque_of(x, p)
    linkage_outputs(x, p, out[O_LINKAGE : O_LINKAGE + N_LINKAGE_OUTPUTS])
