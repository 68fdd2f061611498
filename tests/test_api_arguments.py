"""The Python API refuses what it cannot answer: every wrong type or out-of-range value given
to emasim.run, emasim.linearize, emasim.identify, the acceptance Battery,
Acceptance.frequency_response and run_acceptance is one InputError line naming the argument
and what it allows, raised when called (a Battery: when built), before anything simulates;
never a TypeError, a ValueError or pydantic's error about a scenario built inside, nor a
string read as True or as its characters. The values the command line and the documentation
use still pass."""

import math

import pytest
from typer.testing import CliRunner

import emasim
from emasim.cli import app
from emasim.errors import InputError
from emasim.experiments import acceptance as ac
from emasim.experiments import batch
from emasim.scenarios.loader import load_scenario
from emasim.sim import engine


@pytest.fixture(autouse=True)
def nothing_simulates(monkeypatch):
    """Each check fires before a run: loading the compiled core fails the test."""

    def refused(*args, **kwargs):
        raise AssertionError("a simulation started before the arguments were checked")

    monkeypatch.setattr(engine, "load_compiled", refused)
    monkeypatch.setattr(batch, "load_engine", refused)


def refused(call, needle):
    """``call()`` raises InputError, one line, naming ``needle``."""
    with pytest.raises(InputError) as caught:
        call()
    message = str(caught.value)
    assert needle in message and "\n" not in message, message
    return message


BATTERY = [  # (settings, what the message names)
    ({"small_amplitude": -0.01}, "Battery: small_amplitude must be a finite number above 0"),
    ({"small_amplitude": 0.6}, "Battery: small_amplitude"),  # beyond half the stroke
    ({"large_amplitude": "0.1"}, "Battery: large_amplitude must be a number"),
    ({"chirp_s": math.inf}, "Battery: chirp_s"),
    ({"chirp_s": "30"}, "Battery: chirp_s must be a number"),
    ({"chirp_s": 0.0}, "Battery: chirp_s"),
    ({"frequencies_Hz": (-1,)}, "Battery: frequencies_Hz must be a non-empty list"),
    ({"frequencies_Hz": ()}, "Battery: frequencies_Hz must be a non-empty list"),
    ({"frequencies_Hz": "1, 2"}, "Battery: frequencies_Hz"),
    ({"frequencies_Hz": 4.0}, "Battery: frequencies_Hz"),
    ({"frequencies_Hz": (1.0, math.nan)}, "Battery: frequencies_Hz"),
    ({"frequencies_Hz": (True,)}, "Battery: frequencies_Hz"),
    ({"stiffness_frequencies_Hz": ()}, "Battery: stiffness_frequencies_Hz"),
    ({"settle_s": -1.0}, "Battery: settle_s"),
    ({"settle_cycles": 1.5}, "Battery: settle_cycles must be a whole number"),
    ({"measure_cycles": 0}, "Battery: measure_cycles"),
    ({"measure_min_s": -0.1}, "Battery: measure_min_s"),
    ({"triangle_amplitude": 0.0}, "Battery: triangle_amplitude"),
    ({"triangle_period_s": math.nan}, "Battery: triangle_period_s"),
    ({"triangle_cycles": 1}, "Battery: triangle_cycles"),  # no whole rising and falling sweep
    ({"triangle_cycles": True}, "Battery: triangle_cycles"),
    ({"detection_mm": None}, "Battery: detection_mm"),
    ({"load_step": 2.0}, "Battery: load_step"),  # twice the stall force
    ({"load_hold_s": 0}, "Battery: load_hold_s"),
    ({"dynamic_force": -0.05}, "Battery: dynamic_force"),
    ({"rate_step_fraction": 0.8}, "Battery: rate_step_fraction"),
    ({"stall_ramp_per_s": math.inf}, "Battery: stall_ramp_per_s"),
    ({"stall_deflection_mm": "1"}, "Battery: stall_deflection_mm"),
    ({"cycle_frequency_Hz": 0.0}, "Battery: cycle_frequency_Hz"),
    ({"excitation": "noise"}, "excitation must be one of stepped, chirp"),
    ({"excitation": ["chirp"]}, "excitation must be one of stepped, chirp"),
]


@pytest.mark.parametrize(("settings", "needle"), BATTERY)
def test_a_battery_refuses_each_setting_out_of_its_range_when_built(settings, needle):
    refused(lambda: ac.Battery(**settings), needle)


def test_the_batteries_the_command_line_and_the_docs_build_still_pass():
    default = ac.Battery()
    assert default.frequencies_Hz == ac.DECADE_EIGHTHS and default.chirp_s == 30.0
    assert ac.Battery(excitation="chirp", chirp_s=30.0).excitation == "chirp"
    listed = ac.Battery(frequencies_Hz=[1, 4, 16], settle_cycles=0, measure_min_s=0)
    assert listed.frequencies_Hz == (1.0, 4.0, 16.0) and hash(listed)  # a tuple, kept frozen


def sheet():
    """An Acceptance as run_acceptance returns it, without its runs."""
    scenario = load_scenario("position-step")
    meta = {"linear_model": {"PI": "none: not run"}}
    return ac.Acceptance(scenario, ac.Battery(), {"PI": {}}, {"PI": {"responses": []}}, meta)


