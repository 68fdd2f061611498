"""Many independent runs at once: the one way emasim runs many simulations (a comparison's
controller sets, the ablation, the reproduction, studies), on Dask distributed.

:func:`dask_client` opens a client: to a running cluster (``scheduler``, e.g.
``tcp://host:8786``), or to a ``LocalCluster`` on this machine, of worker processes (studies:
the Python parts of a run, metrics and file writing, hold the GIL) or of threads in this
process (a comparison of a few runs: no process to start, and the compiled loop releases the GIL
while it integrates). :func:`map_runs` sends the jobs, hands each result to ``on_done`` as it
finishes, and returns them in order. Results do not depend on the schedule: numba's noise
generator is per thread and seeded at the start of each run.

A facility's runs are :class:`Job` records (a single-set scenario, its label, and tags naming
where its result belongs: the experiment, the stage, the clearance, the component; a study's
run id, sample and varied values), run by :func:`run_jobs` (a study's by
emasim.experiments.study.run_study); their results are read back by those names, never by
position in a tuple.
"""

import atexit
import concurrent.futures
import contextlib
import logging
import os
import socket
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import EmasimError, InputError, PhysicalLimitWarning
from ..sim.cosim import check_fmu_trust
from ..sim.engine import load_compiled as load_engine
from ..sim.result import Comparison, Result
from .runs import meta_of, run_scenario

if TYPE_CHECKING:
    from dask.distributed import Client

    from ..scenarios.schema import Scenario

log = logging.getLogger("emasim")  # the cluster's addresses, at debug level (emasim --verbose)
CONNECT_TIMEOUT_S = 10
HANDSHAKE_TIMEOUT_S = 5  # a Dask scheduler answers its identity in milliseconds


def workers_available() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def _close_clusters_quietly() -> None:
    """Dask's own exit hook (distributed.deploy.spec.close_clusters), its failure kept off the
    console: a cluster whose start a Ctrl-C or a SIGTERM cut short, its workers not yet
    started, fails to close there with a 29-line traceback (AssertionError: Status.init) after
    the command's one ``interrupted`` line. Its worker processes end with this process as
    always (Dask's workers are daemons)."""
    from distributed.deploy.spec import close_clusters

    with contextlib.suppress(Exception):
        close_clusters()


def _quiet_exit_hook() -> None:
    """Put :func:`_close_clusters_quietly` in the place of Dask's exit hook (once)."""
    from distributed.deploy.spec import close_clusters

    atexit.unregister(close_clusters)
    atexit.unregister(_close_clusters_quietly)
    atexit.register(_close_clusters_quietly)


@contextlib.contextmanager
def dask_client(
    scheduler: str | None = None,
    workers: int | None = None,
    processes: bool = True,
    log_file: tuple[Path, str] | None = None,
):
    """A ``dask.distributed.Client``: to the cluster at ``scheduler``, else to a LocalCluster of
    ``workers`` (default: one per core) single-threaded worker processes, or with
    ``processes=False`` one worker of that many threads in this process. A cluster it started
    is closed on exit; its worker processes show Python warnings as one line each, and with
    ``log_file`` = (path, logger) print everything there, and what that logger records, not on
    the terminal (emasim.experiments.worker_setup).
    """
    from dask.distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    # a run that fails reaches the caller as its exception (the command line's one line):
    # the worker's own report of it, "Compute Failed" with the traceback, is not printed
    logging.getLogger("distributed.worker").setLevel(logging.CRITICAL)
    if scheduler is not None:
        check_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, ValueError, TypeError) as err:
            raise InputError(f"--scheduler {scheduler}: cannot connect ({err})") from None
        with client:
            log.debug(f"Dask: scheduler {scheduler}, dashboard {client.dashboard_link}")
            yield client
        return
    n = workers or workers_available()
    _quiet_exit_hook()
    try:
        cluster = LocalCluster(
            processes=processes,
            n_workers=n if processes else 1,
            threads_per_worker=1 if processes else n,
            dashboard_address=":0",  # a free port: None still binds 8787, and warns if taken
            silence_logs=logging.ERROR,
        )
    except RuntimeError as err:  # a worker process that died while it started
        raise EmasimError(
            f"Dask could not start its worker processes ({err}); a worker's own message is "
            "above. From a script: the lines that start the runs belong under "
            '`if __name__ == "__main__":`, as every worker process runs the script again'
        ) from None
    with cluster, Client(cluster) as client:
        log.debug(
            f"Dask: a local cluster of {n} {'processes' if processes else 'threads'}, "
            f"scheduler {cluster.scheduler_address}, dashboard {client.dashboard_link}"
        )
        if processes:
            from .worker_setup import LogToFile, OneLineWarnings

            if log_file is not None:
                path, failures = log_file
                client.register_plugin(LogToFile(str(Path(path).absolute()), failures))
            client.register_plugin(OneLineWarnings())
        yield client


