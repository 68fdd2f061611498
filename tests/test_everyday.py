"""Everyday use: one way to run (``--label``, gains from the matching set, ``emasim.run``, a
saved scenario that repeats the run, a user's own law with a full Result), the CLI's
``--version``, ``--quiet`` and ``--verbose``, and the trace formats (parquet, CSV, MATLAB)."""

import json
import tomllib

import numba
import numpy as np
import pytest
import scipy.io
from typer.testing import CliRunner

import emasim
from emasim.cli import app
from emasim.control.slot import CONTROLLER_SIG, Compiled
from emasim.experiments.runs import run_scenario
from emasim.output import foreign_files
from emasim.scenarios.loader import load_scenario, read_scenario_file, validate_scenario
from emasim.sim.result import Comparison, Result

runner = CliRunner()
SHORT = "duration_s=0.3"


def invoke(*args):
    return runner.invoke(app, list(args))


def compared_speed_set(label: str) -> dict:
    raw, _ = read_scenario_file("speed-step")
    (entry,) = [e for e in raw["compare"] if e["label"] == label]
    return entry["controllers"]["speed"]


def test_version_is_the_package_version():
    result = invoke("--version")
    assert result.exit_code == 0
    assert result.output.strip() == f"emasim {emasim.__version__}"


def test_label_runs_one_set_with_its_gains_and_the_file_repeats_it(tmp_path):
    out = tmp_path / "smc"
    result = invoke("run", "speed-step", "--label", "SMC", "--set", SHORT, "--out", str(out))
    assert result.exit_code == 0, result.output
    assert "gains: those of the comparison's controller set SMC" in result.output
    saved = tomllib.loads((out / "scenario.toml").read_text())
    assert "compare" not in saved
    assert saved["controllers"]["speed"] == compared_speed_set("SMC")
    meta = json.loads((out / "meta.json").read_text())
    assert meta["gains_from"] == "SMC"
    again = run_scenario(validate_scenario(saved))
    assert np.array_equal(again.data, Result.load(out).data, equal_nan=True)


def test_a_controller_choice_starts_from_the_matching_sets_gains():
    chosen = load_scenario("speed-step", controllers=["speed=st-gpio"])
    tuned = compared_speed_set("ST-SMC+GPIO")
    assert (
        chosen.controllers.speed.model_dump(exclude_unset=False)
        == load_scenario("speed-step", label="ST-SMC+GPIO").controllers.speed.model_dump()
    )
    assert chosen.controllers.speed.boundary_layer_rad_s == tuned["boundary_layer_rad_s"]
    assert chosen.tuning["gains_from"] == "ST-SMC+GPIO"
    unmatched = load_scenario("speed-step", controllers=["speed=adrc"])
    assert "gains_from" not in unmatched.tuning


def test_an_unknown_label_is_one_line():
    result = invoke("run", "speed-step", "--label", "nope")
    assert result.exit_code == 2
    assert "--label: 'nope' is no controller set" in result.output
    assert "PI, SMC, ST-SMC, ST-SMC+GPIO" in result.output


def test_quiet_prints_no_table_and_verbose_conflicts(tmp_path):
    out = tmp_path / "q"
    quiet = invoke("--quiet", "run", "speed-step", "-l", "PI", "--set", SHORT, "--out", str(out))
    assert quiet.exit_code == 0
    assert quiet.output.strip() == ""
    assert (out / "metrics.json").exists()
    loud = invoke("run", "speed-step", "-l", "PI", "--set", SHORT, "--out", str(tmp_path / "l"))
    assert "rise time" in loud.output and "wrote" in loud.output
    both = invoke("--quiet", "--verbose", "list")
    assert both.exit_code == 2 and "--quiet and --verbose" in both.output


