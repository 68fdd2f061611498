"""What emasim's own Dask worker processes set up when they start (a Dask worker plugin).

A worker process does not run the command line's set-up, so a Python warning raised in a run
there (a controller's design check, say) would reach the terminal as Python's raw two-line
warning, with its source path and line. :class:`OneLineWarnings` makes it the command line's
one line, ``warning: <message>``, on the worker's stderr. Python's default filter still shows
each distinct warning once per process. :func:`emasim.experiments.batch.dask_client` registers
it on the LocalClusters it starts, never on a cluster it only connects to, and so
:class:`LogToFile` too, for a study: its workers' output goes to the study's log file.
"""

import logging
import os
import sys
import warnings

from distributed import WorkerPlugin


def one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` as one line on stderr: the message, without the source."""
    print(f"warning: {message}", file=sys.stderr, flush=True)


class OneLineWarnings(WorkerPlugin):
    """Show every Python warning in the worker process as one ``warning:`` line."""

    name = "emasim-one-line-warnings"

    def setup(self, worker) -> None:
        warnings.showwarning = one_line_warning


class LogToFile(WorkerPlugin):
    """Send everything the worker process prints (its stdout and stderr, so Python's and
    Dask's messages and a C library's alike) to the end of the file ``path``, and what the
    logger ``failures`` records (a failed study run's traceback) with it: a study's worker
    processes never write to the user's terminal."""

    name = "emasim-log-to-file"

    def __init__(self, path: str, failures: str):
        self.path = str(path)
        self.failures = failures

    def setup(self, worker) -> None:
        sys.stdout.flush()
        sys.stderr.flush()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.close(fd)
        failures = logging.getLogger(self.failures)
        failures.handlers[:] = [logging.StreamHandler(sys.stderr)]
        failures.setLevel(logging.ERROR)
        failures.propagate = False
