"""Controllers by loop and name: what scenarios and the command line may select."""

from .pid import PositionPID, SpeedPI
from .slot import ControllerConfig

CONTROLLERS: dict[str, dict[str, type[ControllerConfig]]] = {
    "speed": {"pi": SpeedPI},
    "position": {"pi": PositionPID, "pid": PositionPID},
}

DESCRIPTIONS: dict[tuple[str, str], str] = {
    ("speed", "pi"): "PI from a bandwidth, anti-windup (iq* out)",
    ("position", "pi"): "PI on rod position, speed command out, velocity feed-forward",
    ("position", "pid"): "PID with filtered derivative on the measurement",
}
