"""The ``emasim`` command line: list scenarios and controllers, run, tune, reproduce, export.

Bad input ends with one line naming the field and the allowed range, exit code 2, and nothing
written. No Python traceback reaches the user: a usage error is one line (exit 2), an
interruption says so (``error: interrupted``; exit 130 for a Ctrl-C or SIGINT, 143 for a
SIGTERM, which unwinds the program as a Ctrl-C does), and an unexpected failure is one line
naming it (exit 1; set ``EMASIM_TRACEBACK=1`` to see the traceback). Output never replaces
anything emasim did not write (:mod:`emasim.output`); replacing an earlier emasim result needs
``--force``.
"""

import errno
import functools
import gc
import logging
import os
import signal
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.highlighter import NullHighlighter
from rich.logging import RichHandler
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table
from typer.core import TyperGroup

from .errors import EmasimError, PhysicalLimitWarning
from .search_rules import Budget  # small: math and dataclasses only

console = Console()
err_console = Console(stderr=True)
log = logging.getLogger("emasim")
DEFAULT_BUDGET = Budget()  # the tune options' defaults


def _say_error(message: str) -> None:
    """One line on stderr: ``error: message`` (newlines folded)."""
    text = " ".join(str(message).split())
    err_console.print(
        f"[bold red]error:[/] {escape(text)}", highlight=False, soft_wrap=True, markup=True
    )


GLOBAL_FLAGS = ("-q", "--quiet", "-v", "--verbose")


def _global_flags_first(args: list[str] | None) -> list[str]:
    """The command line with the global flags (GLOBAL_FLAGS) moved before the subcommand, so
    that ``emasim run X -q`` is ``emasim -q run X`` (up to a ``--``, after which every word is
    an argument)."""
    words = list(sys.argv[1:] if args is None else args)
    end = words.index("--") if "--" in words else len(words)
    flags = [w for w in words[:end] if w in GLOBAL_FLAGS]
    return flags + [w for w in words[:end] if w not in GLOBAL_FLAGS] + words[end:]


INTERRUPTED = 128 + signal.SIGINT  # the exit code of a Ctrl-C (typer returns it)
TERMINATED = 128 + signal.SIGTERM
_SIGTERM = threading.Event()  # set by _on_sigterm while a command runs


def _on_sigterm(signum, frame, owner: int = os.getpid()) -> None:
    """SIGTERM's handler while a command runs (_OneLineErrors.main): a KeyboardInterrupt
    raised where the program stands, so that it unwinds as from a Ctrl-C (every file being
    written removed, emasim.output) and says ``interrupted``. In a process forked from the
    command's, SIGTERM keeps its default meaning, an immediate end."""
    if os.getpid() != owner:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTERM)
        return
    _SIGTERM.set()
    raise KeyboardInterrupt


class _OneLineErrors(TyperGroup):
    """The command group, with every failure reduced to one line and a meaningful exit code."""

    def main(self, args=None, *rest, **kwargs):
        kwargs["standalone_mode"] = False
        handles = threading.current_thread() is threading.main_thread()
        before = signal.signal(signal.SIGTERM, _on_sigterm) if handles else None
        _SIGTERM.clear()
        try:
            # typer returns INTERRUPTED for a KeyboardInterrupt in a command; one raised
            # outside the command comes here
            code = super().main(_global_flags_first(args), *rest, **kwargs)
        except EmasimError as err:
            _say_error(err)
            code = 2
        except (typer.Abort, KeyboardInterrupt):
            code = INTERRUPTED
        except Exception as err:
            code = _usage_or_internal_error(err)
        finally:
            if handles:
                signal.signal(signal.SIGTERM, before)
        if code == INTERRUPTED:
            _say_error("interrupted")
            code = TERMINATED if _SIGTERM.is_set() else INTERRUPTED
        sys.exit(code if isinstance(code, int) else 0)


def _usage_or_internal_error(err: Exception) -> int:
    """A usage error of the command-line parser (bad option, missing argument: anything with
    click's ``format_message`` and ``exit_code``) as one line; anything else is a bug, said in
    one line too, unless EMASIM_TRACEBACK is set."""
    if type(err).__name__ == "NoArgsIsHelpError":
        err.show()
        return 2
    if hasattr(err, "format_message") and isinstance(getattr(err, "exit_code", None), int):
        _say_error(err.format_message())
        return err.exit_code
    if os.environ.get("EMASIM_TRACEBACK"):
        raise err
    full = _disk_full(err)
    if full is not None:
        _say_error(f"{full}; free some space and run the same command again")
        return 1
    _say_error(f"internal error: {type(err).__name__}: {err} (EMASIM_TRACEBACK=1 shows where)")
    return 1


DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


def _disk_full(err: BaseException) -> str | None:
    """What a failure caused by a full disk or quota says (an OSError, or a database driver's
    error, in the chain of causes), None for any other failure."""
    seen = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, OSError) and err.errno in DISK_FULL:
            where = f": {err.filename}" if err.filename else ""
            return f"cannot write{where} ({err.strerror or os.strerror(err.errno)})"
        if "database or disk is full" in str(err):
            return "cannot write the database (database or disk is full)"
        err = err.__cause__ or err.__context__
    return None


app = typer.Typer(
    cls=_OneLineErrors,
    help="emasim: electromechanical actuator simulation and controller comparison.",
    no_args_is_help=True,
    add_completion=True,  # --install-completion: the shell completes commands and options
    pretty_exceptions_enable=False,
)

FORCE_HELP = "replace an earlier emasim result there (never anything emasim did not write)"
ForceOption = Annotated[bool, typer.Option("--force", help=FORCE_HELP)]
SettingOption = Annotated[
    list[str] | None, typer.Option("--set", "-s", help="dotted.key=value override")
]
COMPILE_NOTICE_S = 1.0  # a load of the compiled core this long was a compile: say so once


