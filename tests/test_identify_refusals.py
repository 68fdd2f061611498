"""``emasim identify`` refuses, in one line, what it cannot identify or simulate, and never
reports a start or a bound as a converged fit.

The traces are the synthetic EMPS-like ones of tests/test_identification.py (its known
parameters), altered as a user's file might be: a column left out, in other units, traces
joined end to end.
"""

import warnings

import numpy as np
import pandas as pd
import pytest
from helpers import refused_in_one_line
from test_identification import KEYS, START, SYMMETRIC, synthetic_trace

from emasim.errors import InputError
from emasim.identification.fit import Key, check_identifiable, output_error
from emasim.identification.identify import check_identified, identify, on_bound


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    """The synthetic trace as a table (emps's column names)."""
    return pd.read_csv(synthetic_trace(tmp_path_factory.mktemp("trace"), SYMMETRIC))


def written(frame: pd.DataFrame, folder, name: str):
    path = folder / f"{name}.csv"
    frame.to_csv(path, index=False)
    return path


def test_a_trace_without_the_drive_input_is_fitted_on_its_position(tmp_path, frame):
    """Without the drive's input the relative residuals are the position's, ~1e-5: the
    optimiser's gradient test stopped at the start and reported it as converged (mass 100,
    the scenario's). The position alone identifies the keys."""
    path = written(frame.drop(columns="vir"), tmp_path, "position-only")
    result = identify("emps", path, settings=START)
    assert result.idim is None and result.fit.converged
    for key, truth in KEYS.items():
        assert result.values[key] == pytest.approx(truth, rel=0.002, abs=0.01), key


def test_a_key_the_outputs_do_not_see_is_refused_before_the_fit(tmp_path, frame, monkeypatch):
    path = written(frame, tmp_path, "trace")
    monkeypatch.setattr("scipy.optimize.least_squares", None)  # the fit must not start
    keys = ["plant.mass_kg", "plant.max_speed_m_s=0.5:5"]  # a divergence bound only
    with pytest.raises(InputError, match=r"^--fit: plant.max_speed_m_s cannot be identified"):
        identify("emps", path, fit=keys)
    refused_in_one_line(
        ["identify", "emps", "--data", str(path), "--fit", keys[0], "--fit", keys[1]],
        "plant.max_speed_m_s cannot be identified from this trace",
    )


def test_a_negligible_or_collinear_column_at_the_start_is_refused():
    """A column too small to matter (spread would give it a finite, meaningless interval)
    and two keys acting alike."""
    keys = [Key("a", 0.0, 1.0), Key("b", 0.0, 10.0), Key("c", -1.0, 1.0)]
    rng = np.random.default_rng(1)
    jac = rng.normal(size=(50, 3))
    check_identifiable(jac, keys)
    small = jac.copy()
    small[:, 1] = 1e-9 * rng.normal(size=50)
    with pytest.raises(InputError, match="^--fit: b cannot be identified"):
        check_identifiable(small, keys)
    alike = jac.copy()
    alike[:, 2] = 5.0 * alike[:, 0]
    with pytest.raises(InputError, match="cannot tell a, c apart"):
        check_identifiable(alike, keys)


def test_a_value_the_optimiser_stopped_short_of_a_bound_is_on_it():
    """The bench's fit stops within its tolerance (1e-3 of a value) of a bound it is pressed
    against: 3.4e-7 of the range from it is on it, not 'identified'."""
    key = Key("plant.backlash.width_mm", 0.01, 0.6)
    near = {key.name: 0.6 - 3.4e-7}
    assert on_bound([key], near, tolerance=1e-3) == {key.name: "upper"}
    assert on_bound([key], {key.name: 0.3}, tolerance=1e-3) == {}
    assert on_bound([key], {key.name: 0.01 + 1e-12}) == {key.name: "lower"}


def test_a_fit_that_pins_nothing_down_is_refused():
    """The bench's rod sensor in mm: backlash 0.6 ± 270 mm over a 0.01-0.6 range, and the
    free run missing the rod's reading by 99.9 %."""
    key = Key("plant.backlash.width_mm", 0.01, 0.6)
    good = {"rod_position_m": 2e-4, "feature drive_lost_motion_m": 1e-4, "rmse_mm": 5.0}
    check_identified("readings.parquet", [key], {key.name: 5e-4}, good)
    with pytest.raises(InputError, match=r"interval of plant.backlash.width_mm \(± 270\)"):
        check_identified("readings.parquet", [key], {key.name: 270.0}, good)
    with pytest.raises(InputError, match="misses rod_position_m by 99.9 %"):
        check_identified("r.parquet", [key], {key.name: 5e-4}, {"rod_position_m": 0.999})


