"""FMI: the plant and the linkage as FMUs (pythonfmu), run under fmpy; an FMU as the mechanism.

Both FMUs run emasim's own compiled functions (engine.plant_step, mechanism.advance) with the
engine's sub-step, and FMI hands IEEE doubles through unchanged, so a master that closes the
same controllers around the FMU reproduces the in-process run to round-off. Every FMU is built
here, in a temporary folder: nothing is downloaded.
"""

import json
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from pythonfmu import FmuBuilder
from typer.testing import CliRunner

from emasim.cli import app
from emasim.control.current import CurrentPI, current_control
from emasim.control.pid import SpeedPI
from emasim.errors import InputError
from emasim.experiments.batch import run_comparison
from emasim.experiments.runs import run_scenario
from emasim.interface import M_ID, M_IQ, M_SPEED, N_MEAS, N_OUT, N_REF, O_VALUE
from emasim.plant import actuator as A
from emasim.plant.elements.motor import limit_voltage
from emasim.plant.presets import sea805, sea805_linkage
from emasim.scenarios.loader import load_scenario
from emasim.signals import ZERO, Step, encode, signal_derivatives, signal_value
from emasim.sim.engine import simulate
from emasim.sim.fmi import (
    MECHANISM_INPUTS,
    MECHANISM_OUTPUTS,
    PLANT_INPUTS,
    PLANT_OUTPUTS,
    FmuSlave,
    describe_fmu,
    export_mechanism_fmu,
    export_plant_fmu,
)
from emasim.sim.setup import Setup, plant_facts

pytestmark = pytest.mark.skipif(
    not FmuBuilder.has_binary(), reason="pythonfmu ships no FMU binary for this platform"
)

TS = 1e-4  # control sample period (s)
SUBSTEPS = 10  # h = 1e-5 s, the engine's default sub-step
DURATION = 0.1  # s
RPM = np.pi / 30.0
# the FMU's outputs in the order of the measurement vector (emasim.interface M_*)
MEASURED = (
    "motor_speed_rad_s",
    "motor_angle_rad",
    "actuator_position_m",
    "actuator_velocity_m_s",
    "id_A",
    "iq_A",
    "drivetrain_force_N",
    "rudder_angle_rad",
)
COMPARED = ("id_A", "iq_A", "motor_speed_rad_s", "actuator_position_m", "rudder_angle_rad")
COMPARED += ("drivetrain_force_N", "ud_V", "uq_V")

# cosim-step on the idealised bench: the linkage alone, which is what a mechanism FMU is
LINKAGE_ALONE = str(Path(__file__).parent / "data" / "idealised" / "cosim-step.toml")


@pytest.fixture(scope="module")
def plant_fmu(tmp_path_factory):
    return export_plant_fmu(tmp_path_factory.mktemp("fmu") / "plant.fmu")


@pytest.fixture(scope="module")
def mechanism_fmu(tmp_path_factory):
    return export_mechanism_fmu(tmp_path_factory.mktemp("fmu") / "mechanism.fmu")


def causalities(path) -> dict[str, str]:
    return {v.name: v.causality for v in read_model_description(str(path)).modelVariables}


def test_the_plant_fmu_describes_its_variables_and_carries_the_plant(plant_fmu):
    md = read_model_description(str(plant_fmu))  # validated against the FMI 2.0 schema
    assert md.fmiVersion == "2.0" and md.coSimulation is not None
    kinds = causalities(plant_fmu)
    assert {name: kinds[name] for name, _ in PLANT_INPUTS} == dict.fromkeys(
        ("ud_V", "uq_V", "load_torque_Nm", "rod_force_N", "rudder_torque_Nm"), "input"
    )
    for name, _ in PLANT_OUTPUTS:
        assert kinds[name] == "output", name
    assert set(MEASURED) <= {name for name, _ in PLANT_OUTPUTS}
    (step,) = [v for v in md.modelVariables if v.name == "step_s"]
    assert step.causality == "parameter" and float(step.start) == 1e-5
    with zipfile.ZipFile(plant_fmu) as fmu:
        data = json.loads(fmu.read("resources/emasim_plant.json"))
    plant = sea805_linkage()
    assert np.array_equal(data["plant"], plant.pack())  # JSON floats read back exactly
    assert np.array_equal(data["initial_state"], plant.initial_state())


