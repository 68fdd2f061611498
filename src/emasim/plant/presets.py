"""Named parameter sets: the paper's motor, the SEA805 actuator and our lumped rudder stage.

Every number is here, once, with where it comes from. "paper" means Ding & Zhou, Actuators 2025,
14(11), 526; "ours" means the paper is silent and the value is our engineering choice (see
"Our assumptions" in docs/model.md). Scenario files start from :data:`PRESETS` and override
fields.
"""

import math

from .contact import ContactParams
from .element import damping_for_ratio
from .elements.anchorage import AnchorageParams
from .elements.compliance import ComplianceParams
from .elements.drivetrain import transmission_ratio
from .elements.gear_mesh import GearMeshParams
from .elements.linkage import LinkageParams
from .elements.load_motor import LoadMotorParams
from .elements.ratings import RatingsParams
from .elements.shaft import ShaftParams
from .elements.stops import EndStopParams
from .parameters import (
    BacklashParams,
    DrivetrainParams,
    FrictionParams,
    LoadParams,
    MotorParams,
    PlantParams,
    SensorChannel,
    SensorParams,
)


def paper_motor() -> MotorParams:
    """The paper's speed-loop PMSM (section 2.3.1), with the SEA805 drive's limits."""
    return MotorParams(
        resistance_ohm=0.0485,  # paper
        inductance_d_H=3.752e-4,  # paper
        inductance_q_H=4.148e-4,  # paper
        flux_linkage_Wb=0.1194,  # paper ("leakage flux coefficient")
        inertia_kgm2=0.0027,  # paper
        viscous_Nms_per_rad=4.924e-4,  # paper
        pole_pairs=4,  # paper
        dc_bus_V=560.0,  # paper
        max_current_A=58.0,  # paper, section 3: the SEA805 motor's drive current
        max_speed_rpm=3000.0,  # ours: above the 1800 rpm that the rated 240 mm/s needs
    )


def sea805_drivetrain() -> DrivetrainParams:
    """SEA805 electromechanical actuator (paper section 3): direct drive onto an 8 mm lead PRSM."""
    return DrivetrainParams(
        gear_ratio=1.0,  # paper: the EAS has no variable-speed stage between motor and screw
        gear_efficiency=1.0,
        screw_lead_mm=8.0,  # paper
        screw_efficiency=0.9,  # ours: typical planetary roller screw efficiency
        stroke_mm=250.0,  # paper
    )


def motor_lugre_friction() -> FrictionParams:
    """LuGre friction on the motor/screw shaft (ours: the paper gives no values).

    Coulomb 0.3 N*m and stiction 0.45 N*m (about 1 % of the 41 N*m peak torque), Stribeck speed
    1 rad/s, bristle stiffness 1500 N*m/rad (presliding travel Tc/sigma0 = 0.2 mrad), critically
    damped bristle mode. The bristle eigenvalue is then about -5e5 1/s at 1000 rpm.
    """
    return FrictionParams(
        model="lugre",
        coulomb_Nm=0.3,
        static_Nm=0.45,
        stribeck_speed_rad_s=1.0,
        bristle_stiffness_Nm_per_rad=1500.0,
        bristle_damping_ratio=1.0,
        viscous_Nms_per_rad=1e-3,
        smoothing_speed_rad_s=0.1,
    )


def drivetrain_backlash() -> BacklashParams:
    """Total backlash of screw and joints: the paper's 0.1 mm width (Fig. 8), our stiffness."""
    return BacklashParams(
        width_mm=0.1,  # paper, position-loop simulation
        stiffness_N_per_m=1.0e8,  # ours: 100 N/um, typical PRSM + mount axial stiffness
        damping_ratio=0.1,  # ours: lets impacts settle within a few contact periods
    )


