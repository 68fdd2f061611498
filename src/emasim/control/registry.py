"""Controllers by loop and name: what scenarios and the command line may select.

Also the two named cascades the paper compares: ``hybrid`` (position RBF-SMC over speed
super-twisting + GPIO over the current loop) and ``pid`` (PID over PI over the current loop).
"""

from typing import Annotated

from pydantic import Field

from .adrc import SpeedADRC
from .fuzzy import PositionFuzzyPI
from .pid import PositionPID, SpeedPI
from .rbf import PositionSlidingMode
from .slot import ControllerConfig
from .smc import SpeedSMC
from .super_twisting import SpeedSuperTwisting

SpeedController = Annotated[
    SpeedPI | SpeedSMC | SpeedSuperTwisting | SpeedADRC, Field(discriminator="name")
]
PositionController = Annotated[
    PositionPID | PositionFuzzyPI | PositionSlidingMode, Field(discriminator="name")
]

CONTROLLERS: dict[str, dict[str, type[ControllerConfig]]] = {
    "speed": {
        "pi": SpeedPI,
        "smc": SpeedSMC,
        "st": SpeedSuperTwisting,
        "st-improved": SpeedSuperTwisting,
        "st-gpio": SpeedSuperTwisting,
        "adrc": SpeedADRC,
    },
    "position": {
        "pi": PositionPID,
        "pid": PositionPID,
        "fuzzy-pi": PositionFuzzyPI,
        "smc": PositionSlidingMode,
        "rbf-smc": PositionSlidingMode,
    },
}

DESCRIPTIONS: dict[tuple[str, str], str] = {
    ("speed", "pi"): "PI from a bandwidth, anti-windup (iq* out)",
    ("speed", "smc"): "classic sliding mode, exponential reaching law, boundary layer",
    ("speed", "st"): "classic super-twisting with the Umax switch (paper eq. 24)",
    ("speed", "st-improved"): "super-twisting with sat1/sat2 boundary layer (eq. 36)",
    ("speed", "st-gpio"): "improved super-twisting + GPIO disturbance observer (eqs. 50-51)",
    ("speed", "adrc"): "linear ADRC: order-2 extended state observer + P",
    ("position", "pi"): "PI on rod position, speed command out, velocity feed-forward",
    ("position", "pid"): "PID with filtered derivative on the measurement",
    ("position", "fuzzy-pi"): "PI retuned online by a 7x7 Mamdani rule base",
    ("position", "smc"): "sliding mode on s = c e + de/dt (no network)",
    ("position", "rbf-smc"): "sliding mode + adaptive RBF network (eqs. 52-64)",
}

CASCADES: dict[str, dict[str, dict]] = {
    "hybrid": {"speed": {"name": "st-gpio"}, "position": {"name": "rbf-smc"}},
    # the conventional cascade the paper compares against: plain PID, no feed-forward
    "pid": {"speed": {"name": "pi"}, "position": {"name": "pid", "velocity_feedforward": False}},
}