def _show_version(value: bool) -> None:
    if value:
        from .version import __version__

        console.print(f"emasim {__version__}", highlight=False)
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_show_version, is_eager=True, help="print the version and exit"
        ),
    ] = False,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="only warnings and errors: no tables, no progress")
    ] = False,
    verbose: Annotated[
        bool,
        typer.Option(
            "--verbose", "-v", help="also the library's debug messages (each run's timing)"
        ),
    ] = False,
) -> None:
    """emasim: electromechanical actuator simulation and controller comparison."""
    from .errors import InputError

    if quiet and verbose:
        raise InputError("--quiet and --verbose: give one of them")
    _configure_logging(logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO)


class _LineHandler(RichHandler):
    """rich's log handler on stderr, a record a line as the command line prints it: no time,
    level or path columns (nor the grid that pads them to the terminal's width), a warning
    marked ``warning:``, the message never read as markup, and never wrapped by rich (a long
    path would be cut mid-word at the terminal's width; the terminal wraps the line itself)."""

    def __init__(self) -> None:
        super().__init__(
            console=err_console,
            show_time=False,
            show_level=False,
            show_path=False,
            markup=True,
            highlighter=NullHighlighter(),
            keywords=[],
        )
        self.setFormatter(_MarkedFormatter())

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.console.print(self.render_message(record, self.format(record)), soft_wrap=True)
        except Exception:
            self.handleError(record)


class _MarkedFormatter(logging.Formatter):
    """The record's message, escaped for rich's markup, after ``warning:`` at WARNING and
    above."""

    def format(self, record: logging.LogRecord) -> str:
        text = escape(super().format(record))
        return f"[bold yellow]warning:[/] {text}" if record.levelno >= logging.WARNING else text


def _configure_logging(level: int) -> None:
    """The ``emasim`` logger's level and one handler to stderr (replaced on every command).
    Python warnings (a controller's design check, say) are captured into logging
    (``logging.captureWarnings``) and shown by the same handler as one ``warning:`` line: their
    message, without the source line or the category."""
    import warnings

    log.handlers[:] = [_LineHandler()]
    log.setLevel(level)
    log.propagate = False
    captured = logging.getLogger("py.warnings")
    captured.handlers[:] = log.handlers
    captured.propagate = False
    warnings.formatwarning = _warning_text
    # captureWarnings(True) does nothing while it holds; released first, it is installed again
    # where warnings.showwarning was restored since (a caller's warnings.catch_warnings)
    logging.captureWarnings(False)
    logging.captureWarnings(True)


def _warning_text(message, category, filename, lineno, line=None) -> str:
    """``warnings.formatwarning`` for the captured warnings: the message alone."""
    return str(message)


def _loud() -> bool:
    """Tables, progress and notes are shown (not --quiet)."""
    return log.getEffectiveLevel() <= logging.INFO


def _collector_off(command):
    """``command`` with Python's cycle collector off while it runs (on again after, as it was:
    a test runs commands in its own process). For a bounded job, one scenario's runs, whose
    arrays go by reference counting: the collector would only walk, twice in full, the objects
    numba's import and registry make (0.08 to 0.1 s of a 1 s command)."""

    @functools.wraps(command)
    def bounded(*args, **kwargs):
        was_on = gc.isenabled()
        gc.disable()
        try:
            return command(*args, **kwargs)
        finally:
            if was_on:
                gc.enable()

    return bounded


def _notice_compile() -> None:
    """One line before the one-off compile of the simulation core (numba's cache is cold)."""
    from . import numba_cache

    if numba_cache.is_cold():
        log.info("compiling the simulation core: first run only")


def _fail(err: Exception) -> None:
    _say_error(err)
    raise typer.Exit(code=2)


@app.command("list")
def list_all() -> None:
    """Show the shipped scenarios, the controllers of each loop and the presets."""
    from .control.registry import CASCADES, CONTROLLERS, DESCRIPTIONS
    from .scenarios.axis_scenario import builtin_axis_scenarios, read_axis_raw
    from .scenarios.loader import builtin_scenarios, read_scenario_file

    table = Table(title="scenarios")
    table.add_column("name")
    table.add_column("description")
    for name in sorted(builtin_scenarios()):
        raw, _ = read_scenario_file(name)
        table.add_row(name, raw.get("description", ""))
    for name in sorted(builtin_axis_scenarios()):
        raw, _, _ = read_axis_raw(name)
        table.add_row(name, f"{raw.get('description', '')} (emasim identify)")
    console.print(table)
    table = Table(title="controllers (--controller LOOP=NAME)")
    table.add_column("loop")
    table.add_column("name")
    table.add_column("what it is")
    for loop, names in CONTROLLERS.items():
        for name in names:
            table.add_row(loop, name, DESCRIPTIONS.get((loop, name), ""))
    for name, loops in CASCADES.items():
        chain = " over ".join(loops[lp]["name"] for lp in ("position", "speed"))
        table.add_row("cascade", name, f"position {chain} over the current loop")
    console.print(table)
    from .plant.presets import PRESETS, SENSOR_PRESETS

    table = Table(title="presets (plant.preset, sensors)")
    table.add_column("section")
    table.add_column("name")
    table.add_column("what it is")
    for section, presets in (("plant", PRESETS), ("sensors", SENSOR_PRESETS)):
        for name, make in presets.items():
            summary = " ".join((make.__doc__ or "").split("\n\n")[0].split())
            table.add_row(section, name, summary)
    console.print(table)


def _runs_bar(description: str, unit: str = "runs"):
    """A progress bar that counts runs (or trials; hidden with --quiet), and
    ``progress(done, total)``."""
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn(f"{{task.completed}}/{{task.total}} {unit}"),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
        disable=not _loud(),
    )
    task = bar.add_task(description, total=None)

    def progress(done: int, total: int) -> None:
        bar.update(task, completed=done, total=total)

    return bar, progress