def lumped_rudder() -> LoadParams:
    """Lumped rudder stage until the linkage lands (ours).

    The arm maps +-125 mm of rod travel to +-30 deg of rudder (125 mm / (pi/6) = 238.7 mm).
    The rudder shaft with its inertia disk is 1.5 kg*m^2 (26 kg at the rod), the rod 3 kg.
    """
    return LoadParams(
        rod_mass_kg=3.0,
        rudder_arm_mm=238.73,
        rudder_inertia_kgm2=1.5,
        viscous_Ns_per_m=50.0,
    )


def paper_hinge_contact() -> ContactParams:
    """The paper's Table 1: ADAMS IMPACT contact and Coulomb friction at hinges 1-4."""
    return ContactParams(
        stiffness_N_per_mm_e=1.0e5,
        exponent=2.2,
        damping_Ns_per_mm=10.0,
        penetration_depth_mm=0.1,
        mu_static=0.3,
        mu_dynamic=0.1,
        stiction_speed_mm_s=100.0,
        dynamic_speed_mm_s=1000.0,
    )


def reference_linkage(clearance_mm: float = 0.01) -> LinkageParams:
    """Our reference geometry (the paper shows only a picture).

    The auxiliary rocker B and the rocker arm D have equal 200 mm arms, and the 500 mm link
    joins them into a parallelogram, so the rudder turns with B. The rod pushes B's other arm
    (250 mm, hanging down) nearly square at mid stroke, so +-125 mm of rod travel turns the
    rudder by about +-30 deg (sin 30 deg = 125/250). The actuator swings about A0, 800 mm behind
    the rod end. Masses: a 15 kg actuator body about its pivot (4 kg m^2), a 3 kg rod, 2.5 kg
    rocker, 1.5 kg link, and the rudder with its inertia disk, 1.5 kg m^2 as in the lumped stage.
    Pins of 10 mm radius, every hinge with the paper's 0.01 mm clearance and Table 1 contact.
    """
    return LinkageParams(
        actuator_pivot_mm=(-800.0, -750.0),
        rocker_pivot_mm=(0.0, -500.0),
        rudder_shaft_mm=(0.0, 0.0),
        rod_length_mm=800.0,
        actuator_inertia_kgm2=4.0,
        rod_mass_kg=3.0,
        rocker_mass_kg=2.5,
        rocker_inertia_kgm2=0.03,
        rocker_arm_1_mm=250.0,
        rocker_arm_2_mm=200.0,
        link_mass_kg=1.5,
        link_inertia_kgm2=0.031,
        link_length_mm=500.0,
        rudder_inertia_kgm2=1.5,
        rudder_arm_mm=200.0,
        rudder_damping_Nms_per_rad=0.0,
        pin_radius_mm=10.0,
        hinge_clearance_mm=(clearance_mm,) * 4,
        contact=paper_hinge_contact(),
    )


STOP_DAMPING_RATIO = 0.2  # ours: a hard stop with an elastomer face rebounds at e = 0.53


def sea805_end_stops() -> EndStopParams:
    """The stops at the ends of the SEA805's 250 mm stroke, and the rudder's travel limits.

    Rod stops (ours): as stiff as the screw's axial path, 100 N/um; damped at zeta = 0.2 on
    the motor's inertia seen at the rod, J / K^2 = 1665 kg, which dominates what hits the stop.
    Rudder stops (ours): at 35 deg, 5 deg beyond the 30 deg that the stroke gives, so that the
    rod's stops act first; 1e6 N m/rad, damped at zeta = 0.2 on the drive's inertia seen at the
    rudder through the 238.7 mm arm (95 kg m^2).
    """
    motor, drivetrain, rudder = paper_motor(), sea805_drivetrain(), lumped_rudder()
    k = transmission_ratio(drivetrain.screw_lead_mm * 1e-3, drivetrain.gear_ratio)
    motor_mass = motor.inertia_kgm2 / k**2
    arm = rudder.rudder_arm_mm * 1e-3
    return EndStopParams(
        stiffness_N_per_m=1.0e8,
        damping_Ns_per_m=damping_for_ratio(STOP_DAMPING_RATIO, 1.0e8, motor_mass),
        rudder_limit_deg=35.0,
        rudder_stiffness_Nm_per_rad=1.0e6,
        rudder_damping_Nms_per_rad=damping_for_ratio(
            STOP_DAMPING_RATIO, 1.0e6, motor_mass * arm**2
        ),
    )