def test_the_mechanism_fmu_describes_its_variables(mechanism_fmu):
    kinds = causalities(mechanism_fmu)
    for name, _ in MECHANISM_INPUTS:
        assert kinds[name] == "input", name
    for name, _ in MECHANISM_OUTPUTS:
        assert kinds[name] == "output", name
    assert {"rod_velocity_m_s", "rod_position_m"} <= {n for n, _ in MECHANISM_INPUTS}
    assert {"rudder_angle_rad", "rod_force_N"} <= {n for n, _ in MECHANISM_OUTPUTS}
    assert kinds["step_s"] == "parameter"


def speed_step_setup() -> Setup:
    """A 300 rpm speed step on the linkage plant, a 5 N m load step at 50 ms; ideal sensors."""
    plant = sea805_linkage()
    facts = plant_facts(plant)
    setup = Setup(
        plant=plant.pack(),
        sample_period_s=TS,
        substeps=SUBSTEPS,
        duration_s=DURATION,
        reference=encode([Step(time_s=0.0, final=300.0)], RPM),
        motor_load=encode([Step(time_s=0.05, final=5.0)]),
        rod_load=ZERO,
        speed=SpeedPI().build(facts, TS),
        current=CurrentPI().build(facts, TS),
        record_every=1,
        x0=plant.initial_state(),
    )
    return setup


def closed_loop_through_fmu(path, setup: Setup) -> dict[str, np.ndarray]:
    """emasim's speed PI and current loop around the plant FMU at Ts, as the engine runs them
    (control_tick with ideal sensors): traces at every tick. Its speed is measured in
    benchmarks/bench_fmu.py."""
    n = setup.n_ticks
    h = setup.step_s
    speed = setup.speed
    speed_state, current_state = speed.state.copy(), np.zeros(2)
    meas, ref, out = np.zeros(N_MEAS), np.zeros(N_REF), np.zeros(N_OUT)
    trace = {name: np.empty(n) for name in COMPARED}
    u_max = setup.plant[A.P_UDC]
    with FmuSlave(path, start_values={"step_s": h}) as fmu:
        inputs = fmu.refs("ud_V", "uq_V", "load_torque_Nm")
        outputs = fmu.refs(*MEASURED)
        for k in range(n):
            t = k * TS
            meas[:] = fmu.get_real(outputs)
            r, dr, _ = signal_derivatives(setup.reference, t)
            ref[0], ref[1], ref[2] = r, dr, 0.0
            speed.function(speed_state, speed.params, meas, ref, TS, out)
            i_d, i_q, w = meas[M_ID], meas[M_IQ], meas[M_SPEED]
            u_d, u_q = current_control(
                current_state, setup.current.params, i_d, i_q, w, 0.0, out[O_VALUE], TS
            )
            u_d, u_q = limit_voltage(u_d, u_q, u_max)
            load = signal_value(setup.motor_load, t + 0.5 * h)  # held: steps fall on ticks
            for name, value in zip(MEASURED, meas, strict=True):
                if name in trace:
                    trace[name][k] = value
            trace["ud_V"][k], trace["uq_V"][k] = u_d, u_q
            fmu.set_real(inputs, [u_d, u_q, load])
            fmu.do_step(t, TS)
    return trace


@pytest.fixture(scope="module")
def fmu_and_engine(plant_fmu):
    setup = speed_step_setup()
    return setup, simulate(setup), closed_loop_through_fmu(plant_fmu, setup)


def test_the_plant_fmu_under_fmpy_matches_the_engine(fmu_and_engine):
    """Same compiled arithmetic on both sides, doubles through FMI unchanged: the traces agree
    to round-off. Measured: identical to the last bit; the bound, 1e-12 of each signal's
    peak, leaves room for a compiler that fuses multiply-adds differently in the two contexts
    (about 1e-16 per operation, grown over 1000 ticks of a well-damped loop)."""
    setup, engine, trace = fmu_and_engine
    speed = engine["motor_speed_rad_s"]
    assert speed[-1] > 0.9 * 300.0 * RPM  # the loop closed: the motor runs at the command
    assert np.ptp(engine["rudder_angle_rad"]) > 1e-3  # and the linkage moved
    for name in COMPARED:
        peak = np.abs(engine[name]).max()
        error = np.abs(trace[name] - engine[name]).max()
        assert error <= 1e-12 * peak, (name, error, peak)


