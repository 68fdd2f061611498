"""The anchorage: the actuator body on the structure (emasim.plant.elements.anchorage).

Checked against closed forms, on sea805-stand made conservative (no friction, no motor
damping, lossless gearing, no gap width and no contact damping, no load damping) with a
locked rotor (J = 1e6 kg m^2, so the nut rides with the body: x_nut = x_h + K theta_m with
theta_m ~ 0):

* body and rod form the chain ground -k_a- m_h -K_b- M_L; started on either eigenvector
  (numpy.linalg.eigh of the mass-normalised stiffness) at rest, the plant's x_h(t) and x_L(t)
  are A cos(omega t) of that mode;
* with the series compliance, the chain ground -k_a- m_h -K_b- m_n -k_s- M_L; started on
  its lowest eigenvector, all three positions are A cos(omega_1 t);
* without damping the mechanical energy (kinetic of body, node, rod and rotor, strain of
  anchorage, gap and spring) is conserved from a start that excites every mode;
* with the gap open the body rings alone on its damped anchorage (the closed-form damped
  oscillator), the rod stays put, and the rod's sensor reads x_L - x_h (emasim.plant.sensors);
* the structure's force (the anchorage_force_N output) is the rate of the total momentum of
  body, node and rod: gap, spring and end-stop forces are internal (body feels -F_gap and
  -F_stop), checked on the rhs at states with the rod on its end stop.

Tolerance of the trajectories, TOL = 1e-6 of the amplitude. What the model does not capture
is two orders smaller: RK4's phase error, t omega (omega h)^4 / 120 <= 1e-9 here, and the
locked rotor's finite mass at the nut, J / K^2 = 6e11 kg, which moves the modes by
~M_L K^2 / J = 5e-11, ~1e-9 of the amplitude after four periods (measured: 5e-10 to 7e-10;
5e-12 for the lower mode once the rotor is added to the chain as a third mass). A wrong
mass, spring, sign or a missing force changes the frequencies by percents and the trajectory
by O(1) of the amplitude within a few periods.
"""

import math

import numpy as np
import pytest
from helpers import conservative_stand, integrate_plant, relative_error

from emasim.interface import M_POSITION, M_VELOCITY, N_MEAS
from emasim.plant import actuator as A
from emasim.plant.elements.anchorage import AnchorageParams
from emasim.plant.elements.compliance import ComplianceParams
from emasim.plant.elements.linkage import N_HINGES
from emasim.plant.presets import sea805
from emasim.plant.sensors import true_values

K_ANCHOR = 6.0e7  # N/m: the bench's anchorage
M_HOUSING = 12.0  # kg: the bench's body
K_GAP = 1.0e8  # N/m: the closed gap (the preset's contact stiffness)
K_SERIES = 1.5e8  # N/m: the bench's screw compliance
M_NODE = 1.0  # kg: the bench's nut body
LOCKED = 1.0e6  # kg m^2: a locked rotor (the largest inertia the model accepts)
AMPLITUDE = 1e-5  # m: the largest displacement of a mode
H = 2e-6  # s: omega h <= 0.032 for every mode here (the fastest, the node's, 1.6e4 rad/s)
TOL = 1e-6  # of the amplitude (module docstring)


def locked_rotor_plant(width_mm=0.0, anchorage_damping=0.0, compliance=False):
    """sea805-stand made conservative with a locked rotor, on the anchorage (module
    docstring); with ``compliance`` the series spring behind the gap."""
    plant = conservative_stand(width_mm, K_GAP)
    plant.motor.inertia_kgm2 = LOCKED
    plant.anchorage = AnchorageParams(
        stiffness_N_per_m=K_ANCHOR, damping_Ns_per_m=anchorage_damping, housing_mass_kg=M_HOUSING
    )
    if compliance:
        plant.compliance = ComplianceParams(
            stiffness_N_per_m=K_SERIES, damping_Ns_per_m=0.0, node_mass_kg=M_NODE
        )
    return plant


def rod_mass(plant) -> float:
    """M_L of the lumped stage: the rod plus the rudder's inertia through the arm (kg)."""
    arm = plant.load.rudder_arm_mm * 1e-3
    return plant.load.rod_mass_kg + plant.load.rudder_inertia_kgm2 / arm**2


def chain_modes(masses, stiffness):
    """Eigenfrequencies (rad/s, ascending) and mode shapes (columns, largest entry 1) of
    M x'' + K x = 0, from the symmetric eigenproblem of M^-1/2 K M^-1/2."""
    scale = np.diag(1.0 / np.sqrt(masses))
    squared, vectors = np.linalg.eigh(scale @ stiffness @ scale)
    shapes = scale @ vectors
    return np.sqrt(squared), shapes / np.max(np.abs(shapes), axis=0)