class _LazyProgress:
    """A progress bar that appears only once a run has taken more than ``delay_s``."""

    def __init__(self, label: str, delay_s: float = 1.0):
        self.label, self.delay_s = label, delay_s
        self.start = time.perf_counter()
        self.bar: Progress | None = None
        self.task = None

    def __call__(self, fraction: float) -> None:
        if self.bar is None and _loud() and time.perf_counter() - self.start > self.delay_s:
            self.bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                TimeRemainingColumn(),
                console=err_console,
                transient=True,
            )
            self.bar.start()
            self.task = self.bar.add_task(self.label, total=1.0)
        if self.bar is not None:
            self.bar.update(self.task, completed=fraction)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def _print_warnings(result) -> None:
    """The warning lines of each run (its meta.json's ``warnings``: each stop it touched and
    each physical limit it crossed, emasim.experiments.runs)."""
    records = getattr(result, "results", None) or {result.meta["label"]: result}
    for label, record in records.items():
        for line in record.meta.get("warnings", []):
            log.warning(f"{label}: {line}")


def _print_metrics(by_label: dict[str, dict], title: str, reasons: dict | None = None) -> None:
    """One row per metric, one column per run: the metric's name in words (breakable where
    the terminal is narrow, never cut) and its unit apart, read from the name's end; each
    ``nan`` then printed with its reason (``reasons``: label -> metric -> why undefined)."""
    if not _loud():
        return
    table = Table(title=title)
    table.add_column("metric", overflow="fold", ratio=1)
    table.add_column("unit", no_wrap=True)
    for label in by_label:
        table.add_column(label, justify="right", no_wrap=True)
    keys = list(dict.fromkeys(k for m in by_label.values() for k in m))
    for key in keys:
        cells = [by_label[label].get(key) for label in by_label]
        table.add_row(*_in_words(key), *("" if v is None else f"{v:.4g}" for v in cells))
    console.print(table)
    for label, why in (reasons or {}).items():
        for key, reason in why.items():
            console.print(f"nan: {label}, {key}: {reason}", highlight=False, markup=False)


def _in_words(metric: str) -> tuple[str, str]:
    """(the metric's name in words, its unit), the unit read from the name's end."""
    from .analysis.units import SUFFIXES, unit_of

    unit = unit_of(metric)
    suffix = next((sfx for sfx, u in SUFFIXES if u == unit and metric.endswith(sfx)), "")
    return metric.removesuffix(suffix).replace("_", " "), unit


@app.command()
@_collector_off
def run(
    scenario: Annotated[str, typer.Argument(help="a shipped scenario name or a .toml path")],
    controller: Annotated[
        list[str] | None,
        typer.Option(
            "--controller",
            "-c",
            help="LOOP=NAME, e.g. speed=st-gpio (repeatable), or a cascade: hybrid, pid; "
            "starts from the gains of the comparison's set that uses it",
        ),
    ] = None,
    label: Annotated[
        list[str] | None,
        typer.Option(
            "--label",
            "-l",
            help="run this controller set of the comparison alone (repeatable: those sets, "
            "compared)",
        ),
    ] = None,
    setting: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            "-s",
            help="dotted.key=value override, e.g. duration_s=1 "
            "or plant.backlash.width_mm=0.2 (repeatable)",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="run folder (default: a fresh runs/SCENARIO/WHAT-YYYYmmdd-HHMMSS)"
        ),
    ] = None,
    force: ForceOption = False,
    trust_fmu: Annotated[
        bool,
        typer.Option(
            "--trust-fmu", help="allow solver.mechanism_fmu: loading an FMU runs its code"
        ),
    ] = False,
    plot: Annotated[bool, typer.Option(help="write plot.png")] = True,
    trace_format: Annotated[
        str,
        typer.Option("--format", help="the traces' file: parquet, csv or mat (MATLAB, with units)"),
    ] = "parquet",
) -> None:
    """Run a scenario (every controller set it compares, or the one chosen); write the run
    folder and print the metrics."""
    from .output import check_target
    from .scenarios.loader import load_scenario

    try:
        sc = load_scenario(
            scenario, settings=setting or [], controllers=controller or [], label=label
        )
        from .analysis.figure_process import figure_writer

        # the figure process imports matplotlib from here on, while this one loads the compiled
        # core and simulates; a refusal ends it at once, having drawn nothing
        with figure_writer(plot) as figures:
            # the compiled core (numba) loads only for a valid scenario
            from .experiments.batch import run as run_any
            from .sim.cosim import check_runnable
            from .sim.result import check_trace_format

            check_runnable(sc, trust_fmu)  # every rule, before the compile notice
            check_trace_format(trace_format, sc)
            if out is not None:
                check_target(out, force)  # refuse before spending the simulation time
            _notice_compile()
            progress = _LazyProgress(f"simulating {sc.name}")
            try:
                with warnings.catch_warnings():  # printed as warning lines (_print_warnings)
                    warnings.simplefilter("ignore", PhysicalLimitWarning)
                    result = run_any(sc, progress=progress, trust_fmu=trust_fmu)
                by_label = result.metrics if sc.compare else {result.meta["label"]: result.metrics}
            finally:
                progress.close()
            for record in [result, *getattr(result, "results", {}).values()]:
                record.meta["overrides"] = list(setting or [])  # for the plots' titles
            folder = result.save(out, plot=plot, overwrite=force, trace_format=trace_format,
                                 figures=figures, words="command line")  # fmt: skip
    except EmasimError as err:
        _fail(err)
    runs = getattr(result, "results", None) or {result.meta["label"]: result}
    reasons = {label: r.meta.get("undefined_metrics", {}) for label, r in runs.items()}
    _print_metrics(by_label, f"{sc.name}: metrics", reasons)
    _print_warnings(result)
    if (label and len(label) == 1) or controller:  # one set: whose gains it took
        origin = sc.tuning.get("gains_from")
        log.info(
            f"gains: those of the comparison's controller set {origin}"
            if origin
            else "gains: the scenario's own and the library's defaults (no controller set of "
            "the comparison uses this choice)"
        )
    compiled = result.meta.get("compile_s", 0.0)
    if compiled >= COMPILE_NOTICE_S:
        log.info(f"compiled the simulation core in {compiled:.0f} s (not counted below)")
    log.info(
        f"simulated {sc.duration_s:g} s x {len(by_label)} in "
        f"{result.meta['simulation_wall_s']:.3f} s (real-time factor "
        f"{result.meta['real_time_factor']:.4f}); wrote {folder}/"
    )


