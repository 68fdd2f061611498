"""The assembled actuator: state layout, parameter layout and right-hand side.

Bodies: the motor rotor (with screw and nut, angle theta_m) and the load side (rod plus the
lumped rudder stage, position x_L). Between them the total drive-train backlash acts at the nut,
where the nut position is K theta_m (K from :mod:`emasim.plant.drivetrain`):

    dx = K theta_m - x_L,  dv = K wm - v_L,  Fb = dead_zone_force(dx, dv)        (N)
    J dwm/dt   = Te - B wm - Tf(wm, z) - TL(t) - reflected_torque(Fb, wm)        (N*m)
    M_L dv_L/dt = Fb - F_L(t) - c_L v_L                                           (N)
    dz/dt       = LuGre bristle rate on wm                                        (rad/s)

plus the dq current equations of :mod:`emasim.plant.motor`. With the clearance-joint linkage
(emasim.plant.linkage) in place of the lumped rudder, M_L is the rod alone, the rod feels the
linkage's axial push and the centripetal term of the swinging actuator,

    m_rod dv_L/dt = Fb + F_axial - F_L(t) - c_L v_L + m_rod r phi'^2,

and the linkage's 16 states follow the drive's rod. TL(t) is a load torque applied on
the motor shaft (the paper's TL) and F_L(t) an external force on the rod (from the rudder);
both are evaluated by the caller.
States and parameters are flat float64 arrays indexed by the constants below, which are looked
up by name in the elements' declarations (emasim.plant.element): the layouts are assembled from
:data:`ELEMENTS`, never kept by hand.
"""

import numpy as np

from ..jit import njit
from . import friction as fr
from . import linkage as L
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
from .motor import MOTOR, current_rates, electromagnetic_torque

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

# the plant's elements, in the order of the state and parameter vectors
# (optional elements last, so that a plant without them integrates only the first X_LINK)
ELEMENTS = (MOTOR, FRICTION, TRANSMISSION, BACKLASH, ROD, L.LINKAGE, COMPLIANCE)
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
X_XN = PLANT.states.index("compliance_node_position_m")
X_VN = PLANT.states.index("compliance_node_velocity_m_s")
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
P_LINK = PLANT.param_offset["linkage"]  # the linkage's parameters (emasim.plant.linkage layout)
P_LINK_END = P_LINK + L.N_LINK_PARAMS

LOAD_LUMPED = 0
LOAD_LINKAGE = 1

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
    on the rod, or on the compliance's node when the plant has one."""
    k = p[P_K]
    if p[P_COMPLIANCE] != 0.0:
        far_x, far_v = x[X_XN], x[X_VN]
    else:
        far_x, far_v = x[X_XL], x[X_VL]
    return dead_zone_force(
        k * x[X_THETA] - far_x, k * x[X_WM] - far_v, p[P_HALF_GAP], p[P_KB], p[P_CB]
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
def motor_torque(x, p):
    """Electromagnetic torque Te (N*m) of the state x."""
    return electromagnetic_torque(x[X_ID], x[X_IQ], p[P_NP], p[P_LD], p[P_LQ], p[P_PSI])


@njit(cache=True, inline="always", error_model="numpy")
def rhs(x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges):
    """Write dx/dt of the actuator into ``dx``.

    x state; (u_d, u_q) applied stator voltages (V); t_load the load torque TL on the motor
    shaft (N*m); f_load the external force F_L on the rod (N); t_rudder the load torque on the
    linkage's rudder shaft (N*m, opposing positive deflection; the lumped stage takes its rudder
    load as part of f_load); p parameters. ``hinges`` (N_HINGES x 2) receives the linkage's
    hinge penetrations and normal forces (untouched with the lumped rudder).
    """
    w = x[X_WM]
    w_e = p[P_NP] * w
    did, diq = current_rates(x[X_ID], x[X_IQ], u_d, u_q, w_e, p[P_RS], p[P_LD], p[P_LQ], p[P_PSI])
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
    dx[X_XL] = x[X_VL]
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        q = p[P_LINK:P_LINK_END]
        y, dy = x[X_LINK:X_LINK_END], dx[X_LINK:X_LINK_END]
        f_axial = L.linkage_rhs(y, x[X_XL], x[X_VL], -t_rudder, q, dy, hinges)
        swing = x[X_LINK + L.N_POS + L.PHI]
        centripetal = (q[L.L0] + x[X_XL]) * swing * swing
        dx[X_VL] = (f_rod + f_axial - f_load - p[P_CL] * x[X_VL]) / p[P_ML] + centripetal
    else:
        dx[X_VL] = (f_rod - f_load - p[P_CL] * x[X_VL]) / p[P_ML]


@njit(cache=True, inline="always", error_model="numpy")
def active_states(p):
    """How many states move: the drive's X_LINK in a plant with neither the linkage nor the
    compliance, else all (an absent element's states then stay as they are: rhs sets their
    derivatives to zero, or leaves the zeros the stages start with)."""
    if p[P_LOAD_MODEL] == LOAD_LINKAGE or p[P_COMPLIANCE] != 0.0:
        return N_STATE
    return X_LINK


@njit(cache=True, error_model="numpy")
def rudder_angle(x, p):
    """Rudder angle (rad): the linkage's rocker arm, or rod position / arm of the lumped stage."""
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        return x[X_LINK + L.TD]
    return x[X_XL] / p[P_ARM]


# --- the element outputs of the trace (PLANT.outputs), written by plant_outputs ------------
O_TORQUE = PLANT.outputs.index("torque_Nm")
O_FRICTION = PLANT.outputs.index("friction_torque_Nm")
O_DRIVETRAIN = PLANT.outputs.index("drivetrain_force_N")
O_RUDDER = PLANT.outputs.index("rudder_angle_rad")
O_COMPLIANCE = PLANT.outputs.index("compliance_force_N")
O_LINKAGE = PLANT.outputs.index(L.LINKAGE.outputs[0].name)
N_OUTPUTS = len(PLANT.outputs)
N_LINKAGE_OUTPUTS = len(L.LINKAGE.outputs)


@njit(cache=True, error_model="numpy")
def linkage_outputs(x, p, out):
    """Rod force and hinge normal forces and penetrations (linkage.LINKAGE.outputs) of state x;
    NaN with the lumped rudder stage."""
    if p[P_LOAD_MODEL] != LOAD_LINKAGE:
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
    """Write every element output of state x (layout PLANT.outputs) into ``out``."""
    out[O_TORQUE] = motor_torque(x, p)
    out[O_FRICTION] = friction(x[X_WM], x[X_Z], p)[0]
    out[O_DRIVETRAIN] = drivetrain_force(x, p)
    out[O_RUDDER] = rudder_angle(x, p)
    out[O_COMPLIANCE] = compliance_force(x, p)
    linkage_outputs(x, p, out[O_LINKAGE : O_LINKAGE + N_LINKAGE_OUTPUTS])
