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

Each element declares these terms itself (its bodies, couplings, laws, forces and rates:
emasim.plant.element); :data:`rhs`, :data:`plant_outputs` and :data:`active_states` are
generated from :data:`ELEMENTS` by emasim.plant.assembly. States and parameters are flat
float64 arrays whose indices are looked up by name in the same declarations. An absent
element's states stay zero.
"""

from ..jit import njit
from . import friction as fr
from . import linkage as L
from .anchorage import ANCHORAGE
from .assembly import load
from .backlash import BACKLASH
from .compliance import COMPLIANCE
from .drivetrain import TRANSMISSION
from .element import (
    Body,
    Element,
    Law,
    Quantity,
    State,
    assemble,
    rod_position_bound,
    rod_velocity_bound,
    total,
    viscous_force,
)
from .friction import FRICTION
from .linkage import LOAD_HELD, LOAD_LINKAGE, LOAD_LUMPED  # noqa: F401 - part of this API
from .load_motor import LOAD_MOTOR
from .motor import MOTOR
from .ratings import RATINGS
from .shaft import RUDDER_SHAFT
from .stops import END_STOPS

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
    outputs=(
        Quantity("rudder_angle_rad", "rad", "rudder angle"),
        Quantity("drivetrain_force_N", "N", "force of the drive train on the rod"),
    ),
    # M_L dv_L/dt = F_drive + F_stop + F_axial - F_L + F_lever - c_L v_L (+ r phi'^2 M_L)
    bodies=(
        Body(
            "rod",
            "actuator_position_m",
            "actuator_velocity_m_s",
            "load_mass_kg",
            order=(
                "fold_far",
                "compliance",
                "end_stops",
                "linkage__axial",
                "f_load",
                "linkage__lever",
                "rod",
            ),
        ),
    ),
    laws=(
        Law(viscous_force, ("p.load_viscous_Ns_per_m", "rod.v"), ("viscous",)),
        # what a load cell on the rod reads: the compliance spring's push, or without the
        # compliance what the gap passes on to the rod
        Law(total, ("far|rod.fold", "-compliance.force"), ("drive_force",), always=True),
    ),
    forces=(("rod", "-in.f_load"), ("rod", "-viscous")),
    values=(("rudder_angle_rad", "rocker.x"), ("drivetrain_force_N", "drive_force")),
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
GENERATED = load(PLANT, hold=("load_model", LOAD_HELD))
rhs = GENERATED.rhs  # (x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges): dx/dt of x
plant_outputs = GENERATED.plant_outputs  # (x, p, out): every element output of x
active_states = GENERATED.active_states  # (p): the states that move
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

FRICTION_NONE = fr.FRICTION_NONE
FRICTION_COULOMB = fr.FRICTION_COULOMB
FRICTION_LUGRE = fr.FRICTION_LUGRE


@njit(cache=True, inline="always", error_model="numpy")
def bristle_step(z0, w, h, p):
    """Exact bristle update over h with the speed w held (see friction.bristle_update)."""
    if p[P_FRICTION] != FRICTION_LUGRE:
        return z0
    return fr.bristle_update(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@njit(cache=True, inline="always", error_model="numpy")
def bristle_half_and_full_step(z0, w, h, p):
    """Exact bristle states after h/2 and h with the speed w held (LuGre only)."""
    if p[P_FRICTION] != FRICTION_LUGRE:
        return z0, z0
    return fr.bristle_half_and_full_step(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


def output(name: str):
    """The compiled ``(x, p) -> value`` of one element output (a column of PLANT.outputs)."""
    return getattr(GENERATED, f"output_{name}")


drivetrain_force = output("drivetrain_force_N")  # (x, p): what a load cell on the rod reads
rudder_angle = output("rudder_angle_rad")  # (x, p): the rocker arm's angle (rad)


@njit(cache=True, error_model="numpy")
def rod_extension(x):
    """The rod's extension relative to the actuator body (m): what its sensor reads."""
    return x[X_XL] - x[X_XH], x[X_VL] - x[X_VH]


N_OUTPUTS = len(PLANT.outputs)