@app.command()
def tune(
    scenario: Annotated[str, typer.Argument(help="a shipped scenario name or a .toml path")],
    controller: Annotated[
        list[str] | None,
        typer.Option("--controller", "-c", help="tune this choice instead of the comparison"),
    ] = None,
    setting: Annotated[list[str] | None, typer.Option("--set", "-s")] = None,
    trials: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=10000,
            help="one trial count for every controller set, per round (default: "
            "--trials-per-knob x its knobs)",
        ),
    ] = None,
    trials_per_knob: Annotated[
        int, typer.Option(min=1, max=10000, help="trials per knob of a set, per round")
    ] = DEFAULT_BUDGET.trials_per_knob,
    patience_per_knob: Annotated[
        int,
        typer.Option(
            min=0,
            max=10000,
            help="stop a round once its best improved by less than --tolerance over this "
            "many trials per knob (0: never early)",
        ),
    ] = DEFAULT_BUDGET.patience_per_knob,
    tolerance: Annotated[
        float,
        typer.Option(min=0.0, max=1.0, help="relative improvement --patience-per-knob asks for"),
    ] = DEFAULT_BUDGET.tolerance,
    widen: Annotated[
        int,
        typer.Option(min=0, max=20, help="times a bound the optimum sits on may be widened"),
    ] = DEFAULT_BUDGET.widenings,
    workers: Annotated[
        int | None,
        typer.Option(min=1, max=1024, help="trials at once (default: one per core, threads)"),
    ] = None,
    scheduler: Annotated[
        str | None, typer.Option(help="a Dask scheduler address to run the trials on")
    ] = None,
    save: Annotated[
        Path | None,
        typer.Option(help="tuned scenario file (default a fresh runs/tune/SCENARIO-TIME.toml)"),
    ] = None,
    force: ForceOption = False,
    seed: Annotated[int, typer.Option(min=0, max=2**32 - 1, help="sampler seed")] = 0,
) -> None:
    """Tune every controller set of a scenario under the same cost and rule (Optuna): trials
    in proportion to its knobs, an early stop once converged, a range widened where the optimum
    sits on its bound; every trial a run of a job store (runs/tune/jobs-KEY, keyed by the fully
    resolved scenario, the seed and the trials at once), so the same command resumes; writes
    the scenario with the tuned gains and a record of each set's search."""
    from .experiments.batch import check_scheduler, dask_client
    from .naming import RUNS_ROOT, fresh_file, slug
    from .output import CLI_HINTS, check_target, write_file
    from .scenarios.loader import (
        apply_controller_choice,
        apply_setting,
        read_scenario_file,
        read_scenario_text,
        validate_scenario,
    )
    from .tuning import (
        STORE_ROOT,
        check_tunable,
        is_tuned_scenario,
        tune_scenario,
        tuned_toml,
        tuning_store,
    )

    budget = Budget(trials, trials_per_knob, patience_per_knob or None, tolerance, widen)

    try:
        raw, source = read_scenario_file(scenario)
        text, _ = read_scenario_text(scenario)  # its comments and layout stay in the tuned file
        if controller:
            raw.pop("compare", None)
        for choice in controller or []:
            apply_controller_choice(raw, choice)
        for item in setting or []:
            apply_setting(raw, item)
        sc = validate_scenario(raw, source)
        check_tunable(sc)
        if scheduler is not None:
            check_scheduler(scheduler)
        if save is not None:
            check_target(save, force, "--save", CLI_HINTS[:1], is_tuned_scenario)
    except EmasimError as err:
        _fail(err)
    _notice_compile()

    def report(label, tuned):
        shown = "n/a (its trial was interrupted)" if tuned.given is None else f"{tuned.given:.5g}"
        bounds = "".join(
            f"; optimum on the {side} bound of {key}" for key, side in tuned.on_bound.items()
        )
        log.info(
            f"{label}: cost {shown} -> {tuned.best:.5g} in {tuned.trials} trials "
            f"({len(tuned.study.best_params)} knobs, {tuned.stopped}){bounds}"
        )

    bar, count = _runs_bar(f"tuning {sc.name}", unit="trials")

    def progress(label, done, total):
        bar.update(bar.task_ids[0], description=f"tuning {sc.name}: {label}")
        count(done, total)

    try:
        with bar, dask_client(scheduler, workers, processes=False) as client:
            store = tuning_store(STORE_ROOT, sc, seed, client)
            tuned, _ = tune_scenario(raw, sc, budget, store, seed, report, progress, client)
        target = save or fresh_file(RUNS_ROOT / "tune", f"{slug(sc.name)}", ".toml")
        write_file(
            target,
            tuned_toml(tuned, sc.name, text),
            force=force,
            is_ours=is_tuned_scenario,
            what="--save",
        )
    except EmasimError as err:
        _fail(err)
    log.info(f"tuned scenario written to {target} (its trials in {store.folder})")


