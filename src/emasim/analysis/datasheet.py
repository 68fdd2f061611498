"""The acceptance datasheet: datasheet.json, frequency_response.csv, the figures (Bode, dynamic
stiffness, hysteresis loop) and report.html, rendered from a Jinja2 template with every text
escaped.

Reads an :class:`emasim.experiments.acceptance.Acceptance`; writes into an existing folder
(the caller's :func:`emasim.output.write_folder` makes it atomic).
"""

import csv
import io
from importlib.resources import files
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..jsonio import json_text
from ..output import write_new
from . import frequency as fr
from .plots import save_figure
from .units import unit_of

FIGURES = (
    (
        "bode.png",
        "Frequency response",
        "Output over command, small signal (solid) and large signal (dashed), of the "
        "command amplitudes in the legend; dotted, each set's linear model where it has one. "
        "Grey: -3 dB, -45 deg and -90 deg.",
    ),
    (
        "stiffness.png",
        "Dynamic stiffness",
        "|F/x| of the rod force while the command holds mid stroke; dotted, each set's linear "
        "model where it has one.",
    ),
    (
        "hysteresis.png",
        "Threshold and hysteresis",
        "Output against command over the slow triangle; the loop's width is the hysteresis "
        "(where the loop's own limit cycle leaves it readable).",
    ),
)


def cell(value, digits: int = 4) -> str:
    """One table cell: ``digits`` significant figures, yes/no, a word as it is, a bound as
    "< x" or "> x", a figure not measurable as "not measurable: what" (the forms of
    emasim.experiments.acceptance.FIGURE_FORMS), or n/a where the battery found none."""
    if value is None:
        return "n/a"
    if isinstance(value, dict):
        if "bound" in value:
            return f"{value['bound']} {value['value']:.{digits}g}"
        return f"not measurable: {value['not_measurable']}"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "yes" if value else "no"
    return f"{value:.{digits}g}"


CSV_COLUMNS = (
    "set",
    "source",
    "input",
    "input_unit",
    "excitation",
    "amplitude",
    "output",
    "output_unit",
    "frequency_Hz",
    "gain_dB",
    "phase_deg",
    "real",
    "imag",
)


