"""Figures drawn by a second process, which imports matplotlib while the first one simulates.

Importing matplotlib and drawing a run's figure take about half a second of a single
``emasim run`` of one second, and neither depends on the simulation until the very end. So
``emasim run`` forks a *figure process* as soon as the scenario is valid, before it imports
the compiled core: it imports ``emasim.analysis.plots`` (matplotlib) on the second core while
the first loads the compiled core and simulates. The import runs on a thread at the lowest
CPU priority (``os.nice(FIGURE_NICENESS)``, which Linux applies to the calling thread): where
every core simulates (a comparison's sets on two threads), it takes only the cycles they leave,
so it never slows the simulation it waits for. A result folder's writer then hands each figure
to it (:meth:`save`: the function that draws it, pickled, and the path of its PNG) and goes on
writing traces and metrics while it is drawn; before the folder is published, :meth:`wait`
collects every figure, and re-raises in the first process whatever the drawing raised, so a
failed figure fails the write as before. The figures are received and drawn by the process's
main thread, at the first process's priority: every caller hands them over once it has
simulated, so the first process is then waiting for them, and at the lowest priority any other
work on the machine (a build, a test suite) would hold them back.

The figure process writes its PNG through ``emasim.output.new_file`` into the folder being
built, so the file is listed in that build's journal like every other. It ends when told
(:meth:`close`; at once if it was handed nothing: a refused run costs no wait for its
import), and at once when the first process ends: the kernel ends it then.
Where ``fork`` is not available (or not safe: macOS, Windows), :func:`figure_writer` gives
:class:`DrawHere`, which draws in the calling process; the files are the same either way.
"""

import contextlib
import ctypes
import importlib
import multiprocessing
import os
import pickle
import queue
import signal
import sys
import threading
from pathlib import Path

PR_SET_PDEATHSIG = 1  # linux/prctl.h
CLOSE_S = 5.0  # how long close() lets the figure process finish before ending it
FIGURE_NICENESS = 19  # the lowest priority: the figure process yields every core it shares


class FigureProcessError(RuntimeError):
    """The figure process ended before it drew every figure handed to it."""


class DrawHere:
    """Draw each figure in this process, at once (no second process)."""

    def save(self, draw, path: Path) -> None:
        """Write the figure ``draw()`` returns (a matplotlib Figure) to ``path``."""
        from .plots import save_figure

        save_figure(draw(), path)

    def wait(self) -> None:
        """Every figure is written already."""

    def close(self) -> None:
        """Nothing to end."""


class FigureProcess:
    """A forked process that imports matplotlib now and draws the figures handed to it later.

    Two one-way pipes: jobs (pickled ``(draw, path)``, sent by a thread of this process, so
    :meth:`save` never waits for the figure process to read) and answers (None, or the
    exception drawing raised). Each process closes the ends it does not use, so the death of
    either one is an end-of-file to the other, never a wait for a message half sent.
    """

    def __init__(self) -> None:
        context = multiprocessing.get_context("fork")
        jobs_in, self._jobs = context.Pipe(duplex=False)
        self._answers, answers_out = context.Pipe(duplex=False)
        self._process = context.Process(
            target=_serve,
            args=(jobs_in, self._jobs, answers_out, self._answers, os.getpid()),
            daemon=True,
        )
        self._process.start()
        jobs_in.close()
        answers_out.close()
        self._outbox = queue.SimpleQueue()
        self._sender = threading.Thread(target=self._send_all, daemon=True)
        self._sender.start()
        self._pending = 0
        self._handed = False  # whether any figure was handed over

    def _send_all(self) -> None:
        """The sender thread: write each job to the pipe; stop at None or a closed pipe."""
        while (job := self._outbox.get()) is not None:
            try:
                self._jobs.send_bytes(job)
            except OSError:  # the figure process is gone: wait() says so
                return

    def save(self, draw, path: Path) -> None:
        """Hand ``draw`` (a function of no arguments that returns the Figure: a bound method
        such as ``Result.plot``, or a ``functools.partial`` of a plotting function; pickled
        here, so an error in pickling it is raised here) and the PNG's path to the figure
        process, and return at once."""
        self._outbox.put(pickle.dumps((draw, str(path)), protocol=pickle.HIGHEST_PROTOCOL))
        self._pending += 1
        self._handed = True

    def wait(self) -> None:
        """Block until every figure handed over is written; re-raise what drawing one raised."""
        while self._pending:
            try:
                error = self._answers.recv()
            except EOFError:
                self._process.join()
                raise FigureProcessError(
                    f"the figure process ended (exit code {self._process.exitcode}) with "
                    f"{self._pending} figure(s) not drawn"
                ) from None
            self._pending -= 1
            if error is not None:
                self._pending = 0
                raise error

    def close(self) -> None:
        """End the figure process: close the jobs pipe (its end-of-file tells it to stop) and
        wait for it. If it is still drawing after CLOSE_S (the writer failed or was
        interrupted with figures pending), end it: its death also ends a send under way. One
        that was handed no figure (the command refused its options) is ended at once, without
        waiting for its import of matplotlib."""
        self._outbox.put(None)
        self._sender.join(timeout=CLOSE_S)
        if self._sender.is_alive() or not self._handed:
            self._process.terminate()
            self._sender.join()
        self._jobs.close()
        self._process.join(timeout=CLOSE_S)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join()
        self._answers.close()


def _die_with(parent: int) -> None:
    """Have the kernel end this process the moment ``parent`` ends (Linux's
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)``), so that no figure is written into the build
    folder of a process that is gone, after the next write has cleaned that folder up."""
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # it ended before the call
        os._exit(0)


_import_niceness: list[int] = []  # the importing thread's niceness, once it has set it


def _import_plots() -> None:
    """The importing thread: lower this thread's priority (module docstring), then import the
    plotting module (matplotlib) and the module of the results that the figures draw (what
    unpickling a job imports: pyarrow, about 0.03 s). A failure is left for the main thread's
    own import to raise."""
    _import_niceness.append(os.nice(FIGURE_NICENESS))
    for name in (".plots", "..sim.result"):  # matplotlib first: every figure needs it
        with contextlib.suppress(Exception):
            importlib.import_module(name, __package__)


def _serve(jobs, jobs_writer, answers, answers_reader, parent: int) -> None:
    """The figure process: end with ``parent``, close its ends of the pipes, import the
    plotting module on a thread of the lowest priority, then draw each job, at this process's
    own priority, until the jobs pipe ends (the parent closed it)."""
    _die_with(parent)
    jobs_writer.close()
    answers_reader.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C is the first process's to handle
    importer = threading.Thread(target=_import_plots, daemon=True)
    importer.start()
    save_figure = None
    while True:
        try:
            job = jobs.recv_bytes()
        except EOFError:
            return
        if save_figure is None:
            importer.join()
            from .plots import save_figure
        try:
            draw, path = pickle.loads(job)
            save_figure(draw(), Path(path))
            answers.send(None)
        except Exception as err:  # handed back to the writer, which raises it
            try:
                pickle.dumps(err)
            except Exception:
                err = RuntimeError(f"{type(err).__name__}: {err}")
            answers.send(err)


def can_fork() -> bool:
    """True where a figure process can be forked safely (Linux)."""
    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


@contextlib.contextmanager
def figure_writer(plot: bool = True):
    """A FigureProcess (where :func:`can_fork`; else DrawHere) for the block, closed after it;
    None without ``plot``."""
    if not plot:
        yield None
        return
    writer = FigureProcess() if can_fork() else DrawHere()
    try:
        yield writer
    finally:
        writer.close()
