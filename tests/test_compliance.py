"""The series spring-damper between the nut and the rod (emasim.plant.elements.compliance).

Checked against closed forms: the two-mass natural frequency sqrt(k (m1 + m2) / (m1 m2)) and
the exact eigenfrequency of the three-mass chain it becomes with the node's mass, and the
static deflection F/k of the spring under a steady rod load held by the closed loop. Without
the element the shipped scenarios' traces are unchanged (tests/test_fingerprints.py) and its
columns are left out; as k grows the chain tends to the two masses on the gap alone (the
series stiffness in the first test).
"""

import math

import numpy as np
import pytest

from emasim.plant import actuator as A
from emasim.plant.elements.compliance import ComplianceParams
from emasim.plant.presets import sea805
from emasim.scenarios.loader import load_scenario
from emasim.signals import ZERO
from emasim.sim.core import new_workspace
from emasim.sim.engine import plant_step, simulate

K_SPRING = 2.0e6  # N/m
K_GAP = 2.0e9  # N/m: the closed gap, a thousand times stiffer than the spring
H = 2e-7  # s: resolves the node's mode (sqrt(K_GAP / m_n) = 2e5 rad/s) with RK4


def conservative_plant(node_mass_kg: float, spring: float = K_SPRING, gap: float = K_GAP):
    """sea805 with no friction, no gap, no damping, no EMF coupling and lossless gearing, so
    that the mechanics alone ring; the compliance behind the gap."""
    plant = sea805()
    plant.friction.model = "none"
    plant.motor.viscous_Nms_per_rad = 0.0
    plant.motor.flux_linkage_Wb = 1e-9  # no torque, no back-EMF: u = 0 keeps i = 0
    plant.drivetrain.gear_efficiency = plant.drivetrain.screw_efficiency = 1.0
    plant.backlash.width_mm = 0.0
    plant.backlash.stiffness_N_per_m = gap
    plant.backlash.damping_ratio = 0.0
    plant.load.viscous_Ns_per_m = 0.0
    plant.compliance = ComplianceParams(
        stiffness_N_per_m=spring, damping_Ns_per_m=0.0, node_mass_kg=node_mass_kg
    )
    return plant


def ringing_frequency(plant, duration_s: float) -> float:
    """Free oscillation from a stretched spring: mean frequency (rad/s) of the rod's motion
    about its mean, from its upward crossings (interpolated)."""
    p = plant.pack()
    x = plant.initial_state()
    x[A.X_XL] = -1e-5  # the rod 10 um back; the node where gap and spring balance
    spring, gap = plant.compliance.stiffness_N_per_m, plant.backlash.stiffness_N_per_m
    x[A.X_XN] = spring * x[A.X_XL] / (spring + gap)
    work = new_workspace()
    n = round(duration_s / H)
    rod = np.empty(n)
    for j in range(n):
        rod[j] = x[A.X_XL]
        plant_step(j * H, x, 0.0, 0.0, p, ZERO, ZERO, ZERO, H, work)
    mean = rod.mean()
    up = np.flatnonzero((rod[:-1] < mean) & (rod[1:] >= mean))
    times = [(i + (mean - rod[i]) / (rod[i + 1] - rod[i])) * H for i in up]
    return 2.0 * math.pi * (len(times) - 1) / (times[-1] - times[0])


def masses(plant) -> tuple[float, float]:
    """Motor side seen at the nut, J / K^2, and the rod side, M_L (kg)."""
    return plant.motor.inertia_kgm2 / plant.ratio_m_per_rad**2, plant.load_mass_kg


def test_two_masses_ring_at_the_closed_form_frequency():
    """With a light node the chain is two masses on the gap and the spring in series."""
    plant = conservative_plant(node_mass_kg=1e-3)
    m1, m2 = masses(plant)
    k = K_SPRING * K_GAP / (K_SPRING + K_GAP)
    expected = math.sqrt(k * (m1 + m2) / (m1 * m2))
    measured = ringing_frequency(plant, duration_s=12 * 2 * math.pi / expected)
    assert measured == pytest.approx(expected, rel=2e-3)


def test_with_a_heavy_node_the_three_mass_chain_rings_at_its_eigenfrequency():
    """m1 -[K_gap]- m_n -[k]- m2: the lower root of the chain's eigenproblem, exactly. Here
    the spring is the stiff one, so the node rides with the rod and adds to its mass."""
    node, spring, gap = 20.0, K_GAP, K_SPRING
    plant = conservative_plant(node_mass_kg=node, spring=spring, gap=gap)
    m1, m2 = masses(plant)
    stiffness = np.array([[gap, -gap, 0.0], [-gap, gap + spring, -spring], [0.0, -spring, spring]])
    squared = np.linalg.eigvals(np.diag([1 / m1, 1 / node, 1 / m2]) @ stiffness).real
    lowest = math.sqrt(sorted(squared)[1])  # [0] is the rigid-body mode
    measured = ringing_frequency(plant, duration_s=12 * 2 * math.pi / lowest)
    assert measured == pytest.approx(lowest, rel=2e-3)
    k = spring * gap / (spring + gap)
    two_mass = math.sqrt(k * (m1 + m2) / (m1 * m2))
    assert measured / two_mass < 0.9  # the node's mass matters here: not a vacuous pass


def test_the_spring_deflects_f_over_k_under_a_steady_rod_load():
    force = 3000.0  # N, against extension
    scenario = load_scenario(
        "position-step",
        controllers=["position=pid"],
        settings=[
            "duration_s=1.5",
            "plant.compliance.stiffness_N_per_m=5e6",
            "plant.compliance.damping_Ns_per_m=2e3",
            "plant.compliance.node_mass_kg=0.5",
            f'load.rod_force_N=[{{type="constant", value={force}}}]',
        ],
    )
    result = simulate(scenario.setup())
    late = result.t > 1.0
    deflection = result["compliance_node_position_m"] - result["actuator_position_m"]
    assert np.mean(deflection[late]) == pytest.approx(force / 5e6, rel=1e-2)
    assert np.mean(result["drivetrain_force_N"][late]) == pytest.approx(force, rel=1e-2)


def test_without_the_element_its_columns_are_left_out():
    result = simulate(
        load_scenario("speed-step", controllers=["speed=pi"], settings=["duration_s=0.01"]).setup()
    )
    assert "compliance_force_N" not in result.columns
    assert "compliance_node_position_m" not in result.columns