def sea805() -> PlantParams:
    """The paper's motor on the SEA805 drive train, LuGre friction, 0.1 mm backlash, rudder,
    and the end stops of its stroke."""
    return PlantParams(
        motor=paper_motor(),
        drivetrain=sea805_drivetrain(),
        friction=motor_lugre_friction(),
        backlash=drivetrain_backlash(),
        load=lumped_rudder(),
        end_stops=sea805_end_stops(),
    )


def sea805_stand() -> PlantParams:
    """sea805 on a motor test stand: the motor and its load with no travel limit (no end
    stops), for the speed-loop experiments (paper Figs. 5-6), whose rod would run past the
    stroke."""
    return sea805().model_copy(update={"end_stops": None})


def sea805_linkage(clearance_mm: float = 0.01) -> PlantParams:
    """sea805 with the clearance-joint linkage in place of the lumped rudder stage."""
    return sea805().model_copy(update={"linkage": reference_linkage(clearance_mm)})


def sea805_ratings() -> RatingsParams:
    """The SEA805's rated limits: 240 mm/s at the 8 mm lead is 1800 rpm (paper section 3);
    ours: a continuous current of 20 A, a third of the 58 A peak (a servo motor's usual 3:1),
    the peak for 2 s from cold."""
    return RatingsParams(rated_speed_rpm=1800.0, continuous_current_A=20.0, peak_current_s=2.0)


LOADER_RATED_TORQUE_NM = 94.5  # the LAFERT B132I load motor's rated torque (paper section 3)
BENCH_DISK_INERTIA_KGM2 = 1.45  # ours: the inertia disk, of the 1.5 kg m^2 rudder stage


def sea805_bench(clearance_mm: float = 0.01) -> PlantParams:
    """The realistic bench: sea805-linkage with the drive's rated limits, the
    compliance of the screw and the anchorage, the rudder shaft's torsion and the load motor.

    Every number is ours (the paper names flexibility as the bench's main cause of
    oscillation, but gives no figure):

    * rated limits: :func:`sea805_ratings`; the speed command limit falls to the rated 1800 rpm;
    * screw/nut axial stiffness in series with the gap: 150 N/um, a roller screw's nut and
      its thrust bearings in series (each several hundred N/um); the nut body 1 kg; 2 % of
      critical damping on the rod's 3 kg;
    * anchorage: 60 N/um, the attachment lugs, spherical bearings and backup structure of an
      actuator of this force class; the body (housing, stator, bearings) 12 kg; 5 % of
      critical damping;
    * rudder shaft: 2e4 N m/rad, a 200 N m torque sensor's shaft and couplings, between the
      rocker arm (0.05 kg m^2 of the rudder stage) and the 1.45 kg m^2 inertia disk: 18.7 Hz
      with the disk alone; 2 % of critical damping;
    * load motor: the paper's LAFERT B132I (section 3), rated 94.5 N m: its torque is held
      to that rating (T_max); ours: a 0.01 kg m^2 rotor and a 200 Hz torque loop. No standing
      preload: the paper states no load profile for its bench tests, so the nominal bench
      carries none; a preload or a hinge-moment profile is a scenario option
      (``plant.load_motor.preload_Nm``, ``load.rudder_torque_Nm``, within the rating).
    """
    base = sea805_linkage(clearance_mm)
    linkage = base.linkage.model_copy(
        update={"rudder_inertia_kgm2": base.linkage.rudder_inertia_kgm2 - BENCH_DISK_INERTIA_KGM2}
    )
    return base.model_copy(
        update={
            "motor": base.motor.model_copy(update={"max_speed_rpm": 1800.0}),
            "linkage": linkage,
            "ratings": sea805_ratings(),
            "compliance": ComplianceParams(
                stiffness_N_per_m=1.5e8,
                damping_Ns_per_m=damping_for_ratio(0.02, 1.5e8, 3.0),
                node_mass_kg=1.0,
            ),
            "anchorage": AnchorageParams(
                stiffness_N_per_m=6.0e7,
                damping_Ns_per_m=damping_for_ratio(0.05, 6.0e7, 12.0),
                housing_mass_kg=12.0,
            ),
            "rudder_shaft": ShaftParams(
                stiffness_Nm_per_rad=2.0e4,
                damping_Nms_per_rad=damping_for_ratio(0.02, 2.0e4, BENCH_DISK_INERTIA_KGM2),
                disk_inertia_kgm2=BENCH_DISK_INERTIA_KGM2,
            ),
            "load_motor": LoadMotorParams(
                inertia_kgm2=0.01, bandwidth_Hz=200.0, max_torque_Nm=LOADER_RATED_TORQUE_NM
            ),
        }
    )


