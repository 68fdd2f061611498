"""Figures: one run (response, inner command, current) or several runs overlaid.

Conventions: legends sit outside the data, right of the axes; columns that compare controller
sets share their y-axes; a run's title names the scenario, the controller set and the command
line's overrides (``meta["overrides"]``); the output panel carries zoomed insets of the first
response (the step's rise) and of the first load step, which are a few pixels wide on the
whole run's axis; a symmetric-log axis has ticks at whole decades, a few per side.
"""

import contextlib
import math
from pathlib import Path

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure  # files only: no pyplot, no display (a second of start-up)

from ..output import new_file

RPM_PER_RAD_S = 30.0 / np.pi


MAX_POINTS = 4000  # per plotted line; longer traces are thinned to their min/max envelope


def _line(ax, t, y, *style, **kwargs):
    """ax.plot of a trace, thinned to at most MAX_POINTS by keeping each bucket's minimum and
    maximum (so oscillations keep their amplitude on the plot)."""
    t, y = np.asarray(t), np.broadcast_to(np.asarray(y, dtype=float), np.shape(t))
    if t.size > MAX_POINTS:
        bucket = -(-t.size // (MAX_POINTS // 2))
        n = t.size // bucket * bucket
        keep = np.unique(
            np.concatenate([*_extremes(y[:n].reshape(-1, bucket)), np.arange(n, t.size)])
        )
        t, y = t[keep], y[keep]
    return ax.plot(t, y, *style, **kwargs)


def _extremes(buckets: np.ndarray, rows: int = 2**20):
    """The index of each row's smallest and of its largest value in the flattened ``buckets``
    (NaN skipped; a row of NaN alone gives its first), a slice of about
    ``rows`` values at a time, so that a long trace's copies stay small."""
    step = max(1, rows // buckets.shape[1])
    lows, highs = [], []
    for first in range(0, buckets.shape[0], step):
        part = buckets[first : first + step]
        base = np.arange(first, first + part.shape[0]) * buckets.shape[1]
        nan = np.isnan(part)
        lows.append(base + np.nanargmin(np.where(nan, np.inf, part), axis=1))
        highs.append(base + np.nanargmax(np.where(nan, -np.inf, part), axis=1))
    return np.concatenate(lows), np.concatenate(highs)


def _legend(ax) -> None:
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)


def run_title(result) -> str:
    """'scenario: label (key=value, ...)' from the run's scenario and metadata."""
    name = result.scenario.get("name", "")
    label = result.meta.get("label")
    overrides = result.meta.get("overrides") or []
    text = f"{name}: {label}" if label else name
    return f"{text} ({', '.join(overrides)})" if overrides else text


ZOOM_FRACTION = 0.08  # an inset spans this fraction of the run


def _event_times(result) -> list[float]:
    """The start of the response (the reference's first step, sine or table) and the first load
    step, where the scenario has them (s)."""
    experiment = result.description.experiment if result.description is not None else None
    if experiment is None:  # a bare Setup's run, or one saved before emasim described it
        return []
    first = experiment.reference[0]
    start = first.get("time_s", first.get("start_s", 0.0))
    times = [float(start[0] if isinstance(start, list) else start)]  # a table's first time
    return times + ([experiment.load_step_s] if experiment.load_step_s is not None else [])


def _insets(ax, traces: list[tuple], duration: float, times: list[float]) -> None:
    """Zoomed copies of ``traces`` ((t, y, style, kwargs), see _panel_traces) from each time
    on, as insets in the lower part of ``ax``."""
    span = ZOOM_FRACTION * duration
    for k, start in enumerate(times):
        inset = ax.inset_axes([0.30 + 0.36 * k, 0.08, 0.30, 0.40])
        for t, y, style, kwargs in traces:
            keep = (t >= start - 0.1 * span) & (t <= start + span)
            inset.plot(t[keep], np.asarray(y)[keep], *style, **{**kwargs, "label": None})
        inset.tick_params(labelsize=6)
        inset.grid(True, alpha=0.3)
        inset.set_title(f"from {start:g} s", fontsize=6)


def _symlog_ticks(ax, linthresh: float, top: float, per_side: int = 4) -> None:
    """Ticks at 0 and at whole decades above linthresh, at most ``per_side`` on each side, so
    that none crowd the linear band around zero."""
    if not top > linthresh:
        return
    first, last = math.ceil(math.log10(linthresh)) + 1, math.floor(math.log10(top))
    decades = list(range(first, last + 1))
    step = max(1, -(-len(decades) // per_side))
    ticks = [10.0**k for k in decades[::-1][::step]]
    ax.set_yticks(sorted([-v for v in ticks] + [0.0] + ticks))


def plot_result(result, title: str | None = None):
    """Three stacked panels sharing time: the controlled output and its reference; in a position
    run the motor speed and its command, in a speed run the torques on the shaft; the q-axis
    current and its command."""
    t = result.t
    position_run = result.outer_loop == "position"
    fig = Figure(figsize=(8, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    if position_run:
        _line(axes[0], t, 1e3 * result["position_ref_m"], "k--", lw=1, label="reference")
        _line(axes[0], t, 1e3 * result["actuator_position_m"], lw=1.4, label="rod position")
        axes[0].set_ylabel("position (mm)")
    else:
        _line(axes[0], t, RPM_PER_RAD_S * result["speed_ref_rad_s"], "k--", lw=1, label="reference")
        _line(axes[0], t, RPM_PER_RAD_S * result["motor_speed_rad_s"], lw=1.4, label="motor speed")
        axes[0].set_ylabel("speed (rpm)")
    if position_run:
        _line(
            axes[1],
            t,
            RPM_PER_RAD_S * result["speed_ref_rad_s"],
            "k--",
            lw=0.8,
            label="speed command",
        )
        _line(axes[1], t, RPM_PER_RAD_S * result["motor_speed_rad_s"], lw=1.0, label="motor speed")
        axes[1].set_ylabel("speed (rpm)")
    else:
        _line(axes[1], t, result["torque_Nm"], lw=1.0, label="electromagnetic")
        _line(axes[1], t, result["load_torque_Nm"], lw=1.0, label="load (motor shaft)")
        _line(axes[1], t, result["friction_torque_Nm"], lw=1.0, label="friction")
        axes[1].set_ylabel("torque (N·m)")
    _line(axes[2], t, result["iq_ref_A"], "k--", lw=0.8, label="iq command")
    _line(axes[2], t, result["iq_A"], lw=1.0, label="iq")
    axes[2].set_ylabel("current (A)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        _legend(ax)
    _insets(axes[0], _panel_traces(axes[0]), float(t[-1] - t[0]), _event_times(result))
    name = title or run_title(result)
    if name:
        axes[0].set_title(name)
    return fig


def _panel_traces(ax) -> list[tuple]:
    """The lines of a panel as (t, y, style, kwargs), to draw again in an inset."""
    return [
        (
            np.asarray(line.get_xdata()),
            np.asarray(line.get_ydata()),
            (),
            {"color": line.get_color(), "ls": line.get_linestyle(), "lw": line.get_linewidth()},
        )
        for line in ax.get_lines()
    ]


def _output(result):
    """(label, unit scale, column, reference column) of the loop a run closes."""
    if result.outer_loop == "position":
        experiment = result.description.experiment if result.description is not None else None
        if experiment is not None and experiment.quantity == "rudder":
            return "rudder angle (deg)", 180.0 / np.pi, "rudder_angle_rad", None
        return "position (mm)", 1e3, "actuator_position_m", "position_ref_m"
    return "speed (rpm)", RPM_PER_RAD_S, "motor_speed_rad_s", "speed_ref_rad_s"


def plot_comparison(results: dict, title: str | None = None):
    """Runs of several controller sets overlaid: output and reference, tracking error, current."""
    fig = Figure(figsize=(8, 7.5), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    first = next(iter(results.values()))
    label, scale, column, ref_column = _output(first)
    if ref_column is None:  # rudder: the scenario's command, in rad
        from .report import rudder_traces

        reference = rudder_traces(first)[1] / scale
    else:
        reference = first[ref_column]
    _line(axes[0], first.t, scale * reference, "k--", lw=1, label="reference")
    for name, result in results.items():
        _line(axes[0], result.t, scale * result[column], lw=1.2, label=name)
        _line(axes[1], result.t, scale * (reference - result[column]), lw=1.0, label=name)
        _line(axes[2], result.t, result["iq_A"], lw=0.8, label=name)
    axes[0].set_ylabel(label)
    axes[1].set_ylabel(f"error, {label}")
    # symmetric log: the approach and the small steady-state error both stay visible
    top = float(np.nanmax(np.abs(scale * reference)))
    linthresh = max(1e-4 * top, 1e-12)
    axes[1].set_yscale("symlog", linthresh=linthresh)
    _symlog_ticks(axes[1], linthresh, top)
    axes[2].set_ylabel("iq (A)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        _legend(ax)
    duration = float(first.t[-1] - first.t[0])
    _insets(axes[0], _panel_traces(axes[0]), duration, _event_times(first))
    if title:
        axes[0].set_title(title)
    return fig


def save_figure(figure, path, dpi: int = 110) -> None:
    """Write a figure to a file (PNG by the path's suffix, through matplotlib's Agg canvas).

    The data lines and the insets lie inside their axes, so the constrained layout need not
    measure them: leaving them out draws the same pixels (compared on speed-step's figure) and
    saves about a tenth of a second a figure, which was spent transforming every plotted point.
    A PNG is laid out once before it is saved (:func:`_laid_out`).
    """
    for ax in figure.axes:
        for artist in (*ax.get_lines(), *ax.child_axes):
            artist.set_in_layout(False)
    kind = Path(path).suffix.lstrip(".").lower() or "png"
    with new_file(path) as handle, _laid_out(figure, dpi, kind):
        figure.savefig(handle, dpi=dpi, format=kind)


@contextlib.contextmanager
def _laid_out(figure, dpi: int, kind: str):
    """The figure laid out by its layout engine on an Agg canvas at ``dpi``, then its engine
    off for the block (restored after, with its canvas and dpi).

    ``savefig`` of a figure with a layout engine draws it twice: once with drawing disabled,
    only to run the layout, then for the pixels. Laid out here, with no engine left to run, it
    is drawn once: the same PNG, byte for byte (each kind of emasim figure compared), in about
    a fifth less time. Other formats (their dpi is the backend's), and a layout that rcParams
    would put back, take ``savefig``'s own way.
    """
    engine = figure.get_layout_engine()
    automatic = mpl.rcParams["figure.autolayout"] or mpl.rcParams["figure.constrained_layout.use"]
    if engine is None or kind != "png" or automatic or not figure.axes:
        yield
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas, figure_dpi = figure.canvas, figure.dpi
    try:
        FigureCanvasAgg(figure)
        figure.set_dpi(dpi)
        with contextlib.suppress(ValueError):  # as Figure.draw: a layout it cannot make
            engine.execute(figure)
        figure.set_layout_engine(None)
        yield
    finally:
        figure.set_layout_engine(engine)
        figure.set_dpi(figure_dpi)
        figure.canvas = canvas


def plot_bench(results: dict, title: str | None = None):
    """The bench figures of the paper (16-19, 20-23): rudder angle (top) and rudder rate
    (bottom), one column per controller set, the reference dashed; what the bench measures
    (the encoder's reading and its differenced rate, which the figures judge) and the true
    rudder angle and rate."""
    from .report import rudder_traces

    fig = Figure(figsize=(5 * len(results), 6), layout="constrained")
    axes = fig.subplots(2, len(results), sharex=True, sharey="row", squeeze=False)
    for col, (name, result) in enumerate(results.items()):
        angle, reference, rate, reference_rate = rudder_traces(result)
        _line(axes[0, col], result.t, reference, "k--", lw=1, label="command")
        _line(axes[0, col], result.t, angle, lw=1.2, label="rudder angle (true)")
        _line(axes[1, col], result.t, reference_rate, "k--", lw=1, label="command rate")
        _line(axes[1, col], result.t, rate, lw=0.8, label="rudder rate (true)")
        if "measured_rudder_rad" in result.columns:
            reading, _, measured_rate, _ = rudder_traces(result, measured=True)
            _line(axes[0, col], result.t, reading, "C1", lw=0.8, label="encoder reading")
            _line(axes[1, col], result.t, measured_rate, "C1", lw=0.8, label="differenced rate")
        axes[0, col].set_title(name)
        axes[0, col].set_ylabel("angle (deg)")
        axes[1, col].set_ylabel("angular velocity (deg/s)")
        axes[1, col].set_xlabel("time (s)")
        for ax in axes[:, col]:
            ax.grid(True, alpha=0.3)
    for ax in axes[:, -1]:
        _legend(ax)
    if title:
        fig.suptitle(title)
    return fig


def plot_clearance_sweep(rows: list[dict]):
    """Rudder steady RMS error and vibration amplitude against hinge clearance, per controller."""
    fig = Figure(figsize=(9, 3.5), layout="constrained")
    axes = fig.subplots(1, 2)
    for label in dict.fromkeys(r["controller"] for r in rows):
        mine = [r for r in rows if r["controller"] == label]
        clearance = [r["clearance_mm"] for r in mine]
        axes[0].plot(clearance, [r["steady_error_rms_deg"] for r in mine], "o-", label=label)
        axes[1].plot(clearance, [r["chatter_amplitude_deg"] for r in mine], "o-", label=label)
    axes[0].set_ylabel("steady RMS error (deg)")
    axes[1].set_ylabel("vibration amplitude (deg)")
    for ax in axes:
        ax.set_xlabel("hinge clearance (mm)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return fig


def plot_pareto(sets: dict):
    """Each controller set's front of tracking against chattering (its tuning trials that no
    other trial beats on both: emasim.analysis.pareto), its tuned point marked. ``sets``:
    label -> its [tuning.sets] record (``front``, ``tuned_point``)."""
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.subplots()
    for label, record in sets.items():
        chatter, tracking = zip(*record["front"], strict=True)
        (line,) = ax.step(chatter, tracking, "o-", where="post", ms=3, label=f"{label}: front")
        ax.plot(*record["tuned_point"], "*", ms=12, color=line.get_color(), label=f"{label}: tuned")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("chattering TV(iq*) / I_max (1/s)")
    ax.set_ylabel("tracking IAE / (T max|ref|)")
    ax.grid(True, which="both", alpha=0.3)
    _legend(ax)
    return fig


STUDY_COLUMNS = 4


def plot_study(table, metrics: list[str], labels: list[str], along: str | None = None):
    """A study's metrics, a panel each (those that differ between runs): against the grid key
    ``along`` when given and numeric (the median over its runs at each value, with the 5-95 %
    band), else as each controller set's distribution (box: quartiles, whiskers 5-95 %)."""
    varying = [m for m in metrics if table[m].nunique(dropna=True) > 1] or metrics[:1]
    if not varying:  # every metric undefined (runs too short for them, or all diverged)
        fig = Figure(figsize=(5, 2), layout="constrained")
        ax = fig.subplots()
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no metric is defined over these runs", ha="center", va="center")
        return fig
    x_numeric = along is not None and table[along].dtype.kind in "fiu"
    rows = -(-len(varying) // STUDY_COLUMNS)
    columns = min(len(varying), STUDY_COLUMNS)
    fig = Figure(figsize=(3.6 * columns, 2.8 * rows), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax, metric in zip(axes, varying, strict=False):
        for label in labels:
            mine = table[table["label"] == label]
            if x_numeric:
                grouped = mine.groupby(along)[metric]
                x = np.asarray(grouped.median().index, dtype=float)
                ax.plot(x, grouped.median().to_numpy(), "o-", ms=3, label=label)
                if grouped.size().max() > 1:
                    low, high = grouped.quantile(0.05), grouped.quantile(0.95)
                    ax.fill_between(x, low.to_numpy(), high.to_numpy(), alpha=0.2)
        if x_numeric:
            ax.set_xlabel(along)
        else:
            data = [table[table["label"] == lb][metric].dropna().to_numpy() for lb in labels]
            ax.boxplot(data, whis=(5, 95), showfliers=False)
            ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=8)
        ax.set_title(metric, fontsize=8)
        ax.grid(True, alpha=0.3)
    for ax in axes[len(varying) :]:
        ax.set_visible(False)
    if x_numeric:
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=4)
    return fig


def plot_wear(degradation: dict):
    """Each headline figure and tuning cost against the wear level, or against the date or
    cycle count of each identified row (an entry's ``at``), PID and the hybrid."""
    names = list(degradation)
    columns = min(len(names), STUDY_COLUMNS)
    rows = -(-len(names) // columns)
    fig = Figure(figsize=(3.6 * columns, 2.8 * rows), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax, name in zip(axes, names, strict=False):
        entry = degradation[name]
        for label, values in entry.items():
            if isinstance(values, list) and label != "levels":
                ax.plot(entry["levels"], values, "o-", ms=3, label=label)
        ax.set_title(f"{name.removesuffix('_reduction')}\n({entry['metric']})", fontsize=8)
        if "at" in entry:
            ax.set_xlabel("identified at")
            ax.set_xticks(entry["levels"], entry["at"], fontsize=7)
        else:
            ax.set_xlabel("wear level (0 new, 4 worn)")
            ax.set_xticks(entry["levels"])
        ax.grid(True, alpha=0.3)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=2)
    return fig


MAP_CLIP_PCT = 100.0  # the verdict map's colour scale: margins beyond +-100 % share its ends


def plot_verdict_map(vmap: dict):
    """The verdict map (emasim.experiments.verdict_map): a panel per headline figure (rows)
    and baseline (columns), each cell's margin 100 (|baseline| - |hybrid|) / |baseline| in
    colour and in figures (blue: the hybrid wins), preload across, encoder and hinge clearance
    down, the nominal bench's cell framed."""
    from matplotlib.patches import Rectangle

    from .judged import figure_words
    from .verdict_map import cell_at, margin_of

    axes_of, nominal = vmap["axes"], vmap["nominal"]
    down = [(e, c) for e in axes_of["encoder"] for c in axes_of["hinge_clearance_mm"]]
    across = axes_of["preload_Nm"]
    entries = list(vmap["figures"].items())
    baselines = list(entries[0][1]["against"])
    fig = Figure(figsize=(4.2 * len(baselines), 2.3 * len(entries)), layout="constrained")
    panels = fig.subplots(len(entries), len(baselines), squeeze=False)
    image = None
    for row, (name, entry) in enumerate(entries):
        for col, baseline in enumerate(baselines):
            ax, cells = panels[row][col], entry["against"][baseline]
            grid = np.array(
                [
                    [
                        margin_of(
                            cell_at(cells, {"preload_Nm": p, "encoder": e, "hinge_clearance_mm": c})
                        )
                        for p in across
                    ]
                    for e, c in down
                ]
            )
            image = ax.imshow(
                np.clip(grid, -MAP_CLIP_PCT, MAP_CLIP_PCT),
                cmap="RdBu",
                vmin=-MAP_CLIP_PCT,
                vmax=MAP_CLIP_PCT,
                aspect="auto",
            )
            for (i, j), value in np.ndenumerate(grid):
                text = f"{value:+.0f}" if np.isfinite(value) else "-inf"
                ax.text(j, i, text, ha="center", va="center", fontsize=7)
            home = (
                down.index((nominal["encoder"], nominal["hinge_clearance_mm"])),
                across.index(nominal["preload_Nm"]),
            )
            ax.add_patch(
                Rectangle((home[1] - 0.5, home[0] - 0.5), 1, 1, fill=False, lw=2, color="k")
            )
            ax.set_xticks(range(len(across)), [f"{p:g}" for p in across], fontsize=7)
            ax.set_yticks(range(len(down)), [f"{e}, {c:g} mm" for e, c in down], fontsize=7)
            ax.set_title(f"{figure_words(name)}: vs {baseline}", fontsize=8)
            if row == len(entries) - 1:
                ax.set_xlabel("standing preload (N m)", fontsize=8)
    fig.colorbar(image, ax=panels, label="hybrid's margin (%), clipped at +-100", shrink=0.6)
    return fig