@pytest.mark.parametrize(
    ("args", "kwargs", "needle"),
    [
        ((["PI"],), {}, "frequency_response: label must be one of PI"),
        (("nope",), {}, "frequency_response: label must be one of PI"),
        (("PI",), {"input": ["rod_force_N"]}, "frequency_response: input must be one of"),
        (("PI",), {"output": 3}, "frequency_response: output must be one of"),
        (("PI",), {"amplitude": 1}, "frequency_response: amplitude for position_command"),
        (("PI",), {"linear": "no"}, "frequency_response: linear must be True or False"),
        (("PI",), {"linear": 1}, "frequency_response: linear must be True or False"),
    ],
)
def test_frequency_response_refuses_names_and_flags_of_the_wrong_kind(args, kwargs, needle):
    refused(lambda: sheet().frequency_response(*args, **kwargs), needle)


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda s: ac.run_acceptance("position-step"), "run_acceptance: scenario must be"),
        (lambda s: ac.run_acceptance(s, labels="PI"), "run_acceptance: labels"),
        (lambda s: ac.run_acceptance(s, labels=[1]), "run_acceptance: labels"),
        (lambda s: ac.run_acceptance(s, battery={"chirp_s": 8}), "run_acceptance: battery"),
        (lambda s: ac.run_acceptance(s, client="localhost:8786"), "run_acceptance: client"),
        (lambda s: ac.run_acceptance(s, progress=5), "run_acceptance: progress"),
        (lambda s: ac.run_acceptance(s, labels=["nope"]), "--label: 'nope'"),
        # recorded every 1 ms: the Nyquist frequency is 500 Hz
        (
            lambda s: ac.run_acceptance(s, battery=ac.Battery(frequencies_Hz=(1.0, 600.0))),
            "Battery: frequencies_Hz reaches 600 Hz: give frequencies below 500 Hz",
        ),
        (
            lambda s: ac.run_acceptance(
                s, battery=ac.Battery(excitation="chirp", stiffness_frequencies_Hz=(400.0,))
            ),
            "Battery: stiffness_frequencies_Hz reaches 400 Hz, and the chirp sweeps",
        ),
        (
            lambda s: ac.run_acceptance(s, battery=ac.Battery(cycle_frequency_Hz=500.0)),
            "Battery: cycle_frequency_Hz",
        ),
        # valid settings whose runs this plant cannot take (a triangle shorter than one tick)
        (
            lambda s: ac.run_acceptance(
                s, labels=["PI"], battery=ac.Battery(settle_s=1e-6, triangle_period_s=1e-6)
            ),
            "Battery: these settings make a run position-step refuses: duration_s",
        ),
    ],
)
def test_run_acceptance_refuses_its_arguments_before_any_run(call, needle):
    scenario = load_scenario("position-step", settings=["solver.record_period_s=0.001"])
    refused(lambda: call(scenario), needle)


def test_the_command_line_keeps_its_excitation_message():
    result = CliRunner().invoke(app, ["acceptance", "position-step", "--excitation", "noise"])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "excitation must be one of stepped, chirp, got 'noise'" in result.output


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"scenario": 3}, "emasim.run: scenario must be"),
        ({"label": 3}, "emasim.run: label must be a string or None"),
        ({"label": "PI", "settings": "duration_s=1"}, "emasim.run: settings must be a list"),
        ({"controllers": "speed=pi"}, "emasim.run: controllers must be a list"),
        ({"trust_fmu": "no"}, "emasim.run: trust_fmu must be True or False"),
        ({"progress": 5}, "emasim.run: progress"),
        ({"client": "localhost:8786"}, "emasim.run: client"),
    ],
)
def test_run_refuses_its_arguments(kwargs, needle):
    kwargs = {"scenario": "speed-step"} | kwargs
    refused(lambda: emasim.run(**kwargs), needle)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"at_s": "1"}, "linearize: at_s must be a number"),
        ({"at_s": -1.0}, "linearize: at_s must be a finite number from 0"),
        ({"operating_speed_rpm": "100"}, "linearize: operating_speed_rpm must be a number"),
        ({"operating_speed_rpm": math.inf}, "linearize: operating_speed_rpm"),
        ({"friction": "no"}, "linearize: friction must be True or False"),
        ({"discrete": 1}, "linearize: discrete must be True or False"),
        ({"settings": "duration_s=1"}, "linearize: settings must be a list of strings"),
        ({"controllers": "speed=pi"}, "linearize: controllers must be a list of strings"),
        ({"label": ["PI"]}, "linearize: label must be a string or None"),
        ({"scenario": 3}, "linearize: scenario must be"),
    ],
)
def test_linearize_refuses_its_arguments(kwargs, needle):
    kwargs = {"scenario": "speed-step", "label": "PI"} | kwargs
    refused(lambda: emasim.linearize(**kwargs), needle)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"scenario": 3}, "identify: scenario must be a string or a Path"),
        ({"data": 3}, "identify: data must be a string or a Path"),
        ({"fit": "a=1:2"}, "identify: fit must be a list of strings"),
        ({"mapping": "x=position"}, "identify: mapping must be a list of strings"),
        ({"settings": "duration_s=1"}, "identify: settings must be a list of strings"),
        ({"validate": "other.csv"}, "identify: validate must be a list of paths"),
        ({"method": ["idim"]}, "identify: method must be a string or None"),
        ({"label": 3}, "identify: label must be a string or None"),
        ({"starts": "2"}, "identify: starts must be a whole number from 1 to"),
        ({"starts": 2.0}, "identify: starts must be a whole number"),
        ({"starts": 0}, "--starts 0: give 1 to"),  # the command line's message
        ({"out": 3}, "identify: out must be"),
        ({"force": "no"}, "identify: force must be True or False"),
    ],
)
def test_identify_refuses_its_arguments(kwargs, needle):
    kwargs = {"scenario": "emps", "data": "trace.csv"} | kwargs
    refused(lambda: emasim.identify(**kwargs), needle)