def chain_stiffness(springs):
    """Stiffness matrix of ground -springs[0]- m_0 -springs[1]- m_1 - ... (a grounded chain)."""
    n = len(springs)
    k = np.zeros((n, n))
    for i, s in enumerate(springs):
        k[i, i] += s
        if i > 0:
            k[i - 1, i - 1] += s
            k[i - 1, i] -= s
            k[i, i - 1] -= s
    return k


def run(plant, x0, duration_s, h=H):
    """Integrate the plant with no loads from x0; returns (t, states)."""
    return integrate_plant(plant, x0, duration_s, h)


@pytest.mark.parametrize("mode", [0, 1])
def test_body_and_rod_ring_in_each_mode_of_the_two_mass_chain(mode):
    """ground -k_a- m_h -K_b- M_L: each eigenvector, started at rest, stays A cos(omega t)."""
    plant = locked_rotor_plant()
    omegas, shapes = chain_modes(
        np.array([M_HOUSING, rod_mass(plant)]), chain_stiffness([K_ANCHOR, K_GAP])
    )
    omega, shape = omegas[mode], AMPLITUDE * shapes[:, mode]
    x0 = plant.initial_state()
    x0[A.X_XH], x0[A.X_XL] = shape
    t, states = run(plant, x0, duration_s=4 * 2 * math.pi / omega)
    expected = np.outer(np.cos(omega * t), shape)
    simulated = states[:, [A.X_XH, A.X_XL]]
    assert relative_error(simulated, expected) < TOL
    assert np.min(np.abs(shape)) > 0.2 * AMPLITUDE  # both bodies swing: not a vacuous pass


def test_with_the_compliance_the_three_mass_chain_rings_at_its_lowest_eigenfrequency():
    """ground -k_a- m_h -K_b- m_n -k_s- M_L: the lowest eigenvector stays A cos(omega_1 t)."""
    plant = locked_rotor_plant(compliance=True)
    masses = np.array([M_HOUSING, M_NODE, rod_mass(plant)])
    omegas, shapes = chain_modes(masses, chain_stiffness([K_ANCHOR, K_GAP, K_SERIES]))
    omega, shape = omegas[0], AMPLITUDE * shapes[:, 0]
    x0 = plant.initial_state()
    x0[A.X_XH], x0[A.X_XN], x0[A.X_XL] = shape
    t, states = run(plant, x0, duration_s=4 * 2 * math.pi / omega)
    expected = np.outer(np.cos(omega * t), shape)
    assert relative_error(states[:, [A.X_XH, A.X_XN, A.X_XL]], expected) < TOL
    without, _ = chain_modes(np.array([M_HOUSING, masses[2]]), chain_stiffness([K_ANCHOR, K_GAP]))
    assert omega / without[0] < 0.95  # the series spring matters here: not a vacuous pass


def mechanical_energy(states, plant):
    """Kinetic energy of body, node, rod and rotor plus the strain energy of the anchorage,
    the gap (closed, width 0: K_b (x_h + K theta - x_n)^2 / 2) and the series spring (J)."""
    xh, vh = states[:, A.X_XH], states[:, A.X_VH]
    xn, vn = states[:, A.X_XN], states[:, A.X_VN]
    xl, vl = states[:, A.X_XL], states[:, A.X_VL]
    nut = xh + plant.ratio_m_per_rad * states[:, A.X_THETA]
    kinetic = 0.5 * (
        M_HOUSING * vh**2
        + M_NODE * vn**2
        + rod_mass(plant) * vl**2
        + LOCKED * states[:, A.X_WM] ** 2
    )
    strain = 0.5 * (K_ANCHOR * xh**2 + K_GAP * (nut - xn) ** 2 + K_SERIES * (xn - xl) ** 2)
    return kinetic, strain


def test_without_damping_the_mechanical_energy_is_conserved():
    """The body displaced alone excites all three modes; their energy only moves around.
    RK4 loses (omega h)^6 / 72 of a mode's energy a step: at most 2e-9 over this run at
    h = 1e-6, for the fastest mode (1.6e4 rad/s); the tolerance is 1e-7 (measured: 6e-10)."""
    plant = locked_rotor_plant(compliance=True)
    x0 = plant.initial_state()
    x0[A.X_XH] = AMPLITUDE
    _, states = run(plant, x0, duration_s=0.01, h=1e-6)
    kinetic, strain = mechanical_energy(states, plant)
    total = kinetic + strain
    assert np.max(np.abs(total - total[0])) / total[0] < 1e-7
    assert np.max(kinetic) > 0.5 * total[0]  # the energy did move around


