"""Plant parameters as validated configuration, in engineering units at the edge.

Every field carries its unit in its name (``inertia_kgm2``, ``screw_lead_mm``). The models reject
unknown keys, NaN/inf and out-of-range values with the field's path. :meth:`PlantParams.pack`
converts everything to SI once and returns the flat float array the compiled plant reads
(indices in :mod:`emasim.plant.actuator`). The numbers themselves live in
:mod:`emasim.plant.presets`.
"""

import math
from typing import Literal

import numpy as np
from pydantic import Field, create_model, model_validator

from ..config import MM, RPM, Strict  # noqa: F401 - RPM and Strict are part of this API
from ..interface import MEASUREMENT_NAMES
from . import actuator as A
from .elements import linkage as L
from .elements.drivetrain import transmission_ratio
from .elements.linkage import LinkageParams
from .elements.motor import torque_constant
from .sensors import S_ALPHA, S_ERROR, S_EVERY, S_PERIOD, S_SOURCE, S_WAVENUMBER, ideal_table


class MotorParams(Strict):
    """PMSM and its drive limits."""

    resistance_ohm: float = Field(gt=0, le=1e3, description="stator resistance Rs")
    inductance_d_H: float = Field(gt=0, le=10, description="d-axis inductance Ld")
    inductance_q_H: float = Field(gt=0, le=10, description="q-axis inductance Lq")
    flux_linkage_Wb: float = Field(gt=0, le=10, description="permanent-magnet flux linkage psi_f")
    inertia_kgm2: float = Field(
        ge=1e-9, le=1e6, description="rotor (+ screw) inertia J (1e6: a locked rotor)"
    )
    viscous_Nms_per_rad: float = Field(ge=0, le=1e4, description="viscous damping B")
    pole_pairs: int = Field(ge=1, le=64, description="pole pairs np")
    dc_bus_V: float = Field(gt=0, le=1e4, description="DC-link voltage Udc")
    max_current_A: float = Field(gt=0, le=1e4, description="q-axis current limit of the drive")
    max_speed_rpm: float = Field(gt=0, le=1e5, description="speed command limit")


class DrivetrainParams(Strict):
    """Gearbox and planetary roller screw (ratio and efficiency kept apart)."""

    gear_ratio: float = Field(gt=0, le=1e3, description="N = Z2/Z1, motor turns per screw turn")
    gear_efficiency: float = Field(gt=0, le=1)
    screw_lead_mm: float = Field(gt=0, le=100, description="lead L = starts * pitch")
    screw_efficiency: float = Field(gt=0, le=1)
    stroke_mm: float = Field(gt=0, le=1e4, description="usable rod stroke")


class FrictionParams(Strict):
    """Friction on the motor/screw shaft (rotational form, N*m and rad)."""

    model: Literal["lugre", "coulomb", "none"] = "lugre"
    coulomb_Nm: float = Field(ge=0, le=1e4, description="Coulomb level Tc")
    static_Nm: float = Field(ge=0, le=1e4, description="stiction level Ts >= Tc")
    stribeck_speed_rad_s: float = Field(gt=0, le=1e4, description="Stribeck speed ws")
    bristle_stiffness_Nm_per_rad: float = Field(gt=0, le=1e12, description="sigma0")
    bristle_damping_ratio: float = Field(
        ge=0, le=10, description="zeta of the presliding mode, sets sigma1"
    )
    viscous_Nms_per_rad: float = Field(ge=0, le=1e4, description="sigma2")
    smoothing_speed_rad_s: float = Field(
        gt=0, le=1e4, description="coulomb model only: tanh(w/ws) replaces sign(w)"
    )

    @model_validator(mode="after")
    def _stiction_not_below_coulomb(self):
        if self.static_Nm < self.coulomb_Nm:
            raise ValueError(
                f"static_Nm must be >= coulomb_Nm ({self.coulomb_Nm}), got {self.static_Nm}"
            )
        return self


class BacklashParams(Strict):
    """Total drive-train backlash between the nut (motor side) and the rod (load side)."""

    width_mm: float = Field(ge=0, le=10, description="total gap 2b")
    stiffness_N_per_m: float = Field(gt=0, le=1e12, description="contact stiffness K")
    damping_ratio: float = Field(ge=0, le=10, description="contact damping ratio on reduced mass")


