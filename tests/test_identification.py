"""emasim identify on traces with known parameters, the axis loop against its exact solution,
and every bad input refused in one line.

The synthetic traces come from the force-driven axis in its loop (emasim.sim.axis_loop) with
chosen parameters; IDIM-LS (an inverse model fitted by linear least squares, a different
method) and the output-error fit (started away from them) must find those parameters again.
"""

import math
import tomllib

import numpy as np
import pandas as pd
import pytest
from helpers import refused_in_one_line
from typer.testing import CliRunner

from emasim.cli import app
from emasim.errors import InputError, SimulationDiverged
from emasim.identification.fit import spread
from emasim.identification.identify import identify
from emasim.plant.axis import AxisFriction, AxisParams
from emasim.plant.elements.friction import (
    asymmetric_coulomb_viscous_force,
    coulomb_viscous_force,
)
from emasim.scenarios.axis_scenario import load_axis_scenario
from emasim.sim.axis_loop import AxisLoop, simulate_axis

TS = 1e-3
TRUE = {"mass_kg": 80.0, "viscous": 150.0, "coulomb": 15.0, "offset": -2.0}


def bang_bang(duration_s: float = 8.0, stroke: float = 0.2) -> np.ndarray:
    """A reference like the EMPS's: constant-acceleration moves between rests, back and forth
    (a trapezoidal speed profile built from a smoothed triangle)."""
    t = np.arange(0.0, duration_s, TS)
    period = 2.0
    phase = (t % period) / period
    triangle = np.where(phase < 0.5, 2 * phase, 2 - 2 * phase)
    kernel = np.ones(200) / 200  # a 0.2 s moving average: bounded acceleration
    smooth = np.convolve(np.r_[np.zeros(199), triangle], kernel, mode="valid")
    return stroke * smooth


def synthetic_trace(tmp_path, friction: AxisFriction, suffix: str = ".csv", mass=80.0):
    """A trace of the emps loop with the given plant, written as a file with emps's names."""
    scenario = load_axis_scenario("emps")
    axis = AxisParams(
        mass_kg=mass,
        drive_gain_N_per_V=scenario.plant.drive_gain_N_per_V,
        stroke_m=0.25,
        max_speed_m_s=1.0,
        friction=friction,
    )
    reference = bang_bang()
    run = simulate_axis(axis, scenario.loop.loop(), reference)
    frame = pd.DataFrame(
        {
            "t": run["time_s"],
            "qg": reference,
            "qm": run["measured_position_m"],
            "vir": run["command_V"],
        }
    )
    path = tmp_path / f"trace{suffix}"
    if suffix == ".csv":
        frame.to_csv(path, index=False)
    else:
        frame.to_parquet(path)
    return path


SYMMETRIC = AxisFriction(coulomb_N=15.0, viscous_Ns_per_m=150.0, offset_N=-2.0)
START = [  # the output-error fit starts 20 % to 40 % away from the truth
    "plant.mass_kg=100.0",
    "plant.friction.viscous_Ns_per_m=200.0",
    "plant.friction.coulomb_N=20.0",
    "plant.friction.offset_N=0.0",
]
KEYS = {
    "plant.mass_kg": 80.0,
    "plant.friction.viscous_Ns_per_m": 150.0,
    "plant.friction.coulomb_N": 15.0,
    "plant.friction.offset_N": -2.0,
}


@pytest.mark.parametrize("method", ["idim", "output-error"])
def test_identify_recovers_the_parameters_of_a_synthetic_trace(tmp_path, method):
    path = synthetic_trace(tmp_path, SYMMETRIC)
    result = identify("emps", path, method=method, settings=START)
    for key, truth in KEYS.items():
        tolerance = 0.02 if method == "idim" else 0.002  # IDIM's filters bias it slightly
        assert result.values[key] == pytest.approx(truth, rel=tolerance, abs=0.05), key
        assert 0 < result.interval95[key] < math.inf
    if method == "output-error":
        # the encoder counts of the free run part from the trace's where the values differ a little
        assert result.errors["position_m"] < 1e-6 and result.errors["command_V"] < 1e-2


def test_the_output_error_fit_without_the_idim_start_finds_them_from_several_starts(tmp_path):
    # the friction's smoothing speed is not in the inverse model, so no IDIM start is made
    path = synthetic_trace(tmp_path, SYMMETRIC, suffix=".parquet")
    fit = [f"{key}" for key in KEYS] + ["plant.friction.smoothing_speed_m_s=0.00005:0.001"]
    result = identify("emps", path, fit=fit, settings=START, starts=3)
    assert result.idim is None
    for key, truth in KEYS.items():
        assert result.values[key] == pytest.approx(truth, rel=0.01, abs=0.05), key


