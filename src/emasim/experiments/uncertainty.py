"""The bench's plant uncertainty that the Monte Carlo of the headline verdicts samples
(:mod:`.robustness`): one table (ROWS), each row a ``--vary`` spec (:mod:`.variation`) with the
reason for its range. ``UNCERTAINTY`` (the specs) and the table of docs/paper.md
(:func:`markdown`, the block TABLE_BLOCK, emasim.page_blocks) are made from it.

Every distribution is uniform (log-uniform for a factor of two either way, where the figure
is ours and only its order of magnitude is known); a ``*`` spec scales the bench's own value.
"""

from dataclasses import dataclass

from ..plant.presets import LOADER_RATED_TORQUE_NM, ttl_rudder_encoder

TABLE_BLOCK = "uncertainty"  # docs/paper.md's block of the table
SEED = "seed"
TWO_EITHER_WAY = "*loguniform(0.5, 2)"
RUDDER_COUNT = ttl_rudder_encoder().resolution  # rad: one count of the bench's rudder encoder
BOLTED = "*uniform(0.7, 1.3)"
DAMPING_REASON = (
    "a factor of 2 either way of our damping ratio: the structural damping of bolted steel "
    "assemblies lies between about 1 and 5 % of critical (typical spread)"
)


@dataclass(frozen=True)
class Uncertain:
    """One sampled parameter: ``name`` (the report's and the sensitivity's), ``spec`` (a
    ``--vary`` KEY=SPEC) and ``reason`` (the range's source or stated reason)."""

    name: str
    spec: str
    reason: str

    @property
    def column(self) -> str:
        """The study table's column that holds its drawn value (the factor of a ``*`` spec)."""
        return self.spec.split("=", 1)[0]


def _bolted(what: str) -> str:
    return f"+-30 % of our {what}: a bolted joint's stiffness is known to about that"


