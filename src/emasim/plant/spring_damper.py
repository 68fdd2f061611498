"""A spring-damper between two ports, and the body it carries: one element type for every
series elasticity of the plant (the anchorage, the screw's compliance, the rudder shaft's
torsion, the torsion between the motor and the screw).

The element's body (mass or inertia m, position x_b) sits at the node it provides; the spring k
and the damper c in parallel tie it to the ``anchor`` port (at x_a):

    F = k (x_a - x_b) + c (v_a - v_b)          (N, or N m for a torsion; on the body, -F on
                                               the anchor)
    m dv_b/dt = F + (every other force on the body's node)

or, with a play of 2b, a law with a dead zone in place of the spring-damper.

The elements that coupled to the node before the element was added now couple to its body:
without the element (its presence parameter 0) the node is the anchor, its states stay idle
and its output is NaN. Its natural mode for the divergence diagnosis is the two-body rate
sqrt(k (1/m + 1/m_anchor)), with m_anchor infinite for a fixed anchor.
"""

import math
from collections.abc import Callable

from ..jit import njit
from .element import (
    CLOSED_OVERLAP,
    RK4_OSCILLATOR_LIMIT,
    Body,
    Coupling,
    Element,
    Quantity,
    State,
    two_body_rate,
)


@njit(cache=True, inline="always", error_model="numpy")
def spring_damper_force(dx, dv, stiffness, damping):
    """F = k dx + c dv (N or N m): dx, dv the anchor's lead over the body and its rate."""
    return stiffness * dx + damping * dv


def spring_damper(
    name: str,
    description: str,
    node: str,
    anchor: str,
    states: tuple[State, State],
    params: tuple[Quantity, Quantity, Quantity, Quantity],
    output: Quantity,
    mode: str,
    rigid_anchor: bool = False,
    output_on_anchor: bool = False,
    order: tuple[str, ...] = (),
    pack: Callable = lambda section, plant: {},
    at_motor: Callable | None = None,
    at_rod: Callable | None = None,
    stage: str = "compliance",
    play: Quantity | None = None,
    law: Callable = spring_damper_force,
    **extra,
) -> Element:
    """A spring-damper element (module docstring). ``states`` are the body's (position,
    velocity); ``params`` (presence, stiffness, damping, mass) by name; ``output`` the force
    on the body (on the anchor with ``output_on_anchor``); ``mode`` names its natural mode,
    ``rigid_anchor`` treats the anchor as fixed in it; ``order`` orders the body's equation
    (emasim.plant.element.Body). ``pack(section, plant)`` gives its parameters from its
    section; ``at_motor(plant)`` and ``at_rod(plant)`` the inertia (kg m^2) and mass (kg) its
    body adds at the motor shaft or at the rod. Its ablation ``stage`` is the compliance's.
    With ``play`` (a parameter: half the play, b) the force is ``law(dx, dv, b, k, c)``, a
    law with a dead zone. ``extra`` passes the rest to the Element (its place and section,
    laws, values, outputs).
    """
    presence, stiffness, damping, mass = (q.name for q in params)
    position, velocity = (s.name for s in states)
    gap = () if play is None else (play.name,)

    def modes(value, mass_at):
        m_anchor = math.inf if rigid_anchor else mass_at(anchor)
        rate = two_body_rate(value(stiffness), value(mass), m_anchor)
        return [(mode, rate, RK4_OSCILLATOR_LIMIT)]

    return Element(
        name,
        description,
        states=states,
        params=params if play is None else (*params, play),
        outputs=(output, *extra.pop("outputs", ())),
        presence=presence,
        bodies=(Body(node, position, velocity, mass, alias=anchor, order=order),),
        couplings=(Coupling(law, anchor, node, (*gap, stiffness, damping)),),
        values=((output.name, "-force" if output_on_anchor else "force"), *extra.pop("values", ())),
        modes=modes,
        pack=lambda plant: pack(getattr(plant, extra["section"]), plant),
        reflected=lambda plant: (
            at_motor(plant) if at_motor else 0.0,
            at_rod(plant) if at_rod else 0.0,
        ),
        stage=stage,
        closed=() if play is None else ((play.name, -CLOSED_OVERLAP),),
        **extra,
    )
