"""Units from names: every metric and figure name ends with its unit (``rise_time_s``,
``load_dip_rpm``, ``static_stiffness_N_per_mm``); :func:`unit_of` reads it back for tables."""

SUFFIXES = (  # name suffix -> unit, longest first
    ("_N_per_mm", "N/mm"),
    ("_deg_s", "deg/s"),
    ("_mm_s", "mm/s"),
    ("_rad_s", "rad/s"),
    ("_rpm", "rpm"),
    ("_pct", "%"),
    ("_Hz", "Hz"),
    ("_dB", "dB"),
    ("_deg", "deg"),
    ("_mm", "mm"),
    ("_Nm", "N·m"),
    ("_N", "N"),
    ("_A", "A"),
    ("_J", "J"),
    ("_s", "s"),
)


def unit_of(name: str) -> str:
    """The unit a name ends with; '' for a count, a flag or a ratio."""
    return next((unit for suffix, unit in SUFFIXES if name.endswith(suffix)), "")