@pytest.mark.parametrize("trace_format", ["csv", "mat"])
def test_trace_formats_round_trip(tmp_path, trace_format):
    out = tmp_path / trace_format
    result = invoke(
        "run",
        "position-step",
        "-l",
        "PI",
        "--set",
        SHORT,
        "--format",
        trace_format,
        "--out",
        str(out),
    )
    assert result.exit_code == 0, result.output
    assert not (out / "result.parquet").exists() and foreign_files(out) == []
    loaded = Result.load(out)
    fresh = emasim.run(load_scenario("position-step", label="PI", settings=[SHORT]))
    assert loaded.columns == fresh.columns
    assert np.array_equal(loaded.data, fresh.data, equal_nan=True)  # CSV: 18 digits
    if trace_format == "mat":
        struct = scipy.io.loadmat(out / "result.mat", squeeze_me=True, struct_as_record=False)
        assert struct["emasim"].units.iq_A == "A"
        assert struct["emasim"].label == "PI"


def test_a_bad_format_is_one_line(tmp_path):
    result = invoke("run", "speed-step", "--format", "xls", "--out", str(tmp_path / "x"))
    assert result.exit_code == 2
    assert "--format: one of parquet, csv, mat" in result.output
    assert not (tmp_path / "x").exists()


def test_traces_no_mat_file_can_hold_are_refused_before_the_run(tmp_path):
    """1000 s of speed-step at 10 kHz: 2.3 GB of traces, over a MAT-file variable's 2 GiB;
    refused in one line before anything is simulated (the run would take half a minute)."""
    out = tmp_path / "big"
    args = ["run", "speed-step", "-l", "PI", "--set", "duration_s=1000", "--format", "mat"]
    result = invoke(*args, "--out", str(out))
    assert result.exit_code == 2, result.output
    assert "--format mat: the traces would be 2.3" in result.output
    assert "solver.record_period_s" in result.output and "simulated" not in result.output
    assert not out.exists()


def test_the_mat_limit_is_matlabs_2_gib_for_one_variable():
    from emasim.sim.result import MAT_MAX_BYTES, check_mat_size

    columns = 8
    rows = MAT_MAX_BYTES // (8 * columns)
    check_mat_size(rows - 1, columns)
    with pytest.raises(emasim.errors.InputError, match="under 2.15 GB"):
        check_mat_size(rows, columns)


def test_meta_says_where_and_how_it_ran(tmp_path, monkeypatch):
    out = tmp_path / "m"
    args = ["run", "speed-step", "-l", "PI", "--set", SHORT, "--out", str(out)]
    monkeypatch.setattr("sys.argv", ["emasim", *args])
    invoke(*args)
    meta = json.loads((out / "meta.json").read_text())
    for key in ("numpy", "scipy", "numba", "python", "platform", "command_line"):
        assert meta[key], key
    assert meta["command_line"].startswith("emasim run speed-step -l PI")
    assert meta["label"] == "PI"
    assert len(meta.get("git_commit", "0" * 40)) == 40  # a git checkout, as in development


def test_emasim_run_returns_the_comparison_with_plot_and_save(tmp_path):
    comparison = emasim.run(load_scenario("speed-step", settings=[SHORT]))
    assert isinstance(comparison, Comparison)
    assert list(comparison.metrics) == ["PI", "SMC", "ST-SMC", "ST-SMC+GPIO"]
    assert comparison.plot().axes
    folder = comparison.save(tmp_path / "c")
    for label in ("pi", "smc"):
        assert (folder / label / "plot.png").exists()  # a plot in every run folder


def test_emasim_run_takes_a_name_or_a_path_with_the_command_lines_options(tmp_path):
    """emasim.run("speed-step", label=..., settings=[...]) reads the scenario as `emasim run`
    does: the same traces as load_scenario then run; the options with a Scenario are refused in
    one line; dir(emasim) lists run, linearize and identify before their first use."""
    by_name = emasim.run("speed-step", label="PI", settings=[SHORT])
    by_scenario = emasim.run(load_scenario("speed-step", label="PI", settings=[SHORT]))
    assert isinstance(by_name, Result)
    np.testing.assert_array_equal(by_name["motor_speed_rad_s"], by_scenario["motor_speed_rad_s"])
    path = tmp_path / "mine.toml"
    by_name.save(tmp_path / "run")
    path.write_text((tmp_path / "run" / "scenario.toml").read_text())
    again = emasim.run(path)
    np.testing.assert_array_equal(again["motor_speed_rad_s"], by_name["motor_speed_rad_s"])
    with pytest.raises(emasim.errors.InputError, match="apply to a scenario's name or path"):
        emasim.run(load_scenario("speed-step"), label="PI")
    assert {"run", "linearize", "identify", "__version__"} <= set(dir(emasim))


