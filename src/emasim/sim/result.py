"""Results: the traces of a run, or of a comparison of several controller sets; save and load.

A run folder holds the traces (``result.parquet``, or ``result.csv`` or ``result.mat`` with
``trace_format``), ``metrics.json``, ``scenario.toml`` (the fully resolved scenario),
``meta.json`` (package version, seed, wall time of the simulation) and ``plot.png``. A
comparison folder holds one such folder per controller set, named by its label, and beside
them ``comparison.png``, ``metrics.json`` (label -> metrics), ``scenario.toml`` and
``meta.json``. Folders are written by :func:`emasim.output.write_folder`: under a temporary name
and renamed into place, so a crash never leaves half a result, and never over anything emasim
did not write (replacing an earlier emasim result needs ``force=True``). Without a folder,
``save()`` picks a fresh one, ``runs/<scenario>/<label>-<time>``.
"""

import json
import os
import tomllib
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import tomli_w

from ..errors import DamagedResult, InputError
from ..jsonio import json_text
from ..manifest import verify_files
from ..naming import RUNS_ROOT, fresh_folder, slug
from ..output import CLI_HINTS, write_file, write_folder, write_new
from . import spool
from .spool import PARQUET_OPTIONS, ParquetTraces, arrow_table

RPM_PER_RAD_S = 30.0 / np.pi
TRACE_FORMATS = ("parquet", "csv", "mat")  # result.<format>


@dataclass(frozen=True)
class Experiment:
    """The experiment a run made, typed (emasim.scenarios.schema.Scenario.experiment): what
    its metrics and figures need of the scenario, so that none reads the TOML.

    ``quantity``: the reference's, 'speed', 'position' or 'rudder'; ``shape``: 'sine' or
    'step'; ``reference``: its terms as given (in rpm, mm or deg, plain dicts);
    ``sine_frequency_Hz``: the sine's, if it is one; ``load_step_s``: the first load step's
    time, if any; the limits the run is checked against: ``max_speed_rpm``,
    ``max_current_A`` and ``stroke_mm`` (None where end stops hold the rod);
    ``rudder_arm_m``: the lumped stage's arm (None with the linkage, whose rudder rate is a
    state)."""

    quantity: str
    shape: str
    reference: tuple[dict, ...]
    sine_frequency_Hz: float | None
    load_step_s: float | None
    max_speed_rpm: float
    max_current_A: float
    stroke_mm: float | None
    rudder_arm_m: float | None

    def to_json(self) -> dict:
        return {**self.__dict__, "reference": [dict(t) for t in self.reference]}

    @classmethod
    def from_json(cls, data: dict) -> "Experiment":
        return cls(**{**data, "reference": tuple(dict(t) for t in data["reference"])})


@dataclass(frozen=True)
class RunDescription:
    """What a run was, typed: analysis and reports read this, never NaN columns or the TOML.

    ``elements``: the plant elements present (emasim.plant.actuator.ELEMENTS names);
    ``loops``: slot -> controller name of every closed loop, outermost first (a controller
    built by hand is named by its function); ``outer_loop``: 'position' or 'speed', the loop
    the reference drives; ``sensors``: channel -> its non-ideal properties (resolution,
    noise_std, offset, gap_width in SI, sample_period_s when it samples slower than the
    controllers, derived_from and filter_alpha for a differenced channel) of every non-ideal
    channel; ``units``: column -> unit of every trace column; ``experiment``: what the run
    made (:class:`Experiment`; None for a bare simulation of a Setup, and for a result
    saved before emasim recorded it).
    """

    elements: tuple[str, ...]
    loops: dict[str, str]
    outer_loop: str
    sensors: dict[str, dict[str, float | str]]
    units: dict[str, str]
    experiment: Experiment | None = None

    def to_json(self) -> dict:
        return {
            "elements": list(self.elements),
            "loops": dict(self.loops),
            "outer_loop": self.outer_loop,
            "sensors": {name: dict(v) for name, v in self.sensors.items()},
            "units": dict(self.units),
            "experiment": None if self.experiment is None else self.experiment.to_json(),
        }

    @classmethod
    def from_json(cls, data: dict) -> "RunDescription":
        experiment = data.get("experiment")
        return cls(
            elements=tuple(data["elements"]),
            loops=dict(data["loops"]),
            outer_loop=data["outer_loop"],
            sensors={name: dict(v) for name, v in data["sensors"].items()},
            units=dict(data["units"]),
            experiment=None if experiment is None else Experiment.from_json(experiment),
        )