def cosim_step(*settings):
    base = ["duration_s=0.2", "solver.communication_step_s=1e-3"]
    return run_scenario(
        load_scenario(LINKAGE_ALONE, controllers=["pid"], settings=[*base, *settings]),
        trust_fmu=True,
    )


def test_a_cosimulation_with_the_mechanism_fmu_matches_the_builtin_mechanism(mechanism_fmu):
    """The FMU steps mechanism.advance with the master's own s0, v, span and sub-step count, so
    every trace must agree to round-off (measured: identical); 1e-12 of the peak is allowed.
    A rudder-shaft load acts on both: the FMU's rudder_torque_Nm has the scenario's sign
    (positive opposes positive deflection), as the plant FMU's does."""
    load = 'load.rudder_torque_Nm=[{type="step", time_s=0.1, final=300.0}]'
    builtin = cosim_step(load)
    through_fmu = cosim_step(load, f"solver.mechanism_fmu={json.dumps(str(mechanism_fmu))}")
    assert through_fmu.scenario["solver"]["mechanism_fmu"] == str(mechanism_fmu)
    angle = np.degrees(builtin["rudder_angle_rad"])
    assert angle.max() > 5.0  # the rudder is on its way to the 10 deg command
    for name in builtin.columns:
        a, b = builtin[name], through_fmu[name]
        both_nan = np.isnan(a) & np.isnan(b)  # position_ref_m before the first record, etc.
        difference = np.abs(np.where(both_nan, 0.0, a - b)).max()
        assert difference <= 1e-12 * np.abs(np.where(both_nan, 0.0, a)).max(), name


MINIMAL_MECHANISM = """
import json
import sys
from pathlib import Path

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Real

from emasim.plant.elements.linkage import N_HINGES, TD, rigid_pose
from emasim.sim.mechanism import advance


class MinimalLinkage(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.q = np.array(json.loads((Path(self.resources) / "linkage.json").read_text()))
        self.y = rigid_pose(0.0, self.q)
        self.s = self.rod_velocity_m_s = self.rod_force_N = 0.0
        self.register_variable(Real("rod_velocity_m_s", causality=Fmi2Causality.input))
        self.register_variable(
            Real("rudder_angle_rad", causality=Fmi2Causality.output, getter=lambda: self.y[TD])
        )
        self.register_variable(Real("rod_force_N", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        v, hinges = self.rod_velocity_m_s, np.zeros((N_HINGES, 2))
        n = round(step_size / 1e-5)
        self.rod_force_N = advance(self.y, self.s, v, step_size, n, 0.0, self.q, hinges)
        self.s += v * step_size
        return True
"""


def test_a_mechanism_fmu_with_only_the_velocity_and_two_outputs_will_do(tmp_path):
    """A third-party-like FMU: rod velocity in, rudder angle and rod force out, its own rod
    position. The rod positions differ from the drive's by round-off only, so the rudder
    follows the built-in mechanism's closely; the rudder rate is the mean over each step, and
    the other linkage columns are NaN."""
    script = tmp_path / "minimal_linkage_fmu.py"
    script.write_text(MINIMAL_MECHANISM)
    linkage = tmp_path / "linkage.json"
    linkage.write_text(json.dumps(sea805_linkage().linkage.pack().tolist()))
    fmu = FmuBuilder.build_FMU(script, dest=tmp_path / "minimal.fmu", project_files=[linkage])
    builtin = cosim_step()
    minimal = cosim_step(f"solver.mechanism_fmu={json.dumps(str(fmu))}")
    a, b = np.degrees(builtin["rudder_angle_rad"]), np.degrees(minimal["rudder_angle_rad"])
    assert np.abs(a - b).max() < 1e-9  # deg
    assert np.isnan(minimal["linkage_actuator_angle_rad"]).all()
    rate = minimal["linkage_rudder_rate_rad_s"]  # mean over a step: lags by half of it
    assert np.abs(rate - builtin["linkage_rudder_rate_rad_s"]).max() < 0.1 * np.abs(rate).max()
    assert np.isfinite(minimal.metrics["rise_time_s"])