class LoadParams(Strict):
    """Load side: rod and a lumped rudder stage (rudder angle = rod position / arm)."""

    rod_mass_kg: float = Field(gt=0, le=1e4)
    rudder_arm_mm: float = Field(gt=0, le=1e4, description="lever from rod travel to rudder angle")
    rudder_inertia_kgm2: float = Field(ge=0, le=1e4, description="rudder shaft + inertia disk")
    viscous_Ns_per_m: float = Field(ge=0, le=1e7, description="load-side viscous damping")


DERIVED_FROM = {"speed": "angle", "velocity": "position"}  # derived channel -> its source


class SensorChannel(Strict):
    """One measurement channel, in the channel's SI unit (rad/s, rad, m, m/s, A, N, rad);
    sampling and derived channels as in emasim.plant.sensors."""

    resolution: float = Field(default=0.0, ge=0, le=1e3, description="quantum, 0 = not quantised")
    noise_std: float = Field(
        default=0.0, ge=0, le=1e3, description="Gaussian noise standard deviation"
    )
    offset: float = Field(default=0.0, ge=-1e3, le=1e3, description="constant bias")
    accuracy_error: float = Field(
        default=0.0,
        ge=0,
        le=1e3,
        description="amplitude a of the smooth position-dependent error a sin(2 pi v / "
        "accuracy_period), zero at v = 0 (an encoder's accuracy class), 0 = none",
    )
    accuracy_period: float = Field(
        default=0.0, ge=0, le=1e3, description="period of the accuracy error, in the reading"
    )
    gap_width: float = Field(
        default=0.0, ge=0, le=1.0, description="total play read through, 0 = none"
    )
    sample_period_s: float = Field(
        default=0.0,
        ge=0,
        le=1.0,
        description="its own sample period, a whole multiple of the controllers' (0 = theirs)",
    )
    derived: bool = Field(
        default=False,
        description="speed and velocity only: differentiate the angle (encoder counts) or "
        "the position reading instead of reading the rate itself",
    )
    filter_time_constant_s: float = Field(
        default=0.0, ge=0, le=10.0, description="tau of a derived channel's lag (0 = none)"
    )

    @model_validator(mode="after")
    def _error_has_a_period(self):
        if self.accuracy_error > 0.0 and self.accuracy_period == 0.0:
            raise ValueError("accuracy_error needs accuracy_period > 0 (the error's period)")
        return self


class SensorParams(Strict):
    """Every channel the controllers can see (see emasim.interface); ideal by default."""

    speed: SensorChannel = SensorChannel()
    angle: SensorChannel = SensorChannel()
    position: SensorChannel = SensorChannel()
    velocity: SensorChannel = SensorChannel()
    id: SensorChannel = SensorChannel()
    iq: SensorChannel = SensorChannel()
    force: SensorChannel = SensorChannel()
    rudder: SensorChannel = SensorChannel()

    @model_validator(mode="after")
    def _derived_channels(self):
        for name in MEASUREMENT_NAMES:
            if getattr(self, name).derived and name not in DERIVED_FROM:
                raise ValueError(
                    f"{name}.derived: only {' and '.join(DERIVED_FROM)} can be derived "
                    f"(from {' and '.join(DERIVED_FROM.values())})"
                )
        return self

    def every(self, name: str, sample_period_s: float) -> int:
        """How many control ticks of ``sample_period_s`` apart channel ``name`` samples;
        ValueError unless its sample period is a whole multiple of it."""
        period = getattr(self, name).sample_period_s
        if period == 0.0:
            return 1
        ratio = period / sample_period_s
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6 * ratio:
            raise ValueError(
                f"sensors.{name}.sample_period_s ({period:g} s) must be a whole multiple (>= 1) "
                f"of solver.sample_period_s ({sample_period_s:g} s)"
            )
        return round(ratio)

    def pack(self, sample_period_s: float) -> np.ndarray:
        """The sensor table read by emasim.plant.sensors.measure, for controllers sampled
        every ``sample_period_s``."""
        table = ideal_table()
        for i, name in enumerate(MEASUREMENT_NAMES):
            ch = getattr(self, name)
            every = self.every(name, sample_period_s)
            period = every * sample_period_s
            table[i, : S_EVERY + 1] = (
                ch.resolution,
                ch.noise_std,
                ch.offset,
                0.5 * ch.gap_width,
                every,
            )
            table[i, S_PERIOD] = period
            if ch.accuracy_error > 0.0:
                table[i, S_ERROR] = ch.accuracy_error
                table[i, S_WAVENUMBER] = 2.0 * math.pi / ch.accuracy_period
            if ch.derived:
                table[i, S_SOURCE] = MEASUREMENT_NAMES.index(DERIVED_FROM[name])
                tau = ch.filter_time_constant_s
                table[i, S_ALPHA] = 1.0 if tau == 0.0 else -math.expm1(-period / tau)
        return table


