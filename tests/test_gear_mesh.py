"""The gear-mesh element (emasim.plant.elements.gear_mesh): the torsion between the motor and
the screw, added as one element module and one preset entry, and present everywhere else from
its declaration alone.

Closed form: with no play the rotor J and the screw side J_s on the mesh's k and c are two
free bodies whose relative angle q obeys J_r q'' + c q' + k q = 0, J_r = J J_s / (J + J_s):
omega_n = sqrt(k (1/J + 1/J_s)) and zeta = c / (2 sqrt(k J_r)). The mechanical block of the
generated right-hand side's Jacobian (central differences about rest at mid stroke, where the
nut sits inside the backlash gap; the motor's viscous damping and the friction off) has the
eigenvalues 0, 0 and -zeta omega_n +- i omega_n sqrt(1 - zeta^2).
"""

import math

import control
import numpy as np
import pytest

from emasim.experiments.ablation import without_stage
from emasim.experiments.runs import run_scenario
from emasim.linear import linearize
from emasim.plant import actuator as A
from emasim.plant.parameters import PlantParams
from emasim.plant.presets import PRESETS
from emasim.scenarios.loader import load_scenario
from emasim.sim import fmi
from emasim.sim.diagnosis import fastest_modes

STATES = ("motor_angle_rad", "motor_speed_rad_s", "screw_angle_rad", "screw_speed_rad_s")
MECHANICAL = [A.PLANT.states.index(name) for name in STATES]
MESH_COLUMNS = {"screw_angle_rad", "screw_speed_rad_s", "gear_mesh_torque_Nm"}


def coupled(play_deg: float = 0.0) -> PlantParams:
    """sea805-coupling without the motor's viscous damping and friction, with a mesh play."""
    data = PRESETS["sea805-coupling"]().model_dump()
    data["motor"]["viscous_Nms_per_rad"] = 0.0
    data["friction"]["model"] = "none"
    data["gear_mesh"]["play_deg"] = play_deg
    return PlantParams.model_validate(data)


def mechanical_jacobian(plant: PlantParams, x0: np.ndarray, step: float = 1e-7) -> np.ndarray:
    """d(rates)/d(states) of the rotor and the screw side, central differences of A.rhs."""
    p = plant.pack()
    jacobian = np.empty((len(MECHANICAL), len(MECHANICAL)))
    for j, column in enumerate(MECHANICAL):
        rates = []
        for sign in (1.0, -1.0):
            x = x0.copy()
            x[column] += sign * step
            dx = np.zeros(A.N_STATE)
            A.rhs(x, 0.0, 0.0, 0.0, 0.0, 0.0, p, dx, np.zeros((4, 2)))
            rates.append(dx[MECHANICAL])
        jacobian[:, j] = (rates[0] - rates[1]) / (2.0 * step)
    return jacobian


def test_the_rotor_and_screw_ring_at_the_two_mass_frequency_and_damping():
    plant = coupled()
    mesh, rotor = plant.gear_mesh, plant.motor.inertia_kgm2
    k, c, screw = mesh.stiffness_Nm_per_rad, mesh.damping_Nms_per_rad, mesh.screw_inertia_kgm2
    reduced = rotor * screw / (rotor + screw)
    omega_n = math.sqrt(k * (1.0 / rotor + 1.0 / screw))
    zeta = c / (2.0 * math.sqrt(k * reduced))
    eigenvalues = np.linalg.eigvals(mechanical_jacobian(plant, plant.initial_state()))
    ringing = eigenvalues[np.argmax(eigenvalues.imag)]
    assert abs(ringing) == pytest.approx(omega_n, rel=1e-6)
    assert -ringing.real / abs(ringing) == pytest.approx(zeta, rel=1e-6)
    assert np.sort(np.abs(eigenvalues))[:2] == pytest.approx([0.0, 0.0], abs=1e-6 * omega_n)
    (mode,) = [m for m in fastest_modes(plant.pack()) if m[0] == "the gear mesh"]
    assert mode[1] == pytest.approx(omega_n, rel=1e-12)  # the divergence diagnosis knows it


def test_inside_the_play_the_mesh_carries_nothing_and_beyond_it_springs():
    plant = coupled(play_deg=0.2)
    half = math.radians(0.1)
    mesh = A.output("gear_mesh_torque_Nm")
    x, p = plant.initial_state(), plant.pack()
    x[A.PLANT.states.index("motor_angle_rad")] = 0.9 * half
    assert mesh(x, p) == 0.0
    x[A.PLANT.states.index("motor_angle_rad")] = 1.5 * half
    assert mesh(x, p) == pytest.approx(plant.gear_mesh.stiffness_Nm_per_rad * 0.5 * half)


def test_the_mesh_is_in_the_trace_bounds_fmu_and_ablation_and_nowhere_without_it():
    plant = PRESETS["sea805-coupling"]()
    assert MESH_COLUMNS <= set(A.PLANT.states.names) | set(A.PLANT.outputs.names)
    assert not MESH_COLUMNS & A.PLANT.absent_columns(plant.pack())
    assert MESH_COLUMNS <= A.PLANT.absent_columns(PRESETS["sea805"]().pack())
    limits = A.PLANT.limits(plant)
    assert np.all(np.isfinite(limits[MECHANICAL]) & (limits[MECHANICAL] > 0))
    fmu_outputs = {name for name, _ in fmi.PLANT_OUTPUTS}
    assert MESH_COLUMNS <= fmu_outputs
    assert without_stage(plant, "compliance").gear_mesh is None  # the compliance's stage
    assert plant.total_inertia_kgm2 == pytest.approx(PRESETS["sea805"]().total_inertia_kgm2)


def test_a_run_with_the_mesh_records_it_and_holds_the_position_step():
    scenario = load_scenario(
        "position-step", settings=['plant.preset="sea805-coupling"', "duration_s=0.3"]
    )
    result = run_scenario(scenario.variants()[0][1])
    assert MESH_COLUMNS <= set(result.columns)
    twist = result["motor_angle_rad"] - result["screw_angle_rad"]
    torque = result["gear_mesh_torque_Nm"]
    stiffness = scenario.plant.gear_mesh.stiffness_Nm_per_rad
    np.testing.assert_allclose(
        torque, stiffness * twist, rtol=0.0, atol=0.02 * np.abs(torque).max()
    )
    assert np.abs(torque).max() > 1.0  # the mesh carries the drive's torque


def test_the_linearisation_takes_the_mesh_in():
    """emasim.linearize differentiates the generated plant, so the mesh's states are in the
    model with no edit to emasim.linear, and the loop still tracks at DC with stable poles."""
    scenario = load_scenario("position-step", settings=['plant.preset="sea805-coupling"'])
    plant = linearize(scenario, kind="plant")
    assert {"screw_angle_rad", "screw_speed_rad_s"} <= set(plant.state_labels)
    loop = linearize(scenario)
    assert control.dcgain(loop) == pytest.approx(1.0, abs=1e-9)
    assert np.all(loop.poles().real < 0)