def test_idim_recovers_asymmetric_friction(tmp_path):
    friction = AxisFriction(
        model="asymmetric",
        coulomb_N=15.0,
        viscous_Ns_per_m=120.0,
        coulomb_negative_N=18.0,
        viscous_negative_Ns_per_m=180.0,
    )
    path = synthetic_trace(tmp_path, friction)
    settings = [
        'plant.friction.model="asymmetric"',
        "plant.friction.coulomb_negative_N=20.0",
        "plant.friction.viscous_negative_Ns_per_m=200.0",
    ]
    keys = [
        "plant.mass_kg",
        "plant.friction.viscous_Ns_per_m",
        "plant.friction.coulomb_N",
        "plant.friction.viscous_negative_Ns_per_m=0:2000",
        "plant.friction.coulomb_negative_N=0:200",
    ]
    result = identify("emps", path, fit=keys, method="idim", settings=settings)
    expected = [80.0, 120.0, 15.0, 180.0, 18.0]
    for key, truth in zip(keys, expected, strict=True):
        assert result.values[key.split("=")[0]] == pytest.approx(truth, rel=0.02), key


def test_the_asymmetric_coulomb_is_collinear_with_the_offset(tmp_path):
    """Fc+ [v > 0] - Fc- [v < 0] and the offset span the same columns where v is never 0:
    identify says the data cannot separate them, never a number."""
    path = synthetic_trace(tmp_path, SYMMETRIC)
    settings = [
        'plant.friction.model="asymmetric"',
        "plant.friction.coulomb_negative_N=20.0",
        "plant.friction.viscous_negative_Ns_per_m=200.0",
    ]
    keys = [
        "plant.friction.coulomb_N",
        "plant.friction.coulomb_negative_N=0:200",
        "plant.friction.offset_N",
    ]
    with pytest.raises(InputError, match="cannot tell .*offset_N apart"):
        identify("emps", path, fit=keys, method="idim", settings=settings)


def test_the_result_folder_holds_what_the_docs_say_and_its_scenario_repeats_the_fit(tmp_path):
    path = synthetic_trace(tmp_path, SYMMETRIC)
    out = tmp_path / "out"
    result = identify("emps", path, method="idim", out=out)
    names = {p.name for p in out.iterdir()}
    assert {"identified.json", "scenario.toml", "traces.parquet", "fit.png", "report.md"} <= names
    record = __import__("json").loads((out / "identified.json").read_text())
    assert record["data"]["sha256"] == result.data["sha256"] and record["method"] == "idim"
    assert set(record["parameters"]) == set(KEYS)
    calibrated = load_axis_scenario(str(out / "scenario.toml"))
    assert calibrated.plant.mass_kg == pytest.approx(result.values["plant.mass_kg"], rel=1e-12)
    assert tomllib.loads((out / "scenario.toml").read_text())["kind"] == "axis"
    traces = pd.read_parquet(out / "traces.parquet")
    assert {"measured_position_m", "simulated_position_m", "residual_command_V"} <= set(traces)


def test_the_axis_loop_agrees_with_its_exact_solution():
    """Without Coulomb friction and encoder the plant is linear, M v' = g u - Fv v - F0, and
    between samples it has a closed form: v(t) = v_inf + (v0 - v_inf) e^(-t/tau), tau = M/Fv.
    The controller is run beside it here in plain Python."""
    m, fv, f0, g, kp, kv = 50.0, 120.0, -1.5, 35.15, 160.18, 243.45
    axis = AxisParams(
        mass_kg=m,
        drive_gain_N_per_V=g,
        stroke_m=0.25,
        max_speed_m_s=1.0,
        friction=AxisFriction(coulomb_N=0.0, viscous_Ns_per_m=fv, offset_N=f0),
    )
    loop = AxisLoop(TS, 10, 0.0, kp, kv, 10.0, 0)
    reference = bang_bang(2.0)
    run = simulate_axis(axis, loop, reference)
    x, v, tau = reference[0], 0.0, m / fv
    q1 = q2 = x
    expected = []
    for r in reference:
        expected.append(x)
        u = min(max(kv * (kp * (r - x) - (x - q2) / (2 * TS)), -10.0), 10.0)
        q2, q1 = q1, x
        v_inf = (g * u - f0) / fv
        decay = math.exp(-TS / tau)
        x += v_inf * TS + (v - v_inf) * tau * (1.0 - decay)
        v = v_inf + (v - v_inf) * decay
    assert np.max(np.abs(run["position_m"] - np.array(expected))) < 1e-10