@numba.njit(CONTROLLER_SIG)
def proportional_speed_law(state, params, meas, ref, ts, out):
    out[0] = params[0] * (ref[0] - meas[0])
    out[1] = 0.0


def test_a_law_of_ones_own_gives_a_full_result(tmp_path):
    scenario = load_scenario("speed-step", label="PI", settings=[SHORT])
    setup = scenario.setup().with_(
        speed=Compiled(proportional_speed_law, np.array([0.5]), np.zeros(1))
    )
    mine = run_scenario(scenario, setup=setup)
    library = run_scenario(scenario)
    assert mine.meta["custom_laws"] == {"speed": "proportional_speed_law"}
    assert "custom_laws" not in library.meta
    assert mine.metrics["rise_time_s"] != library.metrics["rise_time_s"]
    assert mine.description.loops["speed"] == "proportional_speed_law"
    saved = mine.save(tmp_path / "mine")
    assert tomllib.loads((saved / "scenario.toml").read_text())["name"] == "speed-step"
    assert (saved / "plot.png").exists()


def test_a_plain_python_law_is_refused_in_one_line():
    plain = proportional_speed_law.py_func  # the same law, not compiled
    with pytest.raises(emasim.errors.InputError, match="plain Python function; compile it with"):
        Compiled(plain, np.array([0.5]), np.zeros(1))


def test_plots_name_the_run_zoom_on_its_events_and_share_compared_axes():
    from emasim.analysis.plots import plot_bench, plot_comparison, plot_result

    comparison = emasim.run(load_scenario("speed-step", settings=["duration_s=0.6"]))
    pi = comparison.results["PI"]
    pi.meta["overrides"] = ["duration_s=0.6"]
    figure = plot_result(pi)
    top = figure.axes[0]
    assert top.get_title() == "speed-step: PI (duration_s=0.6)"
    assert [inset.get_title() for inset in top.child_axes] == ["from 0 s", "from 0.4 s"]
    overlay = plot_comparison(comparison.results)
    error = overlay.axes[1]
    linthresh = error.yaxis.get_transform().linthresh
    ticks = [v for v in error.get_yticks() if v != 0]
    assert ticks and all(abs(v) >= 10 * linthresh for v in ticks)  # none crowd zero
    overlay.canvas.draw()  # lay the figure out: display coordinates of axes and legends
    for ax in overlay.axes[:3]:  # each legend right of its axes, outside the data
        assert ax.get_legend().get_window_extent().x0 >= ax.get_window_extent().x1
    bench = emasim.run(load_scenario("bench-step", settings=["duration_s=0.05"]))
    axes = plot_bench(bench.results).axes
    n = len(bench.results)
    for row in (axes[:n], axes[n : 2 * n]):
        assert all(row[0].get_shared_y_axes().joined(row[0], other) for other in row[1:])


