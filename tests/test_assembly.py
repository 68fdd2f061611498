"""The compiled plant is generated from element declarations (emasim.plant.assembly): a toy
plant of three elements, checked against its equations written out by hand.

A cart (mass m_c, pushed back by the input f_load) is tied by a spring-damper (k1, c1) to a
block, which sits on a spring-damper (k2, c2) to the ground: the block and its mount are one
optional spring-damper element (emasim.plant.spring_damper). With the mount,

    m_c a_c = -F1 - f_load,   m_b a_b = F1 + F2,
    F1 = k1 (x_c - x_b) + c1 (v_c - v_b),   F2 = -k2 x_b - c2 v_b;

without it the block is the ground: F1 = k1 x_c + c1 v_c, the block's states stay idle and its
output is NaN.
"""

import math

import numpy as np
import pytest

from emasim.plant.assembly import generate, load
from emasim.plant.element import Body, Coupling, Element, Quantity, State, assemble
from emasim.plant.spring_damper import spring_damper, spring_damper_force

CART = Element(
    "cart",
    "a cart pushed back by the input",
    states=(State("cart_x_m", "m"), State("cart_v_m_s", "m/s")),
    params=(Quantity("cart_mass_kg", "kg"),),
    outputs=(Quantity("cart_position_m", "m"),),
    bodies=(Body("cart", "cart_x_m", "cart_v_m_s", "cart_mass_kg"),),
    forces=(("cart", "-in.f_load"),),
    values=(("cart_position_m", "cart.x"),),
)
LINK = Element(
    "link",
    "a spring-damper from the cart to the block (or the ground)",
    params=(Quantity("link_k", "N/m"), Quantity("link_c", "N s/m")),
    outputs=(Quantity("link_force_N", "N"),),
    couplings=(Coupling(spring_damper_force, "cart", "block|ground", ("link_k", "link_c")),),
    values=(("link_force_N", "force"),),
)
MOUNT = spring_damper(
    "mount",
    "a block on a spring-damper to the ground",
    node="block",
    anchor="ground",
    states=(State("block_x_m", "m"), State("block_v_m_s", "m/s")),
    params=(
        Quantity("mount_present", "1"),
        Quantity("mount_k", "N/m"),
        Quantity("mount_c", "N s/m"),
        Quantity("block_mass_kg", "kg"),
    ),
    output=Quantity("mount_force_N", "N"),
    mode="the mount",
)
TOY = assemble((CART, LINK, MOUNT))
M_C, K1, C1, K2, C2, M_B = 2.0, 300.0, 4.0, 5000.0, 7.0, 0.5


@pytest.fixture(scope="module")
def toy():
    return load(TOY)


def params(present: bool) -> np.ndarray:
    values = {"cart_mass_kg": M_C, "link_k": K1, "link_c": C1, "mount_present": float(present)}
    values |= {"mount_k": K2, "mount_c": C2, "block_mass_kg": M_B}
    p = np.zeros(len(TOY.params))
    for name, value in values.items():
        p[TOY.params.index(name)] = value
    return p


def test_the_generated_rhs_is_the_toys_equations(toy):
    rng = np.random.default_rng(7)
    p = params(present=True)
    for _ in range(20):
        xc, vc, xb, vb, f_load = rng.normal(size=5)
        x = np.array([xc, vc, xb, vb])
        dx = np.zeros(4)
        toy.rhs(x, 0.0, 0.0, 0.0, f_load, 0.0, p, dx, np.zeros((4, 2)))
        f1 = K1 * (xc - xb) + C1 * (vc - vb)
        f2 = -K2 * xb - C2 * vb
        expected = [vc, (-f1 - f_load) / M_C, vb, (f1 + f2) / M_B]
        np.testing.assert_allclose(dx, expected, rtol=1e-14, atol=1e-14)
        out = np.zeros(3)
        toy.plant_outputs(x, p, out)
        np.testing.assert_allclose(out, [xc, f1, f2], rtol=1e-14)
        assert toy.output_link_force_N(x, p) == pytest.approx(f1, rel=1e-14)