@app.command()
def study(
    scenario: Annotated[str, typer.Argument(help="a shipped scenario name or a .toml path")],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="study folder; the same command resumes it")
    ],
    vary: Annotated[
        list[str] | None,
        typer.Option(
            "--vary",
            help="KEY=SPEC (repeatable): a list 0.05,0.1; linspace(a,b,n); geomspace(a,b,n); "
            "uniform(a,b); normal(mean,std); loguniform(a,b); integers(a,b); discrete(a,b,n); "
            "a leading * scales the scenario's value",
        ),
    ] = None,
    runs: Annotated[
        int, typer.Option(min=1, max=100_000, help="Monte Carlo runs of each grid point")
    ] = 1,
    seeds: Annotated[
        int, typer.Option(min=1, max=100_000, help="a grid over the scenario seed: seed..+N-1")
    ] = 1,
    seed: Annotated[int, typer.Option(min=0, max=2**32 - 1, help="seed of the draws")] = 0,
    label: Annotated[
        list[str] | None,
        typer.Option("--label", "-l", help="run only this controller set (repeatable)"),
    ] = None,
    setting: Annotated[
        list[str] | None, typer.Option("--set", "-s", help="dotted.key=value, fixed")
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="a Dask scheduler address (default: a LocalCluster on this machine)"),
    ] = None,
    workers: Annotated[
        int | None, typer.Option(min=1, max=1024, help="LocalCluster workers (default: cores)")
    ] = None,
    traces: Annotated[bool, typer.Option(help="keep each run's traces (result.parquet)")] = False,
    trust_fmu: Annotated[
        bool, typer.Option("--trust-fmu", help="allow solver.mechanism_fmu (runs its code)")
    ] = False,
) -> None:
    """Run a grid or a Monte Carlo over any scenario keys, every controller set on every sample,
    on Dask; write a run folder per run, metrics.parquet and a summary; resumable."""
    from .experiments.batch import check_scheduler
    from .experiments.study import StudySpec, run_study

    spec = StudySpec(
        scenario=scenario,
        vary=tuple(vary or ()),
        runs=runs,
        seeds=seeds,
        seed=seed,
        labels=tuple(label or ()),
        settings=tuple(setting or ()),
        traces=traces,
    )
    start = time.perf_counter()
    bar, progress = _runs_bar(f"study of {scenario}")

    shown = []

    def progress_shown(done: int, total: int) -> None:
        if not shown:  # the bar shows once the study is accepted: a refusal is one line
            bar.start()
            shown.append(True)
        progress(done, total)

    try:
        if scheduler is not None:
            check_scheduler(scheduler)
        # every sample is validated before a cluster starts
        result = run_study(spec, out, scheduler, workers, progress_shown, trust_fmu)
    except EmasimError as err:
        _fail(err)
    finally:
        if shown:
            bar.stop()
    _print_study(result)
    log.info(
        f"{len(result.table)} runs in {out}/ (metrics.parquet, summary/) in "
        f"{time.perf_counter() - start:.1f} s: {_status_line(result.table)}"
    )


def _status_line(table) -> str:
    """'3 ok, 1 diverged, 0 failed'."""
    from .experiments.store import status_counts

    return ", ".join(f"{n} {kind}" for kind, n in status_counts(table).items())


def _print_study(result) -> None:
    """How many runs are ok, diverged and failed, the first reasons (warnings), and the median
    [5 %, 95 %] of each metric that varies, one column per controller set: at each value of
    every varied key that takes a few (study.grouping_keys), else over all the runs."""
    from .experiments.store import LOG_FILE, OK, first_reasons, status_counts

    counts = status_counts(result.table)
    if counts[OK] < len(result.table):
        log.warning(
            f"{len(result.table)} runs: {_status_line(result.table)} (status in "
            f"metrics.parquet; worker messages in {result.folder / LOG_FILE}); the first:"
        )
        for line in first_reasons(result.table):
            log.warning(line)
    if not _loud() or not counts[OK]:
        return
    from .experiments.study import grouping_keys, metric_columns, summarize_by

    table, plan = result.table, result.plan
    metrics = [m for m in metric_columns(table, plan) if table[m].nunique(dropna=True) > 1]
    title = f"{plan.spec.scenario}: median [5 %, 95 %] over the runs"
    keys = grouping_keys(table, plan)
    for key in keys:  # a table per varied key, a block of rows per value, the others pooled
        _print_summary(f"{title} at each {key}", metrics, summarize_by(table, plan, key), key)
    if not keys:
        _print_summary(title, metrics, {None: result.summary()})


def _print_summary(title: str, metrics: list[str], groups: dict, key: str | None = None) -> None:
    """A study's summary table: a row per metric, in a block per value of ``key`` (``groups``:
    value -> label -> metric -> distribution; one group, None, when nothing is grouped), a
    column per controller set."""
    if not metrics:
        return
    table = Table(title=title)
    if key is not None:
        table.add_column(key, justify="right", overflow="fold")
    table.add_column("metric", overflow="fold", ratio=1)
    table.add_column("unit", no_wrap=True)
    labels = list(next(iter(groups.values())))
    for name in labels:
        table.add_column(name, justify="right", overflow="fold")
    for value, summary in groups.items():
        for k, metric in enumerate(metrics):
            cells = []
            for label in labels:
                d = summary[label][metric]
                cells.append(
                    f"{d['p50']:.4g} [{d['p05']:.3g}, {d['p95']:.3g}]" if d["runs"] else ""
                )
            shown = f"{value:.4g}" if isinstance(value, float) else str(value)
            first = [shown if k == 0 else ""] if key is not None else []
            last = k == len(metrics) - 1
            table.add_row(*first, *_in_words(metric), *cells, end_section=last)
    console.print(table)