def check_scheduler(scheduler: str, timeout_s: float | None = None) -> None:
    """Refuse, in one line, an address that is not ``scheme://host:port``, or one where no
    Dask scheduler answers within ``timeout_s``: a real Dask handshake and an ``identity``
    request, whatever listens there (nothing, an HTTP server, a listener that sends garbage
    or nothing; ``timeout_s`` defaults to HANDSHAKE_TIMEOUT_S). Checked before a Client
    exists: a Client that failed to connect still tries to close at exit, and prints a
    traceback; one to a listener that never answers waits."""
    timeout_s = HANDSHAKE_TIMEOUT_S if timeout_s is None else timeout_s
    from distributed.comm import parse_address, parse_host_port

    try:
        scheme, location = parse_address(scheduler, strict=True)
        host, port = parse_host_port(location) if scheme == "tcp" else (None, None)
    except (ValueError, TypeError) as err:
        raise InputError(
            f"--scheduler {scheduler}: not an address like tcp://host:8786 ({err})"
        ) from None
    if scheme == "tcp":  # nothing listening: said at once (Dask's connect retries)
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
        except OSError as err:
            raise InputError(
                f"--scheduler {scheduler}: nothing answers there ({err.strerror or err})"
            ) from None
    import asyncio  # here, not at the top: it imports ssl, 12 to 25 ms of every emasim run

    with concurrent.futures.ThreadPoolExecutor(1) as pool:  # its own event loop
        reply = pool.submit(asyncio.run, _identity(scheduler, timeout_s)).result()
    if isinstance(reply, BaseException):
        why = (
            f"no answer within {timeout_s:g} s"
            if isinstance(reply, TimeoutError)
            else " ".join(str(reply).split())[:200] or type(reply).__name__
        )
        raise InputError(f"--scheduler {scheduler}: no Dask scheduler answers there ({why})")
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        shown = reply.get("type") if isinstance(reply, dict) else type(reply).__name__
        raise InputError(f"--scheduler {scheduler}: not a Dask scheduler (it says it is a {shown})")


async def _identity(address: str, timeout_s: float):
    """The ``identity`` reply of the Dask server at ``address``, or the exception that stopped
    the handshake or the request (a TimeoutError after ``timeout_s`` in all)."""
    import asyncio

    from distributed.comm import connect

    async def ask():
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        return await asyncio.wait_for(ask(), timeout_s)
    except (Exception, MemoryError) as err:  # garbage read as a frame length: MemoryError
        return err


def map_runs(
    function,
    jobs: list[tuple],
    client,
    on_done=None,
    first_alone: bool = False,
    grouped: bool = False,
):
    """``[function(*job) for job in jobs]``, run on ``client``'s workers; ``on_done(i, value)``
    is called in this process as each job ``i`` finishes. ``first_alone``: run the first job
    before the others, so that a cold numba cache is compiled once, not by every worker.
    ``grouped``: send several jobs in one task (:func:`task_groups`), for many short jobs: each
    task costs the scheduler and the client a few milliseconds of this process's CPU, which
    the workers lose when the cluster has no core to spare. Each task is released as it
    comes back: no finished task's value stays on a worker. The first failure cancels the
    tasks still waiting and is raised here."""
    from dask.distributed import as_completed

    values = [None] * len(jobs)
    index = {}

    def submit(group):
        future = client.submit(_run_group, function, [jobs[i] for i in group], pure=False)
        index[future.key] = group
        return future

    def collect(future):
        for i, value in zip(index.pop(future.key), future.result(), strict=True):
            values[i] = value
            if on_done is not None:
                on_done(i, value)

    start = 1 if first_alone and jobs else 0
    if start:
        collect(submit([0]))
    rest = range(start, len(jobs))
    groups = task_groups(rest, _slots(client)) if grouped else [[i] for i in rest]
    waiting = {submit(group) for group in groups}
    try:
        for future in as_completed(waiting):
            waiting.discard(future)
            collect(future)
            del future  # released: its value leaves the worker's memory
    except BaseException:
        client.cancel(list(waiting))
        raise
    return values