STEEL_DENSITY_KG_M3 = 7850.0  # structural steel (EN 10025)
SCREW_SHAFT_DIAMETER_M = 0.030  # ours: the roller screw's shaft, for an 8 mm lead, 250 mm stroke
SCREW_SHAFT_LENGTH_M = 0.5  # ours: the stroke, the nut and the two bearing seats


def sea805_coupling() -> PlantParams:
    """sea805 with the torsion between the motor and the screw (emasim.plant.elements.gear_mesh):
    the SEA805 drives its screw directly (paper section 3), through a shaft coupling.

    Every number is ours (the paper gives the rotor and screw's inertia together):

    * the screw side: a solid steel shaft of 30 mm by 0.5 m, J_s = pi rho L d^4 / 32; the rotor
      keeps the rest of the paper's 0.0027 kg m^2;
    * the coupling: 5e4 N m/rad, within the 1e4 to 1e5 N m/rad that metal-bellows couplings of
      a few tens of N m (the motor's peak is 1.5 np psi_f 58 A = 42 N m) list in catalogues,
      with no play; 2 % of critical damping on the two inertias' reduced inertia.
    """
    base = sea805()
    screw = math.pi * STEEL_DENSITY_KG_M3 * SCREW_SHAFT_LENGTH_M * SCREW_SHAFT_DIAMETER_M**4 / 32
    rotor = base.motor.inertia_kgm2 - screw
    stiffness = 5.0e4
    return base.model_copy(
        update={
            "motor": base.motor.model_copy(update={"inertia_kgm2": rotor}),
            "gear_mesh": GearMeshParams(
                stiffness_Nm_per_rad=stiffness,
                damping_Nms_per_rad=damping_for_ratio(
                    0.02, stiffness, rotor * screw / (rotor + screw)
                ),
                screw_inertia_kgm2=screw,
            ),
        }
    )


PRESETS = {
    "sea805": sea805,
    "sea805-coupling": sea805_coupling,
    "sea805-stand": sea805_stand,
    "sea805-linkage": sea805_linkage,
    "sea805-bench": sea805_bench,
}


ARCSEC = math.pi / (180.0 * 3600.0)  # rad
RUDDER_ENCODER_LINES = 1024  # the HEIDENHAIN TTL encoder's line count (ttl_rudder_encoder)
RUDDER_ENCODER_EDGES = 4  # TTL quadrature: every edge of both channels counts
RUDDER_ENCODER_ACCURACY_ARCSEC = 60.0  # the paper's figure (section 3)