@app.command()
def reproduce(
    ctx: typer.Context,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="report folder (default: a fresh runs/reproduce/all-TIME, or only-NAMES-TIME)",
        ),
    ] = None,
    only: Annotated[
        list[str] | None,
        typer.Option("--only", help="run only this experiment (repeatable)"),
    ] = None,
    force: ForceOption = False,
    ablation: Annotated[
        bool,
        typer.Option(help="re-run the bench experiments as the bench's elements are added"),
    ] = True,
    robustness: Annotated[
        bool,
        typer.Option(
            "--robustness",
            help="run the Monte Carlo of the headline verdicts over the plant uncertainty, "
            "the wear study and the verdict map (minutes; resumable, in runs/robustness/)",
        ),
    ] = False,
    runs: Annotated[
        int, typer.Option(min=10, max=100_000, help="--robustness runs per controller set")
    ] = 200,
    seed: Annotated[
        int,
        typer.Option(
            min=0,
            max=2**63 - 1,
            help="the seed of the --robustness Monte Carlo's draws (each seed its own study)",
        ),
    ] = 0,
    replicas: Annotated[
        int,
        typer.Option(
            min=0,
            max=1000,
            help="the paired replicas over which the abstract's claims are decided (minutes; "
            "resumable, in runs/replicas/); 0: show the latest complete replica study",
        ),
    ] = 16,
) -> None:
    """Run every paper experiment and write report.md, report.html and tables.json; decide
    the abstract's claims over --replicas paired replicas (SPEC section 8); the
    robustness of the headline verdicts, the wear and the verdict map are those of the last
    --robustness studies of these experiments, --seed and version, when they exist."""
    from .analysis.paper_report import EXPERIMENTS
    from .errors import InputError
    from .experiments.reproduction import check_replicas, check_robustness
    from .experiments.reproduction import reproduce as run_all
    from .output import check_target

    # the name, not click's enum: typer's own copy of click has its own
    if not robustness and ctx.get_parameter_source("runs").name != "DEFAULT":
        _fail(InputError("--runs applies to --robustness: add --robustness, or leave --runs out"))
    names = [e.scenario for e in EXPERIMENTS]
    unknown = [n for n in only or [] if n not in names]
    if unknown:
        _fail(
            EmasimError(
                f"--only: unknown experiment {unknown[0]!r}; choose from: {', '.join(names)}"
            )
        )
    start = time.perf_counter()
    progress = _LazyProgress("reproducing the paper")
    try:
        if robustness:
            check_robustness(only)
        if ctx.get_parameter_source("replicas").name != "DEFAULT":
            check_replicas(only)
        if out is not None:
            check_target(out, force)
        _notice_compile()
        folder = run_all(
            out,
            only=only,
            progress=progress,
            force=force,
            with_ablation=ablation,
            robustness_runs=runs if robustness else None,
            robustness_seed=seed,
            replica_count=replicas,
        )
    except EmasimError as err:
        _fail(err)
    finally:
        progress.close()
    _print_claims(folder)
    log.info(
        f"wrote {folder}/report.md, report.html, tables.json, runs.parquet in "
        f"{time.perf_counter() - start:.1f} s"
    )


def _print_claims(folder: Path) -> None:
    """The abstract's claims as the report decided them, a line each (emasim.analysis.claims),
    when the report holds them."""
    import json

    from .analysis.claims import claim_lines

    tables = folder / "tables.json"
    claims = json.loads(tables.read_text()).get("claims") if tables.is_file() else None
    if claims:
        console.print(
            f"the abstract's claims over {claims['replicas']} paired replicas "
            "(measured: what the bench sees; true: the rudder's angle):",
            soft_wrap=True,
            markup=False,
        )
        for line in claim_lines(claims):
            console.print(f"  {line}", soft_wrap=True, markup=False)


@app.command()
def acceptance(
    scenario: Annotated[str, typer.Argument(help="a shipped scenario name or a .toml path")],
    label: Annotated[
        list[str] | None,
        typer.Option("--label", "-l", help="test only this controller set (repeatable)"),
    ] = None,
    setting: SettingOption = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="datasheet folder (default: a fresh runs/acceptance/SCENARIO-TIME)"
        ),
    ] = None,
    excitation: Annotated[
        str,
        typer.Option(
            "--excitation",
            help="the frequency responses' input: 'stepped' sines, or 'chirp', one logarithmic "
            "sweep per amplitude (the best linear approximation of each)",
        ),
    ] = "stepped",
    force: ForceOption = False,
) -> None:
    """Run the actuator acceptance battery (frequency response, threshold, stiffness, rate and
    load) for each controller set; write datasheet.json, frequency_response.csv, report.html
    and the figures."""
    from .output import check_target
    from .scenarios.loader import load_scenario

    try:
        sc = load_scenario(scenario, settings=setting or [])
        from .experiments.acceptance import Battery, check_acceptance, run_acceptance

        battery = Battery(excitation=excitation)
        check_acceptance(sc, label, battery)  # every rule, before anything is compiled or run
        if out is not None:
            check_target(out, force)  # refuse before spending the simulation time
        _notice_compile()
        start = time.perf_counter()
        bar, progress = _runs_bar(f"acceptance battery of {sc.name}")
        with bar:
            result = run_acceptance(sc, labels=label, battery=battery, progress=progress)
        folder = result.save(out, force=force)
    except EmasimError as err:
        _fail(err)
    _print_datasheet(result)
    log.info(
        f"{result.meta['runs']} runs, {result.meta['simulated_s']:.0f} s simulated in "
        f"{time.perf_counter() - start:.1f} s; wrote {folder}/ (datasheet.json, "
        "frequency_response.csv, report.html)"
    )


def _print_datasheet(result) -> None:
    """The datasheet's figures, a row each (the name in words, wrapped, and its unit), a column
    per set, its words wrapped too ("not measurable: ...": unwrapped, they left the names no
    room in a narrow terminal); then each set's linear model, or why it has none."""
    if not _loud():
        return
    from .analysis.datasheet import cell

    table = Table(title=f"{result.scenario.name}: acceptance datasheet")
    table.add_column("figure", overflow="fold", ratio=1)
    table.add_column("unit", no_wrap=True)
    for name in result.figures:
        table.add_column(name, justify="right", overflow="fold")
    for key in next(iter(result.figures.values())):
        table.add_row(*_in_words(key), *(cell(f[key]) for f in result.figures.values()))
    console.print(table)
    for label, text in result.meta["linear_model"].items():
        console.print(f"linear model of {label}: {text}", highlight=False, markup=False)