def test_a_choice_over_a_cascade_named_in_the_file(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(
        'name = "c"\nduration_s = 0.05\ncontrollers = "hybrid"\n[plant]\npreset = "sea805"\n'
        '[reference]\nposition_mm = [{ type = "step", final = 1.0 }]\n'
    )
    scenario = load_scenario(str(path), controllers=["speed=pi"])
    assert scenario.controllers.speed.name == "pi"
    assert scenario.controllers.position.name == "rbf-smc"  # the cascade's, kept
    result = invoke("run", str(path), "-c", "speed=pi", "--label", "x")
    assert result.exit_code == 2 and "no controller set" in result.output


def test_to_csv_to_mat_and_save_take_overwrite_and_never_replace_a_users_file(tmp_path):
    """The Python API's files: CSV in the shortest text that reads back to the same floats,
    written atomically; ``overwrite=True`` replaces emasim's own file or folder, never a
    user's, and the refusals speak of the arguments, not of command-line flags."""
    from scipy.io import loadmat

    result = emasim.run("speed-step", label="PI", settings=[SHORT])
    path = tmp_path / "run.csv"
    result.to_csv(path)
    back = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    np.testing.assert_array_equal(back, result.data)  # NaN compares equal here too
    assert path.read_text().splitlines()[0] == ",".join(result.columns)
    full = len(",".join([f"{1.0:.18e}"] * result.data.shape[1]))  # the old format's row
    assert path.stat().st_size < 0.8 * full * result.data.shape[0]
    with pytest.raises(emasim.errors.OutputError, match="pass overwrite=True to replace it"):
        result.to_csv(path)
    result.to_csv(path, overwrite=True)
    mat = tmp_path / "run.mat"
    result.to_mat(mat)
    result.to_mat(mat, overwrite=True)
    assert loadmat(mat)["emasim"].dtype.names[0] == "t_s"
    for text in ("years,of,work\n", "t_s,motor_speed_rad_s\n0.0,my notes\n"):
        mine = tmp_path / "mine.csv"
        mine.write_text(text)
        for write in (result.to_csv, result.to_mat):
            with pytest.raises(emasim.errors.OutputError, match="emasim did not write it"):
                write(mine, overwrite=True)
        assert mine.read_text() == text
    folder = result.save(tmp_path / "saved", plot=False)
    with pytest.raises(emasim.errors.OutputError, match="pass overwrite=True to replace it"):
        result.save(folder, plot=False)
    assert result.save(folder, plot=False, overwrite=True) == folder


def test_no_shipped_gains_fail_the_checks_emasim_applies_to_them():
    """Every controller set of every shipped scenario builds without a warning (the
    super-twisting's eq. 37 check among them): what `emasim run` and `reproduce` print is
    about the runs, never about the gains emasim ships."""
    import warnings

    from emasim.scenarios.loader import builtin_scenarios

    for name in sorted(builtin_scenarios()):
        for label, variant in load_scenario(name).variants():
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                variant.setup()
            assert [str(w.message) for w in caught] == [], (name, label)


def test_a_result_is_a_python_control_time_response():
    result = emasim.run("speed-step", label="PI", settings=[SHORT])
    response = result.to_timeresponse(["motor_speed_rad_s"], inputs=["speed_ref_rad_s"])
    np.testing.assert_array_equal(response.time, result.t)
    np.testing.assert_array_equal(response.outputs, result["motor_speed_rad_s"])
    np.testing.assert_array_equal(response.inputs, result["speed_ref_rad_s"])
    assert response.output_labels == ["motor_speed_rad_s"]
    with pytest.raises(emasim.errors.InputError, match="no_such_column; the columns: t_s"):
        result.to_timeresponse(["no_such_column"])


def test_label_given_twice_runs_both_sets_as_a_comparison(tmp_path):
    """``--label PI --label SMC`` runs those two sets, in that order, each with its gains (it
    ran SMC alone, silently); one set twice, or with ``--controller``, is one line."""
    out = tmp_path / "two"
    result = invoke(
        "run", "speed-step", "-l", "SMC", "-l", "PI", "--set", SHORT, "--out", str(out), "--no-plot"
    )
    assert result.exit_code == 0, result.output
    saved = tomllib.loads((out / "scenario.toml").read_text())
    assert [entry["label"] for entry in saved["compare"]] == ["SMC", "PI"]
    assert saved["compare"][0]["controllers"]["speed"] == compared_speed_set("SMC")
    assert set(Comparison.load(out).results) == {"SMC", "PI"}
    twice = invoke("run", "speed-step", "-l", "PI", "-l", "PI")
    assert twice.exit_code == 2 and "--label: PI given twice" in twice.output, twice.output
    with_loop = invoke("run", "speed-step", "-l", "PI", "-l", "SMC", "-c", "speed=smc")
    assert with_loop.exit_code == 2 and "one --label" in with_loop.output, with_loop.output
