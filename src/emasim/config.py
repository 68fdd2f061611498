"""The base of every validated configuration model, and the unit factors used at the edges."""

import math

from pydantic import BaseModel, ConfigDict

RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
MM = 1e-3  # m per mm


class Strict(BaseModel):
    """Base of every configuration model: no unknown keys, no NaN/inf, assignment validated."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)