def test_many_starts_keep_scipys_warnings_off_the_console():
    keys = [Key("a", 0.0, 1.0), Key("b", -2.0, 2.0)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = output_error(lambda x: x - [0.3, 0.5], keys, np.array([0.9, -1.0]), starts=6)
    assert fit.values == pytest.approx({"a": 0.3, "b": 0.5})


def test_a_time_column_in_ms_is_refused_by_the_sampling_check(tmp_path, frame):
    path = written(frame.assign(t=1e3 * frame.t), tmp_path, "ms")
    refused_in_one_line(["identify", "emps", "--data", str(path)], "sampled every 1 s")


def test_identified_values_that_cannot_be_simulated_are_named(tmp_path, frame):
    """IDIM-LS on a drive input in kV gives every value a thousandth of the truth: the free
    run with them diverges (on EMPS in mm, the sub-step check failed), named as the
    identified values, not an internal error."""
    kv = written(frame.assign(vir=1e-3 * frame.vir), tmp_path, "kV")
    refused_in_one_line(
        ["identify", "emps", "--data", str(kv), "--method", "idim"],
        "--method idim: the identified values (plant.mass_kg = 0.08",
    )


def test_positions_in_mm_or_joined_with_a_jump_are_refused(tmp_path, frame):
    """Both reached IDIM-LS, whose values then failed the free run's sub-step check (an
    internal error); a jump of 1.4 mm at the seam gave a mass of 24 kg (truth 80)."""
    mm = written(frame.assign(qm=1e3 * frame.qm, qg=1e3 * frame.qg), tmp_path, "mm")
    later = frame.assign(qm=frame.qm + 0.02, qg=frame.qg + 0.02)
    tiled = pd.concat([frame, later], ignore_index=True)
    tiled["t"] = 1e-3 * np.arange(len(tiled))
    tiled = written(tiled, tmp_path, "tiled")
    for path, match in ((mm, "beyond the axis's stroke"), (tiled, "from sample 7999 to 8000")):
        for method in ("idim", "output-error"):
            refused_in_one_line(
                ["identify", "emps", "--data", str(path), "--method", method], match
            )


def test_a_series_whose_result_folders_collide_is_refused_before_the_fits(tmp_path, frame):
    path = written(frame, tmp_path, "trace")
    args = ["identify", "emps", "--method", "idim", "--out", str(tmp_path / "series")]
    args += ["--data", str(path), "--at", "2024-01-01", "--data", str(path), "--at", "2024/01/01"]
    refused_in_one_line(args, "--at 2024-01-01, 2024/01/01: these traces' result folders")
    assert not (tmp_path / "series").exists()


def test_unbounded_ranges_and_a_key_twice_in_a_factor_group_are_refused(tmp_path, frame):
    """Already refused (issue 50): every field a fit may vary has a finite upper bound, the
    bench's as the axis's, and a path is fitted once."""
    from emasim.experiments.study import sampled_table
    from emasim.experiments.variation import Variation
    from emasim.scenarios.loader import read_scenario_file, validate_scenario

    path = written(frame, tmp_path, "trace")
    data = ["identify", "emps", "--data", str(path)]
    refused_in_one_line([*data, "--fit", "plant.mass_kg=1:1e300"], "less than or equal to")
    refused_in_one_line([*data, "--fit", "plant.mass_kg,plant.mass_kg=*0.5:2"], "given twice")
    raw, source = read_scenario_file("bench-identify")
    resolved = validate_scenario(raw, source).model_dump(mode="json")

    def numbers(node, prefix=""):
        if isinstance(node, dict):
            for name, value in node.items():
                yield from numbers(value, f"{prefix}{name}.")
        elif isinstance(node, int | float | list) and not isinstance(node, bool):
            values = node if isinstance(node, list) else [node]
            if values and all(isinstance(v, int | float) for v in values):
                yield prefix[:-1]

    accepted = []
    for key in numbers(resolved):
        variation = Variation(key, (key,), None, None, False)
        try:
            validate_scenario(sampled_table(raw, resolved, [variation], {key: 1e300}), source)
            accepted.append(key)
        except InputError:
            pass
    assert accepted == []