def ttl_rudder_encoder() -> SensorChannel:
    """The bench's rudder encoder: a HEIDENHAIN incremental rotary encoder, +-60 arcsec, TTL
    signals (paper section 3), as the count its counter holds.

    The paper gives no line count. HEIDENHAIN states the system accuracy of its incremental
    rotary encoders with TTL signals as +-1/20 of the grating period: +-60" is a period of
    1200", 1080 lines; we take the nearest standard line count, 1024 (+-63"). Evaluated on all
    four edges of the two quadrature signals that is 4096 counts a revolution, a quantum of
    316" (0.088 deg). The reading's error is the position-dependent deviation the class
    bounds, not white noise: +-60" over each grating period (360 deg / 1024), zero at the
    rudder's neutral, where the incremental count is referenced. The counter is read at every
    control tick (the rudder channel's sample period is the controllers').
    """
    lines = RUDDER_ENCODER_LINES
    return SensorChannel(
        resolution=2.0 * math.pi / (RUDDER_ENCODER_EDGES * lines),
        accuracy_error=RUDDER_ENCODER_ACCURACY_ARCSEC * ARCSEC,
        accuracy_period=2.0 * math.pi / lines,
    )


ABSOLUTE_ENCODER_BITS = 20  # absolute_rudder_encoder's single-turn resolution


def absolute_rudder_encoder() -> SensorChannel:
    """A 20-bit absolute rotary encoder on the rudder, the verdict map's alternative to the
    paper's TTL encoder (emasim.experiments.verdict_map): 2^20 counts a revolution (1.24" a
    count), no accuracy error. Not the paper's: it stands for a near-ideal reading (emasim's
    rudder encoder before the bench's was modelled had this resolution), so that the map's
    encoder axis shows what the TTL encoder's coarse count and accuracy error do to each
    verdict. Its own accuracy class is left out, on purpose."""
    return SensorChannel(resolution=2.0 * math.pi / 2**ABSOLUTE_ENCODER_BITS)


def bench_sensors() -> SensorParams:
    """The paper's test-bench sensors (section 3), as quantisation, accuracy error and noise.

    Rudder: the HEIDENHAIN TTL encoder (:func:`ttl_rudder_encoder`).
    Rod position: magnetostrictive sensor, 16 bit over the 250 mm stroke (0.0015 % = 3.8 um).
    Rod force: 0.2 % of the 50 kN range, as uniform error (std 100 N/sqrt(3)).
    Motor speed and currents: the drive's own resolver and shunts (ours: 0.1 rad/s, 0.05 A noise).
    """
    return SensorParams(
        rudder=ttl_rudder_encoder(),
        position=SensorChannel(resolution=0.250 / 2**16),
        force=SensorChannel(noise_std=100.0 / math.sqrt(3)),
        speed=SensorChannel(noise_std=0.1),
        id=SensorChannel(noise_std=0.05),
        iq=SensorChannel(noise_std=0.05),
    )


def bench_digital_sensors() -> SensorParams:
    """bench_sensors as a digital drive reads them: every channel at its own rate, and the
    speed from encoder counts.

    The rudder encoder and the currents at every control tick; the rod position and force
    at 1 kHz (ours: the usual update rate of a magnetostrictive sensor and of a strain-gauge
    amplifier). Motor speed (ours): the drive differences its 17-bit motor encoder's counts
    every tick (a quantum of 0.48 rad/s at 10 kHz) through a 0.5 ms first-order filter, in
    place of the direct reading.
    """
    bench = bench_sensors()
    return bench.model_copy(
        update={
            "position": bench.position.model_copy(update={"sample_period_s": 1e-3}),
            "force": bench.force.model_copy(update={"sample_period_s": 1e-3}),
            "angle": SensorChannel(resolution=2.0 * math.pi / 2**17),
            "speed": SensorChannel(derived=True, filter_time_constant_s=5e-4),
        }
    )


SENSOR_PRESETS = {
    "ideal": SensorParams,
    "bench": bench_sensors,
    "bench-digital": bench_digital_sensors,
}
