"""The Result of a run: traces with unit-named columns, the scenario, metadata; save and load.

A run folder holds ``result.parquet`` (traces), ``metrics.json``, ``scenario.toml`` (the fully
resolved scenario), ``meta.json`` (package version, seed, wall time of the simulation) and
``plot.png``. It is written under a temporary name and renamed into place, so a crash never
leaves half a result.
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

    def save(self, folder: str | Path, plot: bool = True) -> Path:
        """Write the run folder atomically (replacing an existing one) and return its path."""
        folder = Path(folder)
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=folder.parent))
        try:
            pq.write_table(self._to_arrow(), tmp / "result.parquet")
            (tmp / "metrics.json").write_text(json.dumps(self.metrics, indent=2) + "\n")
            (tmp / "meta.json").write_text(json.dumps(self.meta, indent=2) + "\n")
            (tmp / "scenario.toml").write_text(tomli_w.dumps(self.scenario))
            if plot:
                from ..analysis.plots import plot_result

                plot_result(self).savefig(tmp / "plot.png", dpi=110)
            _replace_dir(tmp, folder)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return folder

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


def _replace_dir(new: Path, target: Path) -> None:
    """Move the finished folder ``new`` to ``target``; an old ``target`` is removed after."""
    if target.exists():
        old = target.with_name(f".{target.name}.old-{new.name.rsplit('-', 1)[-1]}")
        target.rename(old)
        new.rename(target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        new.rename(target)
