"""Results: the traces of a run, or of a comparison of several controller sets; save and load.

A run folder holds ``result.parquet`` (traces), ``metrics.json``, ``scenario.toml`` (the fully
resolved scenario), ``meta.json`` (package version, seed, wall time of the simulation) and
``plot.png``. A comparison folder holds one such folder per controller set, named by its label,
and beside them ``comparison.png``, ``metrics.json`` (label -> metrics), ``scenario.toml`` and
``meta.json``. Folders are written under a temporary name and renamed into place, so a crash
never leaves half a result.
"""

import json
import shutil
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import tomli_w

RPM_PER_RAD_S = 30.0 / np.pi


@dataclass
class Result:
    """Traces of one run. ``result["motor_speed_rad_s"]`` returns a column as an array."""

    columns: tuple[str, ...]
    data: np.ndarray
    scenario: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no column '{name}'; columns: {', '.join(self.columns)}") from None

    @property
    def t(self) -> np.ndarray:
        """Sample times (s)."""
        return self["t_s"]

    def to_pandas(self):
        """The traces as a pandas DataFrame, one column per signal (names carry units)."""
        import pandas as pd  # imported here: it costs start-up time and runs do not need it

        return pd.DataFrame(self.data, columns=list(self.columns))

    def _to_arrow(self) -> pa.Table:
        return pa.table({name: self.data[:, i] for i, name in enumerate(self.columns)})

    def write_files(self, folder: Path, plot: bool = True) -> None:
        """Write the run's files into an existing folder (see :meth:`save`)."""
        pq.write_table(self._to_arrow(), folder / "result.parquet")
        _write_records(folder, self.metrics, self.meta, self.scenario)
        if plot:
            from ..analysis.plots import plot_result, save_figure

            save_figure(plot_result(self), folder / "plot.png")

    def save(self, folder: str | Path, plot: bool = True) -> Path:
        """Write the run folder atomically (replacing an existing one) and return its path."""
        return write_atomically(folder, lambda tmp: self.write_files(tmp, plot))

    @classmethod
    def load(cls, folder: str | Path) -> "Result":
        """Read a run folder written by :meth:`save`."""
        folder = Path(folder)
        table = pq.read_table(folder / "result.parquet")
        return cls(
            columns=tuple(table.column_names),
            data=np.column_stack([c.to_numpy() for c in table.columns]).astype(np.float64),
            scenario=tomllib.loads((folder / "scenario.toml").read_text()),
            meta=json.loads((folder / "meta.json").read_text()),
            metrics=json.loads((folder / "metrics.json").read_text()),
        )


@dataclass
class Comparison:
    """Runs of several controller sets on one experiment, by label (in the scenario's order)."""

    results: dict[str, Result]
    scenario: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    @property
    def metrics(self) -> dict[str, dict]:
        return {label: r.metrics for label, r in self.results.items()}

    def write_files(self, folder: Path, plot: bool = True) -> None:
        """Write every run into a sub-folder named by its label, and the overlay beside them."""
        for label, result in self.results.items():
            sub = folder / slug(label)
            sub.mkdir()
            result.write_files(sub, plot=False)
        _write_records(folder, self.metrics, self.meta, self.scenario)
        if plot:
            from ..analysis.plots import plot_comparison, save_figure

            save_figure(
                plot_comparison(self.results, self.scenario.get("name")), folder / "comparison.png"
            )

    def save(self, folder: str | Path, plot: bool = True) -> Path:
        """Write the comparison folder atomically and return its path."""
        return write_atomically(folder, lambda tmp: self.write_files(tmp, plot))

    @classmethod
    def load(cls, folder: str | Path) -> "Comparison":
        """Read a comparison folder written by :meth:`save`."""
        folder = Path(folder)
        metrics = json.loads((folder / "metrics.json").read_text())
        return cls(
            results={label: Result.load(folder / slug(label)) for label in metrics},
            scenario=tomllib.loads((folder / "scenario.toml").read_text()),
            meta=json.loads((folder / "meta.json").read_text()),
        )


def slug(label: str) -> str:
    """A folder name for a label: letters, digits and dashes."""
    return "".join(ch if ch.isalnum() else "-" for ch in label.lower()).strip("-") or "run"


def _write_records(folder: Path, metrics: dict, meta: dict, scenario: dict) -> None:
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    (folder / "meta.json").write_text(json.dumps(meta, indent=2) + "\n")
    (folder / "scenario.toml").write_text(tomli_w.dumps(scenario))


def write_atomically(folder: str | Path, write) -> Path:
    """Call ``write(tmp)`` on a fresh temporary folder beside ``folder``, then move it into
    place (replacing an old ``folder``); on any error nothing is left behind."""
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=folder.parent))
    try:
        write(tmp)
        _replace_dir(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _replace_dir(new: Path, target: Path) -> None:
    """Move the finished folder ``new`` to ``target``; an old ``target`` is removed after."""
    if target.exists():
        old = target.with_name(f".{target.name}.old-{new.name.rsplit('-', 1)[-1]}")
        target.rename(old)
        new.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        new.rename(target)