def test_asymmetric_friction_is_the_coulomb_map_in_each_direction():
    for v in (-0.3, -1e-5, 0.0, 2e-5, 0.4):
        same = asymmetric_coulomb_viscous_force(v, 10.0, 100.0, 10.0, 100.0, 1e-4)
        assert same == coulomb_viscous_force(v, 10.0, 1e-4, 100.0)
    assert asymmetric_coulomb_viscous_force(0.2, 10.0, 100.0, 30.0, 300.0, 1e-4) == (
        pytest.approx(10.0 + 20.0)
    )
    assert asymmetric_coulomb_viscous_force(-0.2, 10.0, 100.0, 30.0, 300.0, 1e-4) == (
        pytest.approx(-30.0 - 60.0)
    )


def test_spread_is_the_inverse_normal_matrix_and_infinite_for_a_blind_direction():
    rng = np.random.default_rng(0)
    jac, r = rng.normal(size=(60, 3)), rng.normal(size=60)
    std, _ = spread(jac, r)
    covariance = (r @ r / 57) * np.linalg.inv(jac.T @ jac)
    assert np.allclose(std, np.sqrt(np.diag(covariance)), rtol=1e-10)
    jac[:, 2] = 0.0
    std, correlation = spread(jac, r)
    assert math.isinf(std[2]) and np.isnan(correlation[2, 0]) and np.isfinite(std[:2]).all()


def test_a_too_long_substep_and_a_runaway_are_refused_in_one_line():
    axis = AxisParams(
        mass_kg=0.01,
        drive_gain_N_per_V=35.15,
        stroke_m=0.25,
        max_speed_m_s=1.0,
        friction=AxisFriction(coulomb_N=20.0, viscous_Ns_per_m=0.0),
    )
    with pytest.raises(ValueError, match="solver.substeps=10 .* at least"):
        simulate_axis(axis, AxisLoop(TS, 10, 0.0, 160.18, 243.45, 10.0, 0), bang_bang(1.0))
    heavy = axis.model_copy(update={"mass_kg": 95.0})
    positive_feedback = AxisLoop(TS, 10, 0.0, -160.18, 243.45, 10.0, 0)
    with pytest.raises(SimulationDiverged, match=r"at t = .* s: axis_\w+ is beyond its bound"):
        simulate_axis(heavy, positive_feedback, bang_bang(20.0))


@pytest.fixture
def trace(tmp_path):
    return synthetic_trace(tmp_path, SYMMETRIC)


def test_bad_data_and_keys_get_one_line_and_exit_code_2(tmp_path, trace):
    frame = pd.read_csv(trace)
    cases = {
        "nan": (frame.assign(qm=frame.qm.where(frame.index != 7)), "not finite at sample 7"),
        "backwards": (frame.assign(t=frame.t.where(frame.index != 5, 0.0)), "does not rise"),
        "slow": (frame.assign(t=2 * frame.t), "sampled every 0.002 s"),
        "no_qm": (frame.drop(columns="qm"), "no column for position_m"),
    }
    for name, (bad, match) in cases.items():
        path = tmp_path / f"{name}.csv"
        bad.to_csv(path, index=False)
        refused_in_one_line(["identify", "emps", "--data", str(path)], match)
    data = ["identify", "emps", "--data", str(trace)]
    refused_in_one_line([*data, "--fit", "plant.no_such_kg=1:2"], "no_such_kg")
    refused_in_one_line([*data, "--fit", "plant.mass_kg=5:1"], "LOW < HIGH")
    refused_in_one_line([*data, "--fit", "plant.mass_kg=-5:1"], "mass_kg")
    refused_in_one_line([*data, "--fit", "plant.friction.model=0:1"], "not a number")
    refused_in_one_line([*data, "--map", "qm"], "FILE_COLUMN=SIGNAL")
    refused_in_one_line([*data, "--map", "nothere=position_m"], "no column nothere")
    refused_in_one_line([*data, "--map", "qm=rod_speed"], "not a signal of this model")
    refused_in_one_line(
        [*data, "--method", "idim", "--fit", "loop.kp_per_s=1:500"], "inverse model"
    )
    refused_in_one_line([*data, "--method", "guess"], "choose one of")
    refused_in_one_line(
        ["identify", "speed-step", "--data", str(trace), "-l", "PI"], "no column for"
    )
    refused_in_one_line(
        [*data, "--fit", "plant.mass_kg,plant.drive_gain_N_per_V=0.5:2"], "take a factor"
    )
    refused_in_one_line([*data, "--fit", "plant.mass_kg=*0.5:2"], "values, not factors")
    refused_in_one_line([*data, "--label", "PID"], "one controller")
    refused_in_one_line(["identify", "emps", "--data", str(tmp_path / "none.csv")], "no such file")
    refused_in_one_line(["identify", "emps", "--data", str(tmp_path)], "give a .csv")


