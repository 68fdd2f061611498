"""A measured trace: read from CSV, MATLAB or Parquet, its columns mapped to a model's signals.

A column map takes the file's names to the model's signals (``qm=position_m``); a signal the
map does not name is looked up under its own name. The user's map names columns the file must
have; the scenario's default map (``defaults``) applies to the columns the file has. Every
column read must be finite, one value per sample, on a time base that rises by one sampling
period (within 0.1 % of it) from sample to sample. Each failure is one InputError line
naming the file and the column.
"""

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

SAMPLING_TOLERANCE = 1e-3  # relative: a step this far from the mean period is not uniform
SUFFIXES = (".csv", ".mat", ".parquet")


@dataclass(frozen=True)
class Trace:
    """A measured trace: its signals by the model's names (one float64 array each), its
    sampling period (s), and the file's path and sha256."""

    signals: dict[str, np.ndarray]
    sample_period_s: float
    path: Path
    sha256: str

    def __len__(self) -> int:
        return len(next(iter(self.signals.values())))


def parse_map(items: list[str], what: str = "--map") -> dict[str, str]:
    """``["file=signal", ...]`` as {file column: signal}; a malformed item is one line."""
    mapping = {}
    for item in items:
        column, sep, signal = item.partition("=")
        if not sep or not column.strip() or not signal.strip():
            raise InputError(f"{what} {item!r}: give it as FILE_COLUMN=SIGNAL, e.g. qm=position_m")
        mapping[column.strip()] = signal.strip()
    return mapping


def _columns(path: Path) -> dict[str, np.ndarray]:
    """Every column of the file by its own name (MATLAB: every numeric variable)."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".mat":
            import scipy.io

            raw = scipy.io.loadmat(path)
            return {
                k: np.asarray(v)
                for k, v in raw.items()
                if not k.startswith("__") and np.asarray(v).dtype.kind in "biuf"
            }
        import pandas as pd

        frame = pd.read_csv(path) if suffix == ".csv" else pd.read_parquet(path)
        return {str(c): frame[c].to_numpy() for c in frame.columns}
    except (OSError, ValueError, TypeError, KeyError, ImportError) as err:
        raise InputError(f"--data {path}: cannot be read as {suffix[1:]} ({err})") from None
    except Exception as err:  # a reader's own error type: still one line
        raise InputError(f"--data {path}: cannot be read as {suffix[1:]} ({err})") from None


def _vector(path: Path, column: str, value) -> np.ndarray:
    try:
        data = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"--data {path}: column '{column}' is not numeric") from None
    if data.ndim == 2 and 1 in data.shape:
        data = data.ravel()
    if data.ndim != 1:
        raise InputError(f"--data {path}: column '{column}' is not one value per sample")
    return data


def load_trace(
    path: str | Path,
    signals: tuple[str, ...],
    required: tuple[str, ...],
    mapping: dict[str, str],
    defaults: dict[str, str] | None = None,
    time_signal: str = "time_s",
) -> Trace:
    """The trace of ``path`` with the model's ``signals`` (``required`` ones must be there),
    the file's columns renamed by ``defaults`` then ``mapping`` (module docstring)."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(f"--data {path}: give a {', '.join(SUFFIXES)} file")
    if not path.is_file():
        raise InputError(f"--data {path}: no such file")
    unknown = sorted(set(mapping.values()) - set(signals))
    if unknown:
        raise InputError(
            f"--map: {', '.join(unknown)} is not a signal of this model; its signals: "
            f"{', '.join(signals)}"
        )
    columns = _columns(path)
    missing_columns = sorted(set(mapping) - set(columns))
    if missing_columns:
        raise InputError(
            f"--data {path}: no column {', '.join(missing_columns)} (--map); its columns: "
            f"{', '.join(sorted(columns)) or 'none'}"
        )
    mapping = {**{c: s for c, s in (defaults or {}).items() if c in columns}, **mapping}
    renamed = {mapping.get(name, name): value for name, value in columns.items()}
    absent = [s for s in required if s not in renamed]
    if absent:
        raise InputError(
            f"--data {path}: no column for {', '.join(absent)}; map one with "
            f"--map FILE_COLUMN={absent[0]} (its columns: {', '.join(sorted(columns))})"
        )
    chosen = {s: _vector(path, s, renamed[s]) for s in signals if s in renamed}
    lengths = {s: v.size for s, v in chosen.items()}
    if len(set(lengths.values())) != 1:
        raise InputError(f"--data {path}: the columns differ in length ({lengths})")
    for name, values in chosen.items():
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise InputError(
                f"--data {path}: column for {name} is not finite at sample {int(bad[0])} "
                f"({bad.size} samples)"
            )
    time = chosen[time_signal]
    if time.size < 3:
        raise InputError(f"--data {path}: {time.size} samples; at least 3 are needed")
    steps = np.diff(time)
    if np.any(steps <= 0.0):
        at = int(np.flatnonzero(steps <= 0.0)[0])
        raise InputError(f"--data {path}: the time does not rise at sample {at + 1}")
    period = float(np.mean(steps))
    if np.max(np.abs(steps - period)) > SAMPLING_TOLERANCE * period:
        raise InputError(
            f"--data {path}: the time is not uniformly sampled (steps {steps.min():.6g} to "
            f"{steps.max():.6g} s)"
        )
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return Trace(chosen, period, path, digest)