LINKAGE_CHECK_POINTS = 101  # rod extensions at which the linkage must close


def check_linkage_closes(linkage: LinkageParams, stroke_mm: float) -> None:
    """Raise ValueError unless the rigid linkage closes at every rod extension of the stroke
    and its rudder angle rises or falls strictly along it."""
    half = 0.5 * stroke_mm * MM
    extensions = np.linspace(-half, half, LINKAGE_CHECK_POINTS)
    poses = L.rigid_poses(extensions, linkage.pack())
    open_at = extensions[~np.isfinite(poses).all(axis=1)]
    if open_at.size:
        raise ValueError(
            f"linkage: the geometry cannot close at rod extension {open_at[0] / MM:+.4g} mm of "
            f"the +-{half / MM:g} mm stroke (check the pivots, arms and lengths)"
        )
    angles = poses[:, L.TD]
    steps = np.diff(np.unwrap(angles))
    if not (np.all(steps > 0) or np.all(steps < 0)):
        raise ValueError(
            "linkage: the rudder angle does not rise (or fall) steadily over the stroke, so a "
            "rudder angle would not name one rod position (check the geometry)"
        )


class FixedPlant(Strict):
    """The whole actuator: motor, drive train, friction, backlash, load, and one optional
    section for each optional element (its ``section``, of its ``config`` model: the
    linkage, end_stops, ratings, compliance, anchorage, rudder_shaft, load_motor sections),
    added from the elements' declarations to make :data:`PlantParams`.

    With ``linkage`` set, the clearance-joint linkage replaces the lumped rudder stage: the rod
    mass comes from the linkage, and the load section keeps only its viscous damping (its
    rudder fields then serve only to convert rudder-angle references for a lumped plant).
    """

    motor: MotorParams
    drivetrain: DrivetrainParams
    friction: FrictionParams
    backlash: BacklashParams
    load: LoadParams

    @model_validator(mode="after")
    def _physically_consistent(self):
        """Every derived quantity exists: the packed parameters are finite (sigma1 >= 0, the
        contact damping real), and a linkage closes over the whole stroke with its rudder
        angle strictly monotonic in the rod extension (so a rudder reference has one rod
        position)."""
        if self.linkage is not None:
            check_linkage_closes(self.linkage, self.drivetrain.stroke_mm)
        if self.ratings is not None:
            if self.ratings.continuous_current_A > self.motor.max_current_A:
                raise ValueError(
                    f"ratings.continuous_current_A ({self.ratings.continuous_current_A:g} A) "
                    f"must not exceed the peak, motor.max_current_A ({self.motor.max_current_A:g})"
                )
            if self.ratings.rated_speed_rpm > self.motor.max_speed_rpm:
                raise ValueError(
                    f"ratings.rated_speed_rpm ({self.ratings.rated_speed_rpm:g}) must not exceed "
                    f"motor.max_speed_rpm ({self.motor.max_speed_rpm:g})"
                )
        try:
            packed = self.pack()
        except (ValueError, ArithmeticError) as err:
            raise ValueError(f"inconsistent plant: {err}") from None
        if not np.all(np.isfinite(packed)):
            raise ValueError("inconsistent plant: a derived parameter is not finite")
        return self

    @property
    def ratio_m_per_rad(self) -> float:
        """K = L/(2 pi N): rod metres per motor radian."""
        d = self.drivetrain
        return transmission_ratio(d.screw_lead_mm * MM, d.gear_ratio)

    @property
    def load_mass_kg(self) -> float:
        """Load-side mass seen at the rod (kg), for design and for the contact damping.

        Lumped stage: rod plus rudder inertia through the arm, J_r / r^2. Linkage: the rod plus
        every body's inertia through the rigid kinematics at mid stroke, sum of m |dp/ds|^2 +
        I (dtheta/ds)^2 (a 1 um central difference of the rigid pose).
        """
        if self.linkage is None:
            ld = self.load
            return ld.rod_mass_kg + self.rudder_inertia_kgm2 / (ld.rudder_arm_mm * MM) ** 2
        q = self.linkage.pack()
        ds = 1e-6
        rate = (L.rigid_pose(ds, q) - L.rigid_pose(-ds, q))[: L.N_POS] / (2 * ds)
        lk = self.linkage
        return (
            lk.rod_mass_kg
            + lk.actuator_inertia_kgm2 * rate[L.PHI] ** 2
            + lk.rocker_mass_kg * (rate[L.XB] ** 2 + rate[L.YB] ** 2)
            + lk.rocker_inertia_kgm2 * rate[L.TB] ** 2
            + lk.link_mass_kg * (rate[L.XC] ** 2 + rate[L.YC] ** 2)
            + lk.link_inertia_kgm2 * rate[L.TC] ** 2
            + self.rudder_inertia_kgm2 * rate[L.TD] ** 2
        )

    @property
    def rudder_inertia_kgm2(self) -> float:
        """The inertia that turns rigidly with the rocker arm (kg m^2): the load's or the
        linkage's rudder inertia, plus the load motor's rotor unless the shaft's torsion
        carries it on the disk."""
        own = (self.load if self.linkage is None else self.linkage).rudder_inertia_kgm2
        return own + (self.load_motor_inertia_kgm2 if self.rudder_shaft is None else 0.0)

    @property
    def load_motor_inertia_kgm2(self) -> float:
        """The load motor's rotor inertia (kg m^2), 0 without one."""
        return self.load_motor.inertia_kgm2 if self.load_motor is not None else 0.0

    @property
    def rod_per_rudder_m_per_rad(self) -> float:
        """d x_L / d theta_r at mid stroke (m/rad): the arm of the lumped stage, or the
        linkage's rigid kinematics (a 1 um central difference)."""
        if self.linkage is None:
            return self.load.rudder_arm_mm * MM
        ds = 1e-6
        angles = L.rudder_angle_of_extension(np.array([-ds, ds]), self.linkage.pack())
        return abs(2 * ds / float(angles[1] - angles[0]))

    @property
    def total_inertia_kgm2(self) -> float:
        """The motor's inertia with what each present element adds at its shaft, and the load
        mass with what each adds at the rod, reflected to the motor shaft:
        J + sum J_e + (M + sum m_e) K^2 (kg*m^2), from the elements' ``reflected``
        (emasim.plant.element.Element): the compliance's node, the inertia disk and the load
        motor behind the rudder shaft's torsion, through the lever."""
        at_motor, moving = self.motor.inertia_kgm2, self.load_mass_kg
        for element in A.ELEMENTS:
            if getattr(self, element.section) is not None:
                motor_side, rod_side = element.reflected(self)
                at_motor, moving = at_motor + motor_side, moving + rod_side
        return at_motor + moving * self.ratio_m_per_rad**2

    @property
    def torque_constant_Nm_per_A(self) -> float:
        """kt = 1.5 np psi_f."""
        return torque_constant(self.motor.pole_pairs, self.motor.flux_linkage_Wb)

    def pack(self) -> np.ndarray:
        """The flat SI parameter array read by the compiled plant: each present element's
        values (emasim.plant.element.Element.pack), its presence parameter 1; an absent
        element's parameters stay 0."""
        p = np.zeros(A.N_PARAMS)
        for element in A.ELEMENTS:
            if getattr(self, element.section) is None:
                continue
            values = element.pack(self)
            if element.presence in (q.name for q in element.params):
                values[element.presence] = 1.0
            for name, value in values.items():
                p[A.PLANT.params.index(name)] = value
        return p

    def initial_state(self) -> np.ndarray:
        """Plant state at rest at mid stroke: currents and speeds zero, and what each present
        element starts at (the linkage's rigid pose, every pin centred in its hole; the load
        motor's standing preload, acting from t = 0)."""
        x = np.zeros(A.N_STATE)
        for element in A.ELEMENTS:
            if getattr(self, element.section) is not None:
                for name, value in element.initial(self).items():
                    x[A.PLANT.states.index(name)] = value
        return x


# the plant's sections: the fixed ones, and an optional one for each optional element
PlantParams = create_model(
    "PlantParams",
    __base__=FixedPlant,
    __module__=__name__,
    __doc__=FixedPlant.__doc__,
    **{e.section: (e.config | None, None) for e in A.ELEMENTS if e.config is not None},
)
