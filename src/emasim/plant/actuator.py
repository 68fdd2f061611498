"""The assembled actuator: its elements, their layouts and the generated right-hand side.

The elements (one module each in emasim.plant.elements) lay out the plant from the motor
outward: the PMSM and its rotor (motor), the friction on its shaft, the gearbox and roller
screw that move the nut with the shaft (transmission, a node that follows the screw), the
backlash gap between the nut and what lies beyond it, the rod with the lumped rudder stage
(rod), the end stops, the drive's ratings, and the optional series compliance (a node
between the gap and the rod), anchorage (the body the nut and the rod's stops ride on),
rudder shaft torsion (the inertia disk behind the rocker arm), load motor (on the disk) and
clearance-joint linkage (the rocker arm's motion in place of the lumped stage's x_L / r).
Each module states its own equations; the scenario's loads (TL on the motor shaft, F_L on
the rod, T(t) on the rudder side) are evaluated by the caller.

Each element declares its terms (its bodies, couplings, laws, forces and rates:
emasim.plant.element); :data:`rhs`, :data:`plant_outputs` and :data:`active_states` are
generated from :data:`ELEMENTS` by emasim.plant.assembly. States and parameters are flat
float64 arrays whose indices are looked up by name in the same declarations. An absent
element's states stay zero.
"""

from ..jit import njit
from .assembly import load
from .element import assemble, ordered
from .elements import discover
from .elements import friction as fr
from .elements import linkage as L
from .elements.linkage import LOAD_HELD, LOAD_LINKAGE, LOAD_LUMPED  # noqa: F401 - this API

# the plant's elements (every module of emasim.plant.elements), in the order of the state and
# parameter vectors: each after the element it names, the mechanism's last (optional elements
# with states after the drive's, the linkage's 16 at the very end: active_states)
ELEMENTS = ordered(discover())
PLANT = assemble(ELEMENTS)
HOLD = ("load_model", LOAD_HELD)  # the rudder side held (a co-simulation integrates it)
GENERATED = load(PLANT, hold=HOLD)
rhs = GENERATED.rhs  # (x, u_d, u_q, t_load, f_load, t_rudder, p, dx, hinges): dx/dt of x
plant_outputs = GENERATED.plant_outputs  # (x, p, out): every element output of x
active_states = GENERATED.active_states  # (p): the states that move
# the drive alone: every plant without the optional elements that own states (compliance,
# anchorage, gear mesh, rudder shaft, load motor, linkage), whose rhs runs without their
# presence tests; DRIVE.applies(p) tells whether the plant of p is one
DRIVE = load(
    PLANT,
    hold=HOLD,
    absent=frozenset(e.name for e in ELEMENTS if e.presence is not None and e.states),
)
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
P_HALF_STROKE = PLANT.params.index("stroke_half_m")
P_K_STOP = PLANT.params.index("stop_stiffness_N_per_m")
P_C_STOP = PLANT.params.index("stop_damping_Ns_per_m")
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
P_LM_TAU = PLANT.params.index("load_motor_time_constant_s")
# the linkage's parameters (emasim.plant.elements.linkage layout)
P_LINK = PLANT.param_offset["linkage"]
P_LINK_END = P_LINK + L.N_LINK_PARAMS


@njit(cache=True, inline="always", error_model="numpy")
def bristle_step(z0, w, h, p):
    """Exact bristle update over h with the speed w held (see friction.bristle_update)."""
    if p[P_FRICTION] != fr.FRICTION_LUGRE:
        return z0
    return fr.bristle_update(z0, w, h, p[P_TC], p[P_TS], p[P_WS], p[P_SIGMA0])


@njit(cache=True, inline="always", error_model="numpy")
def bristle_half_and_full_step(z0, w, h, p):
    """Exact bristle states after h/2 and h with the speed w held (LuGre only)."""
    if p[P_FRICTION] != fr.FRICTION_LUGRE:
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