@app.command()
def identify(
    scenario: Annotated[
        str,
        typer.Argument(
            help="the scenario whose experiment made the trace: emps (an axis), bench-identify "
            "(the bench's friction, backlash and clearance), or a .toml path"
        ),
    ],
    data: Annotated[
        list[Path],
        typer.Option(
            "--data",
            "-d",
            help="the measured trace: .csv, .mat or .parquet (repeatable: a series, each "
            "identified in turn, e.g. over an actuator's life)",
        ),
    ],
    at: Annotated[
        list[str] | None,
        typer.Option("--at", help="each --data trace's date or cycle count, in order"),
    ] = None,
    fit: Annotated[
        list[str] | None,
        typer.Option(
            "--fit",
            "-f",
            help="KEY or KEY=LOW:HIGH to fit, e.g. plant.mass_kg=10:1000, or KEY,KEY=*LOW:HIGH "
            "for a factor on their values (repeatable; default: the scenario's identify.fit)",
        ),
    ] = None,
    mapping: Annotated[
        list[str] | None,
        typer.Option("--map", "-m", help="FILE_COLUMN=SIGNAL, e.g. qm=position_m (repeatable)"),
    ] = None,
    method: Annotated[
        str | None,
        typer.Option("--method", help="output-error (default) or idim (inverse model)"),
    ] = None,
    validate: Annotated[
        list[Path] | None,
        typer.Option(
            "--validate", help="a second trace simulated with the fitted values (repeatable)"
        ),
    ] = None,
    starts: Annotated[
        int, typer.Option("--starts", help="output-error starts (the first from IDIM-LS)")
    ] = 1,
    setting: SettingOption = None,
    label: Annotated[
        str | None,
        typer.Option("--label", "-l", help="the controller set that ran the experiment"),
    ] = None,
    wear: Annotated[
        bool,
        typer.Option(
            "--wear",
            help="with a series: run the bench experiments, PID and hybrid, at each trace's "
            "identified values (minutes; resumable, in runs/robustness/)",
        ),
    ] = False,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="result folder (default: a fresh runs/SCENARIO/identify-TIME)"
        ),
    ] = None,
    force: ForceOption = False,
) -> None:
    """Fit a scenario's parameters to a measured trace (output-error or IDIM-LS); write
    identified.json, the calibrated scenario.toml, traces.parquet, fit.png and report.md."""
    from .identification.identify import default_folder, identify_series, shown
    from .identification.identify import identify as run_identify
    from .output import check_target

    options = {
        "fit": fit or [],
        "mapping": mapping or [],
        "method": method,
        "settings": setting or [],
        "validate": validate or [],
        "starts": starts,
        "label": label,
    }
    try:
        if out is not None:
            check_target(out, force)  # refuse before spending the fit's time
        target = out or default_folder(scenario)
        if len(data) > 1 or at or wear:
            series = identify_series(
                scenario, data, at, out=target, force=force, wear=wear, **options
            )
        else:
            result = run_identify(scenario, data[0], out=target, force=force, **options)
    except EmasimError as err:
        _fail(err)
    if len(data) > 1 or at or wear:
        _print_series(series)
        return
    if _loud():
        table = Table(title=f"{result.scenario}: identified by {result.method}")
        table.add_column("key")
        table.add_column("value", justify="right")
        table.add_column("95 % interval", justify="right")
        for key, value in result.values.items():
            table.add_row(key, f"{value:.6g}", f"± {result.interval95[key]:.3g}")
        console.print(table)
        table = Table(title="free-run simulation: relative errors, position RMSE")
        table.add_column("output")
        table.add_column("training", justify="right")
        for path in result.validation:
            table.add_column(Path(path).name, justify="right")
        for name, error in result.errors.items():
            others = [shown(name, v[name]) for v in result.validation.values()]
            table.add_row(name, shown(name, error), *others)
        console.print(table)
    for key, bound in result.on_bound.items():
        log.warning(f"{key} sits on the {bound} bound of its --fit range: widen it")
    log.info(
        f"identified in {result.seconds:.1f} s; wrote {result.folder}/ (identified.json, "
        "scenario.toml, traces.parquet, fit.png, report.md)"
    )


def _print_series(series) -> None:
    if _loud():
        keys = list(series.runs[0].values)
        table = Table(title="identified over the series (value ± 95 % interval)")
        table.add_column("at")
        for key in keys:
            table.add_column(_short_key(key), justify="right")
        for _, row in series.table.iterrows():
            cells = [f"{row[k]:.5g} ± {row[f'{k} interval95']:.2g}" for k in keys]
            table.add_row(str(row["at"]), *cells)
        console.print(table)
    wear = ", wear.json, wear.png" if series.wear is not None else ""
    log.info(f"wrote {series.folder}/ (series.csv, series.png{wear}, a folder per trace)")


def _short_key(key: str) -> str:
    """A key's last dotted part; a factor on several paths: their common part's, 'factor'."""
    from .experiments.variation import FACTOR

    if not key.endswith(FACTOR):
        return key.rsplit(".", 1)[-1]
    parts = [path.split(".") for path in key.removesuffix(FACTOR).split(",")]
    common = [p[0] for p in zip(*parts, strict=False) if len(set(p)) == 1]
    return (common[-1] if common else "keys") + FACTOR


runs_app = typer.Typer(help="The results emasim wrote under a folder: list them, prune old ones.")
app.add_typer(runs_app, name="runs")
RUNS_ROOT_HELP = "the folder to look in (default: runs)"