def test_an_absent_body_is_its_anchor(toy):
    p = params(present=False)
    x = np.array([0.3, -1.2, 9.0, 9.0])  # the block's states are ignored, not read
    dx = np.full(4, np.nan)
    toy.rhs(x, 0.0, 0.0, 0.0, 0.5, 0.0, p, dx, np.zeros((4, 2)))
    f1 = K1 * 0.3 + C1 * -1.2
    np.testing.assert_allclose(dx, [-1.2, (-f1 - 0.5) / M_C, 0.0, 0.0], rtol=1e-14)
    out = np.zeros(3)
    toy.plant_outputs(x, p, out)
    assert out[1] == pytest.approx(f1, rel=1e-14) and math.isnan(out[2])
    assert TOY.absent_columns(p) == {"block_x_m", "block_v_m_s", "mount_force_N"}


def test_the_moving_states_end_with_the_last_present_element(toy):
    assert toy.active_states(params(present=True)) == 4
    assert toy.active_states(params(present=False)) == 2


def test_the_modes_come_from_the_present_elements():
    (mode,) = TOY.modes(params(present=True))
    assert mode[0] == "the mount" and mode[1] == pytest.approx(math.sqrt(K2 / M_B))
    assert TOY.modes(params(present=False)) == []


def test_a_port_no_element_provides_is_refused():
    lost = Element(
        "lost", "couples to nothing", couplings=(Coupling(spring_damper_force, "a", "b", ()),)
    )
    with pytest.raises(ValueError, match="no element provides a node for the port '[ab]'"):
        generate(assemble((CART, lost)))


def test_a_module_without_an_element_is_the_toy_without_it(toy):
    """The module of every plant without the mount has no presence test left and gives the
    equations of the mount's absence (the test above), and says which plants it applies to."""
    without = load(TOY, absent=frozenset({"mount"}))
    source = generate(TOY, absent=frozenset({"mount"}))
    assert "if p[" not in source.split("def active_states")[0]  # no presence test in rhs
    p = params(present=False)
    x = np.array([0.3, -1.2, 9.0, 9.0])
    dx, expected = np.full(4, np.nan), np.full(4, np.nan)
    without.rhs(x, 0.0, 0.0, 0.0, 0.5, 0.0, p, dx, np.zeros((4, 2)))
    toy.rhs(x, 0.0, 0.0, 0.0, 0.5, 0.0, p, expected, np.zeros((4, 2)))
    np.testing.assert_array_equal(dx, expected)
    assert without.active_states(p) == 2
    assert without.applies(p) and not without.applies(params(present=True))
    with pytest.raises(ValueError, match="always present"):
        generate(TOY, absent=frozenset({"cart"}))


def test_the_drive_module_is_every_elements_rhs_on_the_drive_alone():
    """The loop integrates a plant without the optional bodies (emasim.plant.actuator.DRIVE)
    with the drive's right-hand side: bit for bit every element's, at random states, for the
    shipped lumped scenarios; the bench plants are not drive plants."""
    from emasim.plant import actuator as A
    from emasim.scenarios.loader import load_scenario

    rng = np.random.default_rng(3)
    for name in ("speed-step", "position-step", "bench-step"):
        p = load_scenario(name).setup().plant
        assert A.DRIVE.applies(p) == (not name.startswith("bench"))
        if not A.DRIVE.applies(p):
            continue
        assert A.DRIVE.active_states(p) == A.active_states(p)
        for _ in range(50):
            x = rng.normal(size=A.N_STATE) * 1e-3
            u = rng.normal(size=5) * 10.0
            got, want = np.zeros(A.N_STATE), np.zeros(A.N_STATE)
            A.DRIVE.rhs(x, *u, p, got, np.zeros((4, 2)))
            A.rhs(x, *u, p, want, np.zeros((4, 2)))
            np.testing.assert_array_equal(got, want)
