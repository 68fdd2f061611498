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
States and parameters are flat float64 arrays indexed by the constants below.
"""

import numba as nb
import numpy as np

from . import friction as fr
from . import linkage as L
from .backlash import dead_zone_force
from .drivetrain import reflected_torque
from .motor import current_rates, electromagnetic_torque

# --- state vector -------------------------------------------------------------------------
X_ID = 0  # d-axis current, A
X_IQ = 1  # q-axis current, A
X_THETA = 2  # motor angle, rad
X_WM = 3  # motor mechanical speed, rad/s
X_Z = 4  # LuGre bristle deflection, rad
X_XL = 5  # rod (load-side) position, m
X_VL = 6  # rod velocity, m/s
X_LINK = 7  # first of the linkage's states (zero and idle with the lumped rudder)
N_STATE = X_LINK + L.N_LINK
STATE_NAMES = (
    "id_A",
    "iq_A",
    "motor_angle_rad",
    "motor_speed_rad_s",
    "bristle_state_rad",
    "actuator_position_m",
    "actuator_velocity_m_s",
    *L.LINK_STATE_NAMES,
)

# --- parameter vector (SI), filled by PlantParams.pack ------------------------------------
P_RS = 0  # stator resistance, ohm
P_LD = 1  # d inductance, H
P_LQ = 2  # q inductance, H
P_PSI = 3  # PM flux linkage, Wb
P_NP = 4  # pole pairs
P_J = 5  # rotor inertia, kg m^2
P_B = 6  # motor viscous damping, N m s/rad
P_K = 7  # rod metres per motor radian, m/rad
P_ETA = 8  # drive-train efficiency (gear * screw)
P_FRICTION = 9  # friction model code (FRICTION_*)
P_TC = 10  # Coulomb torque, N m
P_TS = 11  # stiction torque, N m
P_WS = 12  # Stribeck speed, rad/s
P_SIGMA0 = 13  # bristle stiffness, N m/rad
P_SIGMA1 = 14  # bristle damping, N m s/rad
P_SIGMA2 = 15  # viscous friction, N m s/rad
P_W_SMOOTH = 16  # smoothing speed of the Coulomb map, rad/s
P_HALF_GAP = 17  # backlash half-width b, m
P_KB = 18  # backlash contact stiffness, N/m
P_CB = 19  # backlash contact damping, N s/m
P_ML = 20  # load-side mass, kg
P_CL = 21  # load-side viscous damping, N s/m
P_ARM = 22  # rudder arm, m (rudder angle = x_L / arm)
P_UDC = 23  # DC-link voltage, V
P_LOAD_MODEL = 24  # LOAD_LUMPED or LOAD_LINKAGE
P_LINK = 25  # first of the linkage's parameters (emasim.plant.linkage layout)
N_PARAMS = P_LINK + L.N_LINK_PARAMS

LOAD_LUMPED = 0
LOAD_LINKAGE = 1

FRICTION_NONE = 0
FRICTION_COULOMB = 1
FRICTION_LUGRE = 2


@nb.njit(cache=True, error_model="numpy")
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


@nb.njit(cache=True, error_model="numpy")
def bristle_step(z0, w, h, p):
    """Exact bristle update over h with the speed w held (see friction.bristle_update)."""
    if int(p[P_FRICTION]) != FRICTION_LUGRE:
        return z0
    return fr.bristle_update(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@nb.njit(cache=True, error_model="numpy")
def bristle_half_and_full_step(z0, w, h, p):
    """Exact bristle states after h/2 and h with the speed w held (LuGre only)."""
    if int(p[P_FRICTION]) != FRICTION_LUGRE:
        return z0, z0
    return fr.bristle_half_and_full_step(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@nb.njit(cache=True, error_model="numpy")
def backlash_force(x, p):
    """Drive-train contact force Fb (N), positive when the nut pushes the rod forward."""
    k = p[P_K]
    dx = k * x[X_THETA] - x[X_XL]
    dv = k * x[X_WM] - x[X_VL]
    return dead_zone_force(dx, dv, p[P_HALF_GAP], p[P_KB], p[P_CB])


@nb.njit(cache=True, error_model="numpy")
def motor_torque(x, p):
    """Electromagnetic torque Te (N*m) of the state x."""
    return electromagnetic_torque(x[X_ID], x[X_IQ], p[P_NP], p[P_LD], p[P_LQ], p[P_PSI])


@nb.njit(cache=True, error_model="numpy")
def rhs(x, u_d, u_q, t_load, f_load, t_rudder, p, dx):
    """Write dx/dt of the actuator into ``dx``.

    x state; (u_d, u_q) applied stator voltages (V); t_load the load torque TL on the motor
    shaft (N*m); f_load the external force F_L on the rod (N); t_rudder the load torque on the
    linkage's rudder shaft (N*m, opposing positive deflection; the lumped stage takes its rudder
    load as part of f_load); p parameters.
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
    dx[X_XL] = x[X_VL]
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        q = p[P_LINK:]
        hinges = np.empty((L.N_HINGES, 2))
        f_axial = L.linkage_rhs(x[X_LINK:], x[X_XL], x[X_VL], -t_rudder, q, dx[X_LINK:], hinges)
        swing = x[X_LINK + L.N_POS + L.PHI]
        centripetal = (q[L.L0] + x[X_XL]) * swing * swing
        dx[X_VL] = (f_b + f_axial - f_load - p[P_CL] * x[X_VL]) / p[P_ML] + centripetal
    else:
        dx[X_VL] = (f_b - f_load - p[P_CL] * x[X_VL]) / p[P_ML]


@nb.njit(cache=True, inline="always", error_model="numpy")
def active_states(p):
    """How many states move: all with the linkage, the drive's X_LINK without (the linkage's
    states then stay as they are and rhs leaves their derivatives untouched)."""
    return N_STATE if p[P_LOAD_MODEL] == LOAD_LINKAGE else X_LINK


@nb.njit(cache=True, error_model="numpy")
def rudder_angle(x, p):
    """Rudder angle (rad): the linkage's rocker arm, or rod position / arm of the lumped stage."""
    if p[P_LOAD_MODEL] == LOAD_LINKAGE:
        return x[X_LINK + L.TD]
    return x[X_XL] / p[P_ARM]