def frequency_response_csv(curves: dict) -> str:
    """Every set's responses (each input, excitation, output and source), a row a frequency:
    CSV_COLUMNS, H = real + j imag in the output's unit per the input's, its gain in dB of
    that ratio and its phase in degrees, unwrapped along each response."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for label, c in curves.items():
        for r in c["responses"]:
            fixed = [label, r.source, r.input, r.input_unit, r.excitation]
            fixed += ["" if r.amplitude is None else repr(float(r.amplitude))]
            fixed += [r.output, r.output_unit]
            gains, phases = fr.gain_dB(r.h), fr.phase_deg(r.h)
            for f, h, g, ph in zip(r.frequencies_Hz, r.h, gains, phases, strict=True):
                numbers = (f, g, ph, h.real, h.imag)
                writer.writerow(fixed + [repr(float(x)) for x in numbers])
    return buffer.getvalue()


def position_curve(c: dict, input: str, excitation: str) -> tuple | None:
    """(f, H, peak of the excitation) of a set's response of the position to ``input`` at
    ``excitation`` (``Response.excitation``: "model" for the linear model's), or None."""
    for r in c["responses"]:
        if (r.input, r.excitation, r.output) == (input, excitation, "position"):
            return r.frequencies_Hz, r.h, r.amplitude
    return None


def plot_bode(curves: dict) -> Figure:
    fig = Figure(figsize=(8, 6), layout="constrained")
    gain, phase = fig.subplots(2, 1, sharex=True)
    for k, (label, c) in enumerate(curves.items()):
        color = f"C{k}"
        for size, style in (("small", "-o"), ("large", "--s")):
            f, h, amplitude = position_curve(c, "position_command", size)
            name = f"{label}, {size} (±{1e3 * amplitude:.3g} mm)"
            gain.semilogx(f, fr.gain_dB(h), style, color=color, ms=3, label=name)
            phase.semilogx(f, fr.phase_deg(h), style, color=color, ms=3)
        model = position_curve(c, "position_command", "model")
        if model is not None:
            f, h, _ = model
            name = f"{label}, linear model"
            gain.semilogx(f, fr.gain_dB(h), ":", color=color, lw=1.5, label=name)
            phase.semilogx(f, fr.phase_deg(h), ":", color=color, lw=1.5)
    gain.axhline(-3.0, color="0.6", lw=0.8)
    for level in (-45.0, -90.0):
        phase.axhline(level, color="0.6", lw=0.8)
    gain.set_ylabel("gain (dB)")
    phase.set_ylabel("phase (deg)")
    phase.set_xlabel("frequency (Hz)")
    return _with_legend(fig, gain)


def plot_stiffness(curves: dict) -> Figure:
    fig, ax = _figure("frequency (Hz)", "|F/x| (N/mm)")
    for k, (label, c) in enumerate(curves.items()):
        f, h, _ = position_curve(c, "rod_force_N", "force")
        ax.loglog(f, 1e-3 / np.abs(h), "-o", color=f"C{k}", ms=3, label=label)
        model = position_curve(c, "rod_force_N", "model")
        if model is not None:
            f, h, _ = model
            name = f"{label}, linear model"
            ax.loglog(f, 1e-3 / np.abs(h), ":", color=f"C{k}", lw=1.5, label=name)
    return _with_legend(fig, ax)


def plot_hysteresis(curves: dict) -> Figure:
    fig, ax = _figure("command (mm)", "output - command (mm)")
    for label, c in curves.items():
        command, output = (np.asarray(v) for v in c["loop"])
        ax.plot(command * 1e3, (output - command) * 1e3, lw=0.8, label=label)
    return _with_legend(fig, ax)


def _figure(xlabel: str, ylabel: str):
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.subplots()
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    return fig, ax


def _with_legend(fig: Figure, ax) -> Figure:
    """The legend outside the data, right of the axes."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    return fig


def write_datasheet(acceptance, folder: Path) -> None:
    """datasheet.json, frequency_response.csv, bode.png, stiffness.png, hysteresis.png and
    report.html in ``folder``."""
    from jinja2 import Environment, select_autoescape

    sheet = acceptance.datasheet()
    write_new(folder / "datasheet.json", json_text(sheet))
    curves = acceptance.curves
    write_new(folder / sheet["frequency_response"], frequency_response_csv(curves))
    for (name, _, _), plot in zip(
        FIGURES, (plot_bode, plot_stiffness, plot_hysteresis), strict=True
    ):
        save_figure(plot(curves), folder / name)
    labels = list(sheet["sets"])
    rows = [
        {
            "name": key,
            "unit": unit_of(key),
            "cells": [cell(sheet["sets"][label].get(key)) for label in labels],
        }
        for key in sheet["definitions"]
    ]
    notes = [  # why each figure that is not a number is what it is, where it says
        f"{label}, {key}: {cell(value)}: {value['why']}"
        for label in labels
        for key, value in sheet["sets"][label].items()
        if isinstance(value, dict) and "why" in value
    ]
    environment = Environment(autoescape=select_autoescape(default=True))
    template = environment.from_string(
        files("emasim.analysis").joinpath("datasheet.html.j2").read_text()
    )
    meta = sheet["meta"]
    html = template.render(
        title=f"Acceptance datasheet: {sheet['scenario']}",
        scenario=sheet["scenario"],
        version=meta["emasim_version"],
        created=meta["created_utc"],
        runs=meta["runs"],
        simulated=f"{meta['simulated_s']:.0f}",
        wall=f"{meta['simulation_wall_s']:.1f}",
        output=sheet["output"],
        linear_model=sheet["linear_model"],
        responses=sheet["frequency_response"],
        labels=labels,
        rows=rows,
        forms=sheet["figure_forms"],
        notes=notes,
        figures=[{"file": f, "title": t, "caption": c} for f, t, c in FIGURES],
        definitions=sheet["definitions"],
        battery={
            k: ", ".join(map(cell, v)) if isinstance(v, list | tuple) else cell(v)
            for k, v in sheet["battery"].items()
        },
    )
    write_new(folder / "report.html", html)