@runs_app.command("list")
def runs_list(
    root: Annotated[Path, typer.Argument(help=RUNS_ROOT_HELP)] = Path("runs"),
    as_json: Annotated[
        bool, typer.Option("--json", help="one JSON list on stdout, each result's full path")
    ] = False,
) -> None:
    """List every emasim result under a folder, oldest first: its kind, age and size; each
    result named relative to the folder (--json: its full path)."""
    import json

    from .results import find

    try:
        found = find(root)
    except EmasimError as err:
        _fail(err)
    if as_json:
        rows = [{"folder": str(r.folder.resolve()), "kind": r.kind, "written": r.written,
                 "bytes": r.size} for r in found]  # fmt: skip
        print(json.dumps(rows, indent=1))
        return
    rows = [("result", "kind", "written", "MB")] + [
        (
            _under(r.folder, root),
            r.kind,
            time.strftime("%Y-%m-%d %H:%M", time.localtime(r.written)),
            f"{r.size / 1e6:.3g}",
        )
        for r in found
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    for *left, size in rows:  # plain lines, never cut or folded: the terminal wraps them
        cells = [cell.ljust(width) for cell, width in zip(left, widths, strict=True)]
        line = "  ".join([*cells, size.rjust(len("MB"))])
        console.print(line.rstrip(), soft_wrap=True, markup=False, highlight=False)
    total_mb = sum(r.size for r in found) / 1e6
    log.info(f"{len(found)} emasim results under {root}, {total_mb:.3g} MB")


def _under(folder: Path, root: Path) -> str:
    """``folder`` relative to ``root`` (``.`` for the root itself), with forward slashes."""
    return folder.relative_to(root).as_posix()


@runs_app.command("prune")
def runs_prune(
    root: Annotated[Path, typer.Argument(help=RUNS_ROOT_HELP)] = Path("runs"),
    older_than: Annotated[
        str | None, typer.Option("--older-than", help="only results older than this: 12h, 7d, 2w")
    ] = None,
    keep: Annotated[
        int | None, typer.Option("--keep", help="keep this many newest results of each folder")
    ] = None,
    yes: Annotated[bool, typer.Option("--yes", help="remove them (without it: a dry run)")] = False,
) -> None:
    """Remove old emasim results (a dry run unless --yes): only folders holding emasim's marker,
    and of them only emasim's own files; a result holding a file of yours stays whole."""
    from .results import choose, find, parse_age, remove

    try:
        chosen = choose(find(root), parse_age(older_than) if older_than else None, keep)
    except EmasimError as err:
        _fail(err)
    freed = 0
    for result in chosen:
        if not yes:
            console.print(
                f"would remove {_under(result.folder, root)} ({result.size / 1e6:.3g} MB)",
                soft_wrap=True,
                markup=False,
                highlight=False,
            )
            continue
        try:
            kept = remove(result.folder)
        except OSError as err:
            reason = err.strerror or str(err)
            log.warning(
                f"{_under(result.folder, root)}: cannot remove: {reason[:1].lower()}{reason[1:]}"
            )
            continue
        if kept:
            log.warning(
                f"{_under(result.folder, root)}: kept, it holds files emasim did not write "
                f"({kept[0]})"
            )
        else:
            freed += result.size
            console.print(
                f"removed {_under(result.folder, root)}",
                soft_wrap=True,
                markup=False,
                highlight=False,
            )
    if yes:
        log.info(f"{len(chosen)} results chosen; freed {freed / 1e6:.3g} MB")
    else:
        total = sum(r.size for r in chosen) / 1e6
        log.info(f"{len(chosen)} results chosen; would free {total:.3g} MB; add --yes to remove")


@app.command("export-fmu")
def export_fmu(
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", help="FMU file (default emasim-plant.fmu, or emasim-mechanism.fmu)"
        ),
    ] = None,
    preset: Annotated[
        str, typer.Option(help="plant preset: sea805 (lumped rudder) or sea805-linkage")
    ] = "sea805-linkage",
    mechanism: Annotated[
        bool, typer.Option("--mechanism", help="the linkage alone, its rod velocity driven")
    ] = False,
    force: ForceOption = False,
) -> None:
    """Write the plant (drive + rudder stage or linkage) as an FMI 2.0 co-simulation FMU.

    Inputs ud_V, uq_V, load_torque_Nm, rod_force_N; parameter step_s (sub-step, 1e-5 s).

    Outputs id_A, iq_A, motor_speed_rad_s, actuator_position_m, rudder_angle_rad, and more.

    --mechanism: the linkage alone; input rod_velocity_m_s, outputs rudder_angle_rad, rod_force_N.

    The FMU (pythonfmu) runs emasim in the Python of the tool that loads it: install emasim there.
    """
    from .errors import InputError
    from .plant.presets import PRESETS
    from .sim.fmi import export_mechanism_fmu, export_plant_fmu

    try:
        if preset not in PRESETS:
            raise InputError(
                f"--preset: unknown preset '{preset}'; choose one of: {', '.join(PRESETS)}"
            )
        plant = PRESETS[preset]()
        if mechanism and plant.linkage is None:
            raise InputError(f"--preset {preset} has no linkage; --mechanism needs one")
        export = export_mechanism_fmu if mechanism else export_plant_fmu
        default = "emasim-mechanism.fmu" if mechanism else "emasim-plant.fmu"
        path = export(out or Path(default), plant, force=force)
    except EmasimError as err:
        _fail(err)
    what = "mechanism" if mechanism else "plant"
    log.info(f"wrote {path} ({what} FMU, FMI 2.0 co-simulation, {preset})")


def program() -> None:
    """The ``emasim`` program (and ``python -m emasim``): the command line, in a process of its
    own. When the command is done, Python's cycle collector is frozen (``gc.freeze``), so the
    interpreter's shutdown frees the objects by reference counting and no longer walks, in its
    final collections, the hundreds of thousands that numba's import and registry make: 0.14 s
    of each command that loads the compiled core (a fresh process that loads it and exits:
    0.70 against 0.56 s, interleaved). Every file emasim writes is closed before (written whole,
    then published), and the standard streams and ``atexit`` handlers are handled as before.
    In process (tests, notebooks) ``app`` is called instead, and nothing is frozen."""
    try:
        app()
    finally:
        gc.freeze()