ROWS = (
    Uncertain(
        "friction",
        "plant.friction.coulomb_Nm,plant.friction.static_Nm,plant.friction.viscous_Nms_per_rad"
        "=*uniform(0.5, 1.5)",
        "+-50 %, the three parts together: a lubricated screw's friction changes about this "
        "much between cold and warm and from new to run in (typical spread)",
    ),
    Uncertain(
        "backlash",
        "plant.backlash.width_mm=uniform(0.05, 0.2)",
        "half to twice the paper's 0.1 mm (its Fig. 8): a tighter build, or a preload worn off",
    ),
    Uncertain(
        "hinge clearance",
        "plant.linkage.hinge_clearance_mm=uniform(0, 0.0205)",
        "every joint alike, radial (the model's), from none to the largest of a running fit "
        "of the 20 mm pins: ISO 286 H7/g6 at 20 mm gives 0.007 to 0.041 mm diametral, half "
        "of it radial",
    ),
    Uncertain(
        "load inertia",
        "plant.linkage.rudder_inertia_kgm2,plant.rudder_shaft.disk_inertia_kgm2=*uniform(0.8, 1.2)",
        "+-20 %, rudder and disk together: the paper gives the 1.5 kg m^2 load as one figure "
        "without a tolerance; +-20 % for an inertia reckoned from the geometry",
    ),
    Uncertain(
        "preload",
        f"plant.load_motor.preload_Nm=uniform(0, {LOADER_RATED_TORQUE_NM:g})",
        "the loader's range, 0 to the LAFERT B132I's 94.5 N m rating (paper section 3); the "
        "paper states no load profile",
    ),
    Uncertain(
        "screw stiffness",
        f"plant.compliance.stiffness_N_per_m={BOLTED}",
        _bolted("150 N/um (nut and thrust bearings in series; the paper gives none)"),
    ),
    Uncertain(
        "screw damping", f"plant.compliance.damping_Ns_per_m={TWO_EITHER_WAY}", DAMPING_REASON
    ),
    Uncertain(
        "anchorage stiffness",
        f"plant.anchorage.stiffness_N_per_m={BOLTED}",
        _bolted("60 N/um (lugs, spherical bearings, backup structure)"),
    ),
    Uncertain(
        "anchorage damping", f"plant.anchorage.damping_Ns_per_m={TWO_EITHER_WAY}", DAMPING_REASON
    ),
    Uncertain(
        "shaft stiffness",
        f"plant.rudder_shaft.stiffness_Nm_per_rad={BOLTED}",
        _bolted("2e4 N m/rad (torque sensor shaft and its clamped couplings)"),
    ),
    Uncertain(
        "shaft damping", f"plant.rudder_shaft.damping_Nms_per_rad={TWO_EITHER_WAY}", DAMPING_REASON
    ),
    Uncertain(
        "contact stiffness",
        f"plant.linkage.contact.stiffness_N_per_mm_e={TWO_EITHER_WAY}",
        "a factor of 2 either way: the pin joints' Hertz-type stiffness is our figure from a "
        "formula, not measured; fit, surface and lubricant film move it that much",
    ),
    Uncertain(
        "load motor bandwidth",
        f"plant.load_motor.bandwidth_Hz={TWO_EITHER_WAY}",
        "100 to 400 Hz: our 200 Hz torque loop (the paper gives none), a factor of 2 either way",
    ),
    Uncertain(
        "computation delay",
        "loop.computation_delay_s=*discrete(0.5, 1, 3)",
        "half to one control period (50 to 100 us; nominal one period): the drive's "
        "computation time is not stated; the schema takes a whole number of solver steps, at "
        "most one period, so it is one of 2 to 4 steps of 25 us (the bench's h), each equally "
        "likely",
    ),
    Uncertain(
        "speed filter",
        f"sensors.speed.filter_time_constant_s={TWO_EITHER_WAY}",
        "0.25 to 1 ms: our 0.5 ms drive setting (the paper gives none), a factor of 2 either way",
    ),
    Uncertain(
        "motor kt",
        "plant.motor.flux_linkage_Wb=*uniform(0.9, 1.1)",
        "+-10 %, a servo-motor datasheet's tolerance on kt (kt = 1.5 p psi: the flux linkage "
        "sets it)",
    ),
    Uncertain(
        "motor J",
        "plant.motor.inertia_kgm2=*uniform(0.9, 1.1)",
        "+-10 %, as the datasheet's other constants (typical tolerance): the rotor with its "
        "encoder and coupling hub",
    ),
    Uncertain(
        "motor R",
        "plant.motor.resistance_ohm=*uniform(0.9, 1.45)",
        "the datasheet's +-10 % at 20 C, and copper's +0.393 %/K up to a 100 C winding (+31 %)",
    ),
    Uncertain(
        "motor L",
        "plant.motor.inductance_d_H,plant.motor.inductance_q_H=*uniform(0.9, 1.1)",
        "+-10 %, d and q together: a servo-motor datasheet's tolerance",
    ),
    Uncertain(
        "encoder error",
        "sensors.rudder.accuracy_error=*uniform(0, 1)",
        "its amplitude 0 to 60\": the encoder's +-60\" class bounds the error, a unit's lies "
        "anywhere below; its phase is no parameter (zero at the neutral, where the count is "
        "referenced)",
    ),
    Uncertain(
        "encoder phase",
        f"sensors.rudder.offset=uniform({-0.5 * RUDDER_COUNT!r}, {0.5 * RUDDER_COUNT!r})",
        "where the rudder encoder's grid falls on the true angle, uniform over one count "
        "(+-q/2): set by how the encoder was mounted; the rudder starts at rest at the "
        "neutral, so it also sets where the start lies within a count",
    ),
    Uncertain(SEED, "seed=integers(0, 4294967295)", "a new sensor-noise realisation each plant"),
)
UNCERTAINTY = tuple(row.spec for row in ROWS)
COLUMNS = {row.column: row.name for row in ROWS}  # study table column -> parameter name


def markdown(specs: tuple[str, ...] = UNCERTAINTY) -> str:
    """The table of ``specs`` (docs/paper.md's: ROWS', the block TABLE_BLOCK), each
    with its row's name and reason ('-' for a spec of no row)."""
    from ..analysis.tables import markdown_table

    known = {row.spec: row for row in ROWS}
    return markdown_table(
        ["parameter", "`--vary` spec", "range and its reason"],
        [
            [known[s].name, f"`{s}`", known[s].reason] if s in known else ["-", f"`{s}`", "-"]
            for s in specs
        ],
    )
