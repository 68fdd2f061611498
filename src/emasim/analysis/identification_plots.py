"""The figures of an identification: each measured output beside the simulated one with the
residual below it, and a series' values against the trace's date or cycle count."""

import numpy as np

UNITS = {  # an output -> (what it is, the figure's unit, the scale from its own)
    "position_m": ("position", "mm", 1e3),
    "command_V": ("drive input", "V", 1.0),
    "angle_rad": ("motor encoder", "rad", 1.0),
    "rod_position_m": ("rod sensor", "mm", 1e3),
    "iq_A": ("q current", "A", 1.0),
    "force_N": ("rod force", "N", 1.0),
    "rudder_rad": ("rudder encoder", "deg", 180.0 / np.pi),
}


def fit_figure(time: np.ndarray, measured: dict, simulated: dict, title: str):
    """A Figure with, per output (UNITS), the measured and simulated traces and their
    difference, in the unit of UNITS."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in UNITS if n in measured]
    fig, axes = plt.subplots(
        2, len(names), figsize=(6.0 * len(names), 5.5), sharex=True, squeeze=False
    )
    for j, name in enumerate(names):
        what, unit, scale = UNITS[name]
        top, bottom = axes[0, j], axes[1, j]
        top.plot(time, scale * measured[name], label="measured", lw=1.0)
        top.plot(time, scale * simulated[name], label="simulated", lw=0.8, ls="--")
        top.set_ylabel(f"{what} ({unit})")
        top.legend(loc="best")
        top.grid(True, alpha=0.3)
        bottom.plot(time, scale * (measured[name] - simulated[name]), lw=0.6, color="C3")
        bottom.set_ylabel(f"measured - simulated ({unit})")
        bottom.set_xlabel("time (s)")
        bottom.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def series_figure(table, keys: list[str]):
    """A Figure with one panel per key: its value against ``table["at"]`` with its 95 %
    interval as error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(keys), 1, figsize=(7.0, 2.2 * len(keys)), sharex=True)
    axes = [axes] if len(keys) == 1 else list(axes)
    at = list(table["at"])
    for ax, key in zip(axes, keys, strict=True):
        ax.errorbar(at, table[key], yerr=table[f"{key} interval95"], fmt="o-", capsize=3)
        ax.set_ylabel(key.rsplit(".", 1)[-1], fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("trace (date or cycle count)")
    fig.tight_layout()
    return fig