@dataclass(frozen=True)
class Block:
    """Rows of some columns of a trace (:meth:`Result.blocks`): ``columns``, one array per
    column asked for; ``own_from``, the index in the block of its first row that the block
    before did not hold (0 for the first block, 1 after: the seam row)."""

    own_from: int
    columns: tuple[np.ndarray, ...]


def seamed_blocks(groups):
    """:class:`Block` after Block of ``groups`` (each a list of columns' arrays, of one row
    group): each block after the first begins with the last row of the block before, so that
    a difference or a trapezoid across the seam is counted once; ``Block.own_from`` is where
    its own rows begin. One group is one Block of its arrays as they are."""
    last = None
    for group in groups:
        yield (
            Block(0, tuple(group)) if last is None else Block(1, tuple(map(np.append, last, group)))
        )
        last = [column[-1] for column in group]


@dataclass
class Result:
    """Traces of one run. ``result["motor_speed_rad_s"]`` returns a column as an array;
    ``description`` says what the run was (saved in meta.json as ``run``). ``data`` is the
    traces, one column per signal: an array, or for a trace larger than
    emasim.sim.spool.SPOOL_BYTES a :class:`~emasim.sim.spool.ParquetTraces` (its Parquet file,
    read a column at a time; ``np.asarray(result.data)`` reads it all)."""

    columns: tuple[str, ...]
    data: np.ndarray | ParquetTraces
    scenario: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    description: RunDescription | None = None
    _drawn: "Result | None" = field(default=None, init=False, repr=False, compare=False)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            index = self.columns.index(name)
        except ValueError:
            raise KeyError(f"no column '{name}'; columns: {', '.join(self.columns)}") from None
        if isinstance(self.data, ParquetTraces):
            return self.data.column(index)
        return self.data[:, index]

    def blocks(self, *names: str):
        """The columns ``names``, a block of rows at a time (:func:`seamed_blocks`): a spooled
        trace's row groups, an in-memory trace in one block."""
        if isinstance(self.data, ParquetTraces):
            return seamed_blocks(self.data.column_groups([self.columns.index(n) for n in names]))
        return seamed_blocks([[self[name] for name in names]])

    @property
    def span(self) -> tuple[float, float]:
        """The first and the last sample time (s), read without reading every row."""
        if isinstance(self.data, ParquetTraces):
            return self.data.span()
        t = self.t
        return float(t[0]), float(t[-1])

    @property
    def outer_loop(self) -> str:
        """'position' or 'speed': the loop the reference drives (from the description, or for a
        folder saved without one, from the resolved scenario's reference)."""
        if self.description is not None:
            return self.description.outer_loop
        return "speed" if self.scenario.get("reference", {}).get("speed_rpm") else "position"

    @property
    def t(self) -> np.ndarray:
        """Sample times (s)."""
        return self["t_s"]

    def to_pandas(self):
        """The traces as a pandas DataFrame, one column per signal (names carry units)."""
        import pandas as pd  # imported here: it costs start-up time and runs do not need it

        return pd.DataFrame(np.asarray(self.data), columns=list(self.columns))

    def to_timeresponse(self, outputs: list[str], inputs: list[str] = ()):
        """The traces as python-control's ``TimeResponseData``: the named columns as its
        outputs and inputs (each labelled by its column name, which carries the unit), on
        the recorded time. Unknown names are refused in one line naming the columns."""
        import control

        unknown = [name for name in (*outputs, *inputs) if name not in self.columns]
        if unknown or not outputs:
            raise InputError(
                f"outputs/inputs: {', '.join(unknown) or 'no output given'}; the columns: "
                f"{', '.join(self.columns)}"
            )
        return control.TimeResponseData(
            self.t,
            np.array([self[name] for name in outputs]),
            inputs=np.array([self[name] for name in inputs]) if inputs else None,
            output_labels=list(outputs),
            input_labels=list(inputs) if inputs else None,
            title=f"{self.scenario.get('name', 'run')}: {self.meta.get('label', '')}",
        )

    def _write_parquet(self, handle) -> None:
        """The traces as a Parquet file: a spooled trace's file as it is, else one float64
        column per signal (emasim.sim.spool.arrow_table: no copy)."""
        if isinstance(self.data, ParquetTraces):
            self.data.copy_to(handle)
        else:
            table = arrow_table(self.columns, (self.data[:, i] for i in range(len(self.columns))))
            pq.write_table(table, handle, **PARQUET_OPTIONS)

    def _csv_blocks(self):
        """The traces as CSV text, in blocks (one per row group of a spooled trace): a header
        of column names (each carries its unit), one row per recorded sample, each number in
        the shortest text that reads back to the same float64 (Python's repr; NaN as nan)."""
        yield ",".join(self.columns) + "\n"
        spooled = isinstance(self.data, ParquetTraces)
        for block in self.data.row_groups() if spooled else [self.data]:
            yield "".join(",".join(map(repr, row)) + "\n" for row in block.tolist())

    def _write_mat(self, handle) -> None:
        """The traces as a MATLAB file (scipy.io.savemat, written to the binary ``handle``): one
        struct ``emasim`` with a field per column (a column vector), ``units`` (column ->
        unit), ``scenario`` and ``label``. A spooled trace's columns are read one at a time,
        as savemat writes each (:class:`_ColumnRead`): memory holds one column, not the trace."""
        from scipy.io import savemat

        check_mat_size(self.data.shape[0], len(self.columns))
        units = self.description.units if self.description is not None else {}
        spooled = isinstance(self.data, ParquetTraces)
        struct = {
            name: _ColumnRead(self.data, i) if spooled else self.data[:, i]
            for i, name in enumerate(self.columns)
        }
        struct["units"] = {name: units.get(name, "") for name in self.columns}
        struct["scenario"] = self.scenario.get("name", "")
        struct["label"] = self.meta.get("label", "")
        savemat(handle, {"emasim": struct}, oned_as="column")

    def to_csv(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write the traces as CSV (:meth:`_csv_blocks`, a block at a time) to the file
        ``path``, atomically; ``overwrite`` replaces a trace file emasim wrote there, never any
        other file."""
        return write_file(Path(path), self._csv_blocks(), force=overwrite, is_ours=_is_trace_csv,
                          what="path", replace_hint=OVERWRITE_HINT)  # fmt: skip

    def to_mat(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write the traces as a MATLAB file (:meth:`_write_mat`) to the file ``path``, atomically;
        ``overwrite`` replaces a trace file emasim wrote there, never any other file."""
        return write_file(Path(path), self._write_mat, force=overwrite, is_ours=_is_trace_mat,
                          what="path", replace_hint=OVERWRITE_HINT)  # fmt: skip

    def plot(self):
        """The run's figure (emasim.analysis.plots.plot_result): a matplotlib Figure."""
        from ..analysis.plots import plot_result

        return plot_result(self.drawn())

    def drawn(self) -> "Result":
        """This result, or, for a spooled trace, the same result holding only what its figure
        draws: the columns it reads (emasim.analysis.report.FIGURE_COLUMNS), at the rows of
        their envelope (ParquetTraces.envelope of ENVELOPE_RUNS runs). Small and in memory, so
        a figure process can be handed it. Read once: a comparison's overlay and the run's own
        figure draw the same."""
        if not isinstance(self.data, ParquetTraces):
            return self
        if self._drawn is None:
            from ..analysis.report import FIGURE_COLUMNS

            names = tuple(name for name in self.columns if name in FIGURE_COLUMNS)
            indices = [self.columns.index(name) for name in names]
            envelope = self.data.envelope(ENVELOPE_RUNS, indices)
            self._drawn = replace(self, columns=names, data=envelope)
        return self._drawn

    def write_files(
        self,
        folder: Path,
        plot: bool = True,
        traces: bool = True,
        trace_format: str = "parquet",
        figures=None,
    ) -> None:
        """Write the run's files into an existing folder (see :meth:`save`); without
        ``traces``, no trace file (a study's runs: the metrics and the scenario). ``figures``
        draws the plot (emasim.analysis.figure_process: a FigureProcess, or by default
        DrawHere); the caller waits for it before publishing the folder. The plot is handed
        over first, so that a figure process draws it while this one writes the traces."""
        if traces and trace_format not in TRACE_FORMATS:
            raise ValueError(f"trace_format must be one of {TRACE_FORMATS}, got {trace_format!r}")
        if plot:
            _drawer(figures).save(self.drawn().plot, folder / "plot.png")
        if traces:
            path = folder / f"result.{trace_format}"
            if trace_format == "csv":
                write_new(path, self._csv_blocks())
            else:
                write_new(path, self._write_mat if trace_format == "mat" else self._write_parquet)
        meta = self.meta
        if self.description is not None:
            meta = {**meta, "run": self.description.to_json()}
        if traces:  # what Result.load checks the traces against (beside the manifest's sum)
            rows, width = self.data.shape
            meta = {**meta, "traces": {"file": path.name, "rows": rows, "columns": width}}
        write_records(folder, self.metrics, meta, self.scenario)

    def save(
        self,
        folder: str | Path | None = None,
        plot: bool = True,
        overwrite: bool = False,
        trace_format: str = "parquet",
        figures=None,
        words: str = "python",
    ) -> Path:
        """Write the run folder atomically and return its path (see :func:`default_folder`
        when ``folder`` is None); ``overwrite`` replaces an earlier emasim result there (never
        a file emasim did not write); ``trace_format`` one of TRACE_FORMATS; ``figures`` draws
        the plot (see :meth:`write_files`); ``words`` (WORDS) the refusals' wording: these
        arguments', or the command line's options."""
        return _save(self, folder, plot, overwrite, "run", trace_format, figures, words)

    @classmethod
    def load(cls, folder: str | Path) -> "Result":
        """Read a run folder written by :meth:`save` (its traces in any of TRACE_FORMATS).

        Every file read must be the one emasim wrote, whole (its size and SHA-256 in the
        folder's manifest, :func:`emasim.manifest.verify_files`), and the traces must hold the
        rows and columns meta.json counts; anything else raises
        :class:`emasim.errors.DamagedResult` naming the file."""
        folder = Path(folder)
        trace = _trace_file(folder)
        verify_files(folder, [trace.name, "meta.json", "metrics.json", "scenario.toml"])
        meta = _parse(folder / "meta.json", json.loads)
        columns, data = _parse(trace, lambda _: read_traces(folder, lazy=True))
        counted = meta.pop("traces", None)
        if not isinstance(counted, dict) or counted.get("file") != trace.name:
            raise DamagedResult(f"{folder / 'meta.json'}: does not count the rows of {trace.name}")
        if data.shape != (counted.get("rows"), counted.get("columns")):
            raise DamagedResult(
                f"{trace}: holds {data.shape[0]} rows of {data.shape[1]} columns; meta.json "
                f"counts {counted.get('rows')} of {counted.get('columns')}"
            )
        run = meta.pop("run", None)
        return cls(
            columns=columns,
            data=data,
            scenario=_parse(folder / "scenario.toml", tomllib.loads),
            meta=meta,
            metrics=_parse(folder / "metrics.json", json.loads),
            description=_parse(folder / "meta.json", lambda _: _description(run)),
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

    def plot(self):
        """The overlay of every controller set (emasim.analysis.plots.plot_comparison)."""
        from ..analysis.plots import plot_comparison

        name, overrides = self.scenario.get("name", ""), self.meta.get("overrides") or []
        runs = self.drawn().results
        return plot_comparison(runs, f"{name} ({', '.join(overrides)})" if overrides else name)

    def drawn(self) -> "Comparison":
        """This comparison with each run :meth:`Result.drawn`."""
        return replace(self, results={label: r.drawn() for label, r in self.results.items()})

    def write_files(
        self, folder: Path, plot: bool = True, trace_format: str = "parquet", figures=None
    ) -> None:
        """Write every run into a sub-folder named by its label (each with its own plot), and
        the overlay beside them (``figures``: see :meth:`Result.write_files`)."""
        if plot:
            _drawer(figures).save(self.drawn().plot, folder / "comparison.png")  # longest first
        for label, result in self.results.items():
            sub = folder / slug(label)
            sub.mkdir()
            result.write_files(sub, plot=plot, trace_format=trace_format, figures=figures)
        write_records(folder, self.metrics, self.meta, self.scenario)

    def save(
        self,
        folder: str | Path | None = None,
        plot: bool = True,
        overwrite: bool = False,
        trace_format: str = "parquet",
        figures=None,
        words: str = "python",
    ) -> Path:
        """Write the comparison folder atomically and return its path (see :meth:`Result.save`)."""
        return _save(self, folder, plot, overwrite, "comparison", trace_format, figures, words)

    @classmethod
    def load(cls, folder: str | Path) -> "Comparison":
        """Read a comparison folder written by :meth:`save`, each file checked as
        :meth:`Result.load` checks a run's."""
        folder = Path(folder)
        verify_files(folder, ["meta.json", "metrics.json", "scenario.toml"])
        metrics = _parse(folder / "metrics.json", json.loads)
        if not isinstance(metrics, dict):
            raise DamagedResult(f"{folder / 'metrics.json'}: not a table of label -> metrics")
        return cls(
            results={label: Result.load(folder / slug(label)) for label in metrics},
            scenario=_parse(folder / "scenario.toml", tomllib.loads),
            meta=_parse(folder / "meta.json", json.loads),
        )


def _trace_file(folder: Path) -> Path:
    """The traces' file of a run folder: result.<format> for the first of TRACE_FORMATS there."""
    for name in TRACE_FORMATS:
        path = folder / f"result.{name}"
        if os.path.lexists(path):
            return path
    verify_files(folder, [])  # a missing folder, or one that is no result, says so first
    names = ", ".join(f"result.{name}" for name in TRACE_FORMATS)
    raise DamagedResult(f"{folder}: holds no traces ({names}); a run saved with them can be loaded")


def _parse(path: Path, parse):
    """``parse(text)`` of a file Result.load reads; any failure is a DamagedResult naming it."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy's 'empty input': the row count says it
            return parse(path.read_text() if path.suffix in (".json", ".toml") else path)
    except DamagedResult:
        raise
    except Exception as err:
        raise DamagedResult(f"{path}: cannot be read ({type(err).__name__}: {err})") from None


class _ColumnRead:
    """Column ``index`` of a spooled trace, read when numpy asks for it (``np.asarray``):
    scipy.io.savemat converts a struct's field to an array as it writes that field."""

    def __init__(self, data: ParquetTraces, index: int):
        self.data, self.index = data, index

    def __array__(self, dtype=None, copy=None):
        column = self.data.column(self.index)
        return column if dtype is None else column.astype(dtype)


def _description(run) -> "RunDescription | None":
    return RunDescription.from_json(run) if run is not None else None


def default_folder(scenario: dict, what: str) -> Path:
    """A fresh folder for a result: ``runs/<scenario name>/<what>-<YYYYmmdd-HHMMSS>``."""
    return fresh_folder(RUNS_ROOT / slug(scenario.get("name", "run")), what)


# MATLAB's limit on one variable of a MAT-file of version 7 or earlier (its save needs -v7.3
# for 2 GB or more); scipy.io.savemat writes version 5, and :meth:`Result._mat` one variable
MAT_MAX_BYTES = 2**31


def check_trace_format(trace_format: str, scenario=None) -> None:
    """Refuse an unknown trace format, and, for ``mat``, a run of ``scenario`` (each of its
    controller sets) whose traces one MAT-file variable cannot hold: before it is simulated."""
    if trace_format not in TRACE_FORMATS:
        raise InputError(f"--format: one of {', '.join(TRACE_FORMATS)}, got {trace_format!r}")
    if trace_format == "mat" and scenario is not None:
        for _, variant in scenario.variants():
            setup = variant.setup()
            check_mat_size(setup.recorded_rows, len(setup.kept_columns()))


def check_mat_size(rows: int, columns: int) -> None:
    """Refuse traces of ``rows`` x ``columns`` float64 at or over MAT_MAX_BYTES, in one line."""
    size = 8 * rows * columns
    if size >= MAT_MAX_BYTES:
        raise InputError(
            f"--format mat: the traces would be {size / 1e9:.3g} GB ({rows} rows x {columns} "
            f"columns); a MAT-file variable holds under {MAT_MAX_BYTES / 1e9:.3g} GB (MATLAB's "
            "limit before -v7.3): write parquet or csv, or record fewer rows "
            "(solver.record_period_s)"
        )


def _drawer(figures):
    """``figures``, or by default one that draws in this process."""
    if figures is not None:
        return figures
    from ..analysis.figure_process import DrawHere

    return DrawHere()


# runs of rows whose extremes a spooled trace's figure keeps (Result.drawn): a figure is 8 in
# at 110 dpi, 880 pixels wide, so two rows or more to a pixel's column
ENVELOPE_RUNS = 2000
OVERWRITE_HINT = "pass overwrite=True to replace it"
WORDS = {  # how a refusal names the target and says how to replace it or get a fresh one
    "python": ("folder", (OVERWRITE_HINT, "or folder=None for a fresh folder")),
    "command line": ("--out", CLI_HINTS),
}


def _is_trace_csv(path: Path) -> bool:
    """Whether the file has the form of a trace CSV emasim writes: a header of distinct trace
    columns in the trace's order, time first, then rows of exactly that many numbers. A bare
    CSV carries no manifest, so this is its form, not a proof: a copy of an emasim export
    whose numbers a user edited has it too, and ``overwrite=True`` replaces such a file."""
    from .trace import TRACE_COLUMNS  # the plant's layout: loaded only when a file is there

    try:
        with open(path) as handle:
            header = handle.readline().strip().split(",")
            order = [TRACE_COLUMNS.index(name) for name in header]
            if header[0] != "t_s" or order != sorted(set(order)):
                return False
            data = np.loadtxt(handle, delimiter=",", ndmin=2)
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return data.shape[1] == len(header) or data.size == 0


def _is_trace_mat(path: Path) -> bool:
    """Whether the file has the form of a trace MATLAB file emasim writes: its one variable
    is the struct ``emasim``, holding ``t_s``, ``units``, ``scenario`` and ``label`` (its
    form, as for :func:`_is_trace_csv`, not a proof)."""
    from scipy.io import loadmat

    try:
        struct = loadmat(path, variable_names=["emasim"])["emasim"]
        names = set(struct.dtype.names or ())
    except Exception:  # not a MATLAB file at all, whatever scipy's reader raises
        return False
    return {"t_s", "units", "scenario", "label"} <= names


def _save(result, folder, plot, force, kind, trace_format, figures, words):
    check_trace_format(trace_format)
    what, hints = WORDS[words]
    if folder is None:
        named = "compare" if kind == "comparison" else result.meta.get("label", "run")
        target, unique = default_folder(result.scenario, named), True
    else:
        target, unique = Path(folder), False
    drawer = _drawer(figures)

    def write(tmp: Path) -> None:
        result.write_files(tmp, plot, trace_format=trace_format, figures=drawer)
        drawer.wait()  # every figure is in the folder before it is published

    return write_folder(target, write, force=force, unique=unique, kind=kind, what=what,
                        hints=hints)  # fmt: skip


def read_traces(
    folder: Path, lazy: bool = False
) -> tuple[tuple[str, ...], np.ndarray | ParquetTraces]:
    """(column names, float64 data) of the traces a run folder holds, in any TRACE_FORMATS;
    ``lazy``: a Parquet file larger than SPOOL_BYTES as :class:`ParquetTraces` (read by
    column), not in memory."""
    path = folder / "result.parquet"
    if lazy and path.exists() and path.stat().st_size > spool.SPOOL_BYTES:
        traces = ParquetTraces.open(path)
        return traces.columns, traces
    if path.exists():
        table = pq.read_table(path)
        data = np.array([c.to_numpy() for c in table.columns], dtype=np.float64).T
        return tuple(table.column_names), data
    if (folder / "result.csv").exists():
        with open(folder / "result.csv") as f:
            columns = tuple(f.readline().strip().split(","))
        return columns, np.loadtxt(folder / "result.csv", delimiter=",", skiprows=1, ndmin=2)
    from scipy.io import loadmat

    struct = loadmat(folder / "result.mat", squeeze_me=True, struct_as_record=False)["emasim"]
    columns = tuple(
        name for name in struct._fieldnames if name not in ("units", "scenario", "label")
    )
    return columns, np.column_stack([np.atleast_1d(getattr(struct, c)) for c in columns])


def write_records(folder: Path, metrics: dict, meta: dict, scenario: dict) -> None:
    """metrics.json, meta.json and scenario.toml of a run or comparison folder."""
    write_new(folder / "metrics.json", json_text(metrics))
    write_new(folder / "meta.json", json_text(meta))
    write_new(folder / "scenario.toml", tomli_w.dumps(scenario))
