"""Small compiled helpers shared by plant and control code."""

import math

from .jit import njit


@njit(cache=True, inline="always", error_model="numpy")
def clamp(value, lower, upper):
    """value limited to [lower, upper]."""
    return min(max(value, lower), upper)


@njit(cache=True, inline="always", error_model="numpy")
def limit_magnitude(a, b, limit):
    """Scale the vector (a, b) down to length ``limit`` if it is longer; keep its direction."""
    mag = math.sqrt(a * a + b * b)
    if mag <= limit:
        return a, b
    scale = limit / mag
    return a * scale, b * scale


@njit(cache=True, inline="always", error_model="numpy")
def sign(x):
    """sign(x) in {-1, 0, 1}."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def boundary_layer(s, width):
    """sat(s / width): the sign function smoothed linearly inside |s| < width (width 0: sign)."""
    if width <= 0.0:
        return sign(s)
    return min(max(s / width, -1.0), 1.0)