TASKS_PER_SLOT = 4  # a grouped task is at most 1/TASKS_PER_SLOT of a slot's remaining share
GROUP_MAX = 8  # jobs: the caller hears of a slot's progress at least every GROUP_MAX jobs


def task_groups(indices, slots: int) -> list[list[int]]:
    """``indices`` cut into tasks of shrinking size (guided self-scheduling): each takes
    ceil(remaining / (TASKS_PER_SLOT * slots)) of the jobs left, at most GROUP_MAX, so the
    first tasks are large (few tasks in all) and the last hold one job each (no slot waits
    long for another's last task)."""
    indices, groups = list(indices), []
    while indices:
        size = min(-(-len(indices) // (TASKS_PER_SLOT * max(slots, 1))), GROUP_MAX)
        groups.append(indices[:size])
        indices = indices[size:]
    return groups


def _slots(client) -> int:
    """How many tasks ``client``'s cluster runs at once (its workers' threads)."""
    return sum(w["nthreads"] for w in client.scheduler_info()["workers"].values())


def _run_group(function, jobs: list[tuple]) -> list:
    return [function(*job) for job in jobs]


@dataclass(frozen=True)
class Job:
    """One run of a many-run facility: a single-set ``scenario``, the ``label`` its Result
    carries, ``tags`` naming where the result belongs (module docstring), and whether a
    store keeps its ``trace`` (emasim.experiments.store; without, the run records only what
    its metrics read)."""

    scenario: "Scenario"
    label: str | None = None
    tags: Mapping[str, Any] = field(default_factory=dict)
    trace: bool = False


def run_jobs(jobs: list[Job], client=None, progress=None) -> list[Result]:
    """The Results of ``jobs``, in their order (:func:`run_all`)."""
    return run_all(
        [job.scenario for job in jobs],
        labels=[job.label for job in jobs],
        client=client,
        progress=progress,
    )


def run_all(scenarios, labels=None, trust_fmu: bool = False, client=None, progress=None) -> list:
    """Simulate scenarios (single runs) in parallel; return their Results in order.

    ``labels`` name the runs (one per scenario); ``trust_fmu`` as in ``run_scenario``;
    ``client`` a Dask client (default: threads in this process); ``progress`` is told the
    fraction of runs done after each run. The runs start longest simulated time first, so
    that the last to end is a short one and no core waits long for it."""
    scenarios = list(scenarios)
    labels = list(labels) if labels is not None else [None] * len(scenarios)
    order = sorted(range(len(scenarios)), key=lambda i: -scenarios[i].duration_s)
    jobs = [(scenarios[i], trust_fmu, labels[i]) for i in order]
    done = [0]

    def on_done(_, __):
        done[0] += 1
        if progress is not None:
            progress(done[0] / len(jobs))

    with contextlib.nullcontext(client) if client else dask_client(processes=False) as used:
        started = map_runs(_run, jobs, used, on_done)
    results = [None] * len(jobs)
    for i, result in zip(order, started, strict=True):
        results[i] = result
    return results


def _run(scenario, trust_fmu, label):
    return run_scenario(scenario, trust_fmu=trust_fmu, label=label)


def run(
    scenario: "Scenario | str | Path",
    progress: Callable[[float], None] | None = None,
    trust_fmu: bool = False,
    client: "Client | None" = None,
    *,
    label: str | None = None,
    controllers: Sequence[str] = (),
    settings: Sequence[str] = (),
) -> Comparison | Result:
    """Run a scenario as the command line does: every controller set of its comparison in
    parallel (a :class:`~emasim.sim.result.Comparison`), or its one run (a Result) when it
    compares nothing. ``scenario`` is a Scenario, or a shipped scenario's name or a TOML
    file's path, read with ``label``, ``controllers`` and ``settings`` as ``emasim run`` reads
    ``--label``, ``--controller`` and ``--set`` (:func:`emasim.scenarios.loader.load_scenario`:
    ``label`` picks one set). Both results have ``metrics``, ``plot()`` and ``save()``."""
    from ..arguments import client_or_none, flag, function_or_none
    from ..scenarios.loader import as_scenario

    trust_fmu = flag("emasim.run: trust_fmu", trust_fmu)
    function_or_none("emasim.run: progress", progress)
    client_or_none("emasim.run: client", client)
    scenario = as_scenario(scenario, label, controllers, settings)
    if scenario.compare:
        result = run_comparison(scenario, progress, trust_fmu, client)
    else:
        result = run_scenario(scenario, progress=progress, trust_fmu=trust_fmu)
    warn_limits(result)
    return result


def warn_limits(result: Comparison | Result) -> None:
    """Each line of each run's meta.json ``warnings`` (a stop touched, a physical limit
    passed) as a :class:`~emasim.errors.PhysicalLimitWarning`, prefixed with its controller
    set's label, so that a script or a notebook shows it and a user can filter or escalate it
    (the command line prints the same lines as its own ``warning:`` lines instead)."""
    records = getattr(result, "results", None) or {result.meta["label"]: result}
    for label, record in records.items():
        for line in record.meta.get("warnings", []):
            warnings.warn(f"{label}: {line}", PhysicalLimitWarning, stacklevel=3)


def load_compiled(variants) -> float:
    """Load or compile the engine and every law of the ``(label, scenario)`` variants; the
    seconds it took (emasim.sim.engine.load_compiled)."""
    start = time.perf_counter()
    load_engine()
    for _, variant in variants:
        if variant.solver.mechanism_fmu is None:  # a co-simulation's master compiles its own
            variant.setup().law_addresses()
    return time.perf_counter() - start


def run_comparison(
    scenario: "Scenario",
    progress: Callable[[float], None] | None = None,
    trust_fmu: bool = False,
    client: "Client | None" = None,
) -> Comparison:
    """Run every controller set of ``scenario.compare`` (or its one set) on the experiment,
    in parallel (:func:`run_all`); ``progress`` is told the fraction of runs done. The meta's
    ``simulation_wall_s`` is the wall time of all the runs side by side, ``runs_wall_sum_s``
    the sum of each run's own."""
    check_fmu_trust(scenario, trust_fmu)
    variants = scenario.variants()
    if progress is not None:
        progress(0.0)
    compile_s = load_compiled(variants)  # before the timer: the runs' time is the simulation's
    start = time.perf_counter()
    runs = run_all(
        (v for _, v in variants),
        labels=[label for label, _ in variants],
        trust_fmu=trust_fmu,
        client=client,
        progress=progress,
    )
    results = dict(zip((label for label, _ in variants), runs, strict=True))
    comparison = comparison_of(scenario, results, time.perf_counter() - start)
    comparison.meta["compile_s"] = compile_s
    return comparison


def comparison_of(scenario: "Scenario", results: dict[str, Result], wall_s: float) -> Comparison:
    """The Comparison of ``results``, label -> Result of each of ``scenario.variants()`` in
    their order. ``wall_s`` is the wall time the runs took side by side (the meta's
    ``simulation_wall_s``: not the sum of their times, which is ``runs_wall_sum_s``)."""
    meta = meta_of(scenario, wall_s)
    meta["runs_wall_sum_s"] = sum(r.meta["simulation_wall_s"] for r in results.values())
    meta["real_time_factor"] = wall_s / (scenario.duration_s * len(results))
    return Comparison(
        results, scenario=scenario.model_dump(mode="json", exclude_none=True), meta=meta
    )
