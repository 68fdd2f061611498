"""JSON as emasim writes it: valid JSON (NaN and infinity become ``null``), indented."""

import json
import math


def finite_or_none(value):
    """``value`` with every NaN and infinity (also nested in dicts and lists) set to None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_or_none(v) for key, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # a numpy scalar
        return finite_or_none(value.item())
    return value


def json_text(value) -> str:
    """Valid JSON (no NaN or Infinity tokens: they become null), indented, with a newline."""
    return json.dumps(finite_or_none(value), indent=2, allow_nan=False, default=str) + "\n"