def test_an_actuator_scenario_refuses_a_trace_without_its_readings_from_python(trace):
    with pytest.raises(InputError, match="compares controller sets; choose the one"):
        identify("bench-step", trace)
    with pytest.raises(InputError, match="no column for time_s, angle_rad"):
        identify("bench-step", trace, label="PID")


def test_a_series_of_traces_tracks_a_rising_friction_with_its_intervals(tmp_path):
    """Wear tracking: three traces of an axis whose Coulomb friction rises, identified in turn
    from the command line, give a table of each key against the cycle count."""
    paths = []
    for coulomb in (15.0, 18.0, 21.0):
        folder = tmp_path / f"fc{coulomb:g}"
        folder.mkdir()
        friction = AxisFriction(coulomb_N=coulomb, viscous_Ns_per_m=150.0, offset_N=-2.0)
        paths.append(synthetic_trace(folder, friction))
    out = tmp_path / "series"
    args = ["identify", "emps", "--method", "idim", "--out", str(out)]
    for path, cycles in zip(paths, ("0", "5000", "10000"), strict=True):
        args += ["--data", str(path), "--at", cycles]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out / "series.csv")
    assert list(table["at"]) == [0, 5000, 10000]
    found = table["plant.friction.coulomb_N"]
    assert found.to_numpy() == pytest.approx([15.0, 18.0, 21.0], rel=0.02)
    assert (table["plant.friction.coulomb_N interval95"] > 0).all()
    assert (out / "series.png").is_file() and len([p for p in out.iterdir() if p.is_dir()]) == 3
    twice = [str(tmp_path / "again") if a == str(out) else a for a in args[:-1]] + ["5000"]
    refused_in_one_line(twice, "each trace needs its own")


@pytest.mark.parametrize(
    "items",
    [
        ["plant.friction.coulomb_Nm,plant.friction.coulomb_Nm=*0.5:2"],
        ["plant.friction.coulomb_Nm=0.1:1", "plant.friction.coulomb_Nm,plant.mass_kg=*0.5:2"],
    ],
)
def test_a_path_fitted_twice_is_refused_even_inside_a_factor_group(items):
    from emasim.identification.fit import parse_keys

    with pytest.raises(InputError, match="plant.friction.coulomb_Nm given twice"):
        parse_keys(items, [])


def test_every_field_of_an_axis_has_an_upper_bound():
    """A fit's range is checked against the field's bounds: a field without an upper one let
    ``--fit mass_kg=1:1e300`` through (issue 50)."""
    from pydantic import BaseModel

    from emasim.scenarios.axis_scenario import AxisScenario

    unbounded = []

    def walk(model: type[BaseModel], prefix: str) -> None:
        for name, field in model.model_fields.items():
            annotation = field.annotation
            if isinstance(annotation, type) and issubclass(annotation, BaseModel):
                walk(annotation, f"{prefix}{name}.")
            elif annotation in (float, int) or annotation == (float | None):
                bounds = [m for m in field.metadata if hasattr(m, "le") or hasattr(m, "lt")]
                if not bounds:
                    unbounded.append(prefix + name)

    walk(AxisScenario, "")
    assert unbounded == []


def test_starts_are_bounded_as_runs_are(tmp_path):
    """``identify --starts 100000`` never returned (issue 50)."""
    path = synthetic_trace(tmp_path, SYMMETRIC, suffix=".parquet")
    refused_in_one_line(
        ["identify", "emps", "--data", str(path), "--starts", "100000"], "give 1 to 1000"
    )


def test_a_fit_range_beyond_the_fields_bound_is_refused(tmp_path):
    path = synthetic_trace(tmp_path, SYMMETRIC, suffix=".parquet")
    refused_in_one_line(
        ["identify", "emps", "--data", str(path), "--fit", "plant.mass_kg=1:1e300"], "mass_kg"
    )