def test_an_external_fmu_runs_only_when_trusted(mechanism_fmu):
    """Loading an FMU runs its code: without trust_fmu the run is refused before it starts."""
    scenario = load_scenario(
        LINKAGE_ALONE,
        controllers=["pid"],
        settings=[
            "duration_s=0.01",
            "solver.communication_step_s=1e-3",
            f"solver.mechanism_fmu={json.dumps(str(mechanism_fmu))}",
        ],
    )
    with pytest.raises(InputError, match="--trust-fmu"):
        run_scenario(scenario)
    with pytest.raises(InputError, match="trust_fmu=True"):
        run_comparison(scenario)
    assert run_scenario(scenario, trust_fmu=True).t[-1] > 0


def test_the_mechanism_fmu_is_refused_outside_a_cosimulation_or_without_its_variables(
    plant_fmu, tmp_path
):
    with pytest.raises(InputError, match="communication_step_s"):
        load_scenario("cosim-step", controllers=["pid"], settings=["solver.mechanism_fmu=x.fmu"])
    with pytest.raises(InputError, match="an FMU mechanism is the linkage alone"):
        run_scenario(  # the shipped cosim-step has the rudder shaft and the load motor
            load_scenario(
                "cosim-step",
                controllers=["pid"],
                settings=[
                    "solver.communication_step_s=1e-3",
                    f"solver.mechanism_fmu={json.dumps(str(plant_fmu))}",
                ],
            ),
            trust_fmu=True,
        )
    with pytest.raises(InputError, match="solver.mechanism_fmu: .*no such FMU file"):
        cosim_step(f"solver.mechanism_fmu={json.dumps(str(tmp_path / 'missing.fmu'))}")
    with pytest.raises(InputError, match="lacks the Real input 'rod_velocity_m_s'"):
        cosim_step(f"solver.mechanism_fmu={json.dumps(str(plant_fmu))}")  # the wrong FMU


runner = CliRunner()


def test_export_fmu_writes_an_fmu_and_refuses_bad_input(tmp_path):
    out = tmp_path / "lumped.fmu"
    result = runner.invoke(app, ["export-fmu", "--preset", "sea805", "--out", str(out)])
    assert result.exit_code == 0, result.output
    with zipfile.ZipFile(out) as fmu:
        data = json.loads(fmu.read("resources/emasim_plant.json"))
    assert np.array_equal(data["plant"], sea805().pack())
    out = tmp_path / "linkage.fmu"
    result = runner.invoke(app, ["export-fmu", "--mechanism", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert causalities(out)["rod_force_N"] == "output"
    for args, message in (
        (["--preset", "nope"], "unknown preset 'nope'"),
        (["--mechanism", "--preset", "sea805"], "has no linkage"),
        (["--out", str(tmp_path / "plant.zip")], "must end in .fmu"),
        (["--out", str(tmp_path)], "must end in .fmu"),
    ):
        result = runner.invoke(app, ["export-fmu", *args])
        assert result.exit_code == 2, args
        assert message in result.output and len(result.output.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["linkage.fmu", "lumped.fmu"]


def test_without_the_fmi_extra_export_says_how_to_install_it(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "pythonfmu", None)  # importing it now fails
    result = CliRunner().invoke(app, ["export-fmu", "--out", "x.fmu"])
    assert result.exit_code == 2, result.output
    assert "needs emasim's FMI extra (pythonfmu is not installed)" in result.output
    assert "pip install 'emasim[fmi]'" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "x.fmu").exists()


def test_without_the_fmi_extra_loading_an_fmu_says_how_to_install_it(monkeypatch, tmp_path):
    (tmp_path / "m.fmu").write_bytes(b"not read: fmpy is missing")
    monkeypatch.setitem(sys.modules, "fmpy", None)
    with pytest.raises(InputError, match=r"loading an FMU needs emasim's FMI extra \(fmpy"):
        describe_fmu(tmp_path / "m.fmu")


def test_both_fmus_pass_fmpys_validation(plant_fmu, mechanism_fmu):
    """fmpy's validate_fmu finds no problem: every output is among ModelStructure's
    InitialUnknowns, which pythonfmu leaves out (emasim.sim.fmi.with_initial_unknowns)."""
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(plant_fmu)) == []
    assert validate_fmu(str(mechanism_fmu)) == []