def test_with_the_gap_open_the_body_rings_alone_and_the_rod_sensor_reads_the_extension():
    """A 10 mm gap leaves the rod free: the body is a damped oscillator on its anchorage,
    x_h = A e^(-zeta w t) (cos w_d t + zeta / sqrt(1 - zeta^2) sin w_d t), w = sqrt(k_a / m_h),
    the rod stays at 0, and the rod's sensor, fixed on the body, reads x_L - x_h = -x_h."""
    zeta = 0.05
    damping = 2.0 * zeta * math.sqrt(K_ANCHOR * M_HOUSING)
    plant = locked_rotor_plant(width_mm=10.0, anchorage_damping=damping)
    omega = math.sqrt(K_ANCHOR / M_HOUSING)
    x0 = plant.initial_state()
    x0[A.X_XH] = AMPLITUDE
    t, states = run(plant, x0, duration_s=4 * 2 * math.pi / omega)
    w_d = omega * math.sqrt(1.0 - zeta**2)
    expected = (
        AMPLITUDE
        * np.exp(-zeta * omega * t)
        * (np.cos(w_d * t) + zeta / math.sqrt(1.0 - zeta**2) * np.sin(w_d * t))
    )
    assert relative_error(states[:, A.X_XH], expected) < TOL
    assert np.all(states[:, A.X_XL] == 0.0) and np.all(states[:, A.X_VL] == 0.0)

    p = plant.pack()
    values = np.zeros(N_MEAS)
    for x in states[:: len(states) // 50]:
        true_values(x, p, values)
        assert values[M_POSITION] == pytest.approx(x[A.X_XL] - x[A.X_XH], rel=1e-15, abs=0)
        assert values[M_VELOCITY] == pytest.approx(x[A.X_VL] - x[A.X_VH], rel=1e-15, abs=0)
    assert np.max(np.abs(states[:, A.X_XH])) > 0.5 * AMPLITUDE  # the reading differs from x_L


def momentum_states(plant):
    """States of the full sea805 plant on the anchorage and the compliance: a tight gap, a
    stretched spring, and the rod beyond its end stop relative to the body (its rudder angle
    within the rudder's stops)."""
    k = plant.ratio_m_per_rad
    states = []
    for xh, vh, xl, vl, gap, stretch in [
        (2e-5, -0.01, 0.01, 0.1, 3e-4, 1e-5),
        (-3e-5, 0.02, -0.05, -0.2, -2e-4, -2e-5),
        (1e-3, 0.05, 0.127, 0.3, 1e-4, 4e-6),  # 1 mm past the 125 mm stop
        (-1e-3, -0.05, -0.127, -0.3, -1e-4, -4e-6),
    ]:
        x = plant.initial_state()
        x[A.X_XH], x[A.X_VH], x[A.X_XL], x[A.X_VL] = xh, vh, xl, vl
        x[A.X_XN], x[A.X_VN] = xl + stretch, vl + 0.01
        x[A.X_THETA] = (x[A.X_XN] + gap - xh) / k  # the nut 'gap' ahead of the node
        x[A.X_WM] = (vl - vh) / k
        states.append(x)
    return states


def test_the_structure_force_is_the_rate_of_the_chains_momentum():
    """m_h dv_h/dt + m_n dv_n/dt + M_L dv_L/dt = -k_a x_h - c_a v_h: the gap's, the spring's
    and the end stops' forces act between the bodies (the body feels -F_gap and -F_stop), and
    the structure's force is the anchorage_force_N output. On the rhs of the full sea805
    (LuGre friction, contact damping, end stops), damped anchorage; round-off tolerance."""
    plant = sea805()
    plant.load.viscous_Ns_per_m = 0.0  # a force from the ground on the rod: keep it out
    damping = 2.0 * 0.05 * math.sqrt(K_ANCHOR * M_HOUSING)
    plant.anchorage = AnchorageParams(
        stiffness_N_per_m=K_ANCHOR, damping_Ns_per_m=damping, housing_mass_kg=M_HOUSING
    )
    plant.compliance = ComplianceParams(
        stiffness_N_per_m=K_SERIES, damping_Ns_per_m=2e3, node_mass_kg=M_NODE
    )
    p = plant.pack()
    dx, hinges, out = np.zeros(A.N_STATE), np.zeros((N_HINGES, 2)), np.zeros(A.N_OUTPUTS)
    stops_hit = 0
    for x in momentum_states(plant):
        A.rhs(x, 0.0, 0.0, 0.0, 0.0, 0.0, p, dx, hinges)
        A.plant_outputs(x, p, out)
        terms = [
            M_HOUSING * dx[A.X_VH],
            M_NODE * dx[A.X_VN],
            rod_mass(plant) * dx[A.X_VL],
        ]
        structure = -K_ANCHOR * x[A.X_XH] - damping * x[A.X_VH]
        scale = max(abs(v) for v in terms)
        assert sum(terms) == pytest.approx(structure, abs=1e-12 * scale)
        assert out[A.PLANT.outputs.index("anchorage_force_N")] == pytest.approx(
            structure, rel=1e-14
        )
        stops_hit += A.output("end_stop_force_N")(x, p) != 0.0
        assert A.output("rudder_stop_torque_Nm")(x, p) == 0.0  # no external torque
    assert stops_hit == 2  # the rod's stops took part
