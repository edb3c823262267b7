"""Independent tasks on a pool of threads or a Dask scheduler, results handed back as they
finish.

Every long job whose work splits into independent pieces (probes of a bake, voxel chunks of
the sun bake, items of a study) runs through ``run_tasks``. A task is a pure function of a
large shared argument and a small per-task one, so where it runs does not change what it
returns, and callers merge results by task index: every scheduler gives the same output as
the plain loop. Schedulers (``--scheduler`` on the command line):

- ``"serial"``: one task after another in this process, each task's kernels on every core.
- ``None`` or ``"threads"``: a pool of threads in this process, one per core (the standard
  library's; Dask's threaded scheduler added a graph to optimise, 0.3 s of imports and, with
  many tasks, minutes). The shared argument is not copied; the Numba kernels release the GIL,
  so tasks overlap on all cores.
- ``"processes"``: a ``distributed.LocalCluster`` of one single-threaded worker process per
  core, started for the job and closed after it (``local_cluster``).
- any other string with a colon: the address of a running Dask scheduler
  (``tcp://host:8786``), reached with ``distributed.Client``; its workers need voxfield
  installed (the same version) and must see any file the job names.
- a ``distributed.Client``: used as it is (and left open).

With a ``distributed`` client the shared argument is scattered to the workers once and each
task receives only its own small argument. When several tasks run at once the cores are shared
out among them (``kernel_threads``; one each on a cluster worker), so tasks, not pixels, are
the parallel axis and the cores are not oversubscribed. Callers decide what ``None`` means:
``run_tasks`` takes it as ``"threads"``; the studies and the sun bake keep their plain loop.
A task that raises ends the job with its own error; one lost with its workers or the
scheduler ends it with ``TaskLostError`` (see ``_run_client``), never a result.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import signal
import threading
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

from voxfield.errors import VoxfieldError
from voxfield.parallel import use_threads_in_this_thread

LOCAL_SCHEDULERS = ("threads", "processes", "serial")
SCHEDULER_HELP = ("where independent pieces run: threads (a pool in this process), "
                  "processes (a local Dask cluster), serial (one after another), or a Dask "
                  "scheduler address like tcp://host:8786")


class SchedulerError(VoxfieldError):
    """The Dask scheduler could not be reached or started."""


class TaskLostError(SchedulerError):
    """A task ended without a result of its own: its workers died (taking the job's shared
    argument, which Dask cannot recompute, with them) or the scheduler went away."""


def check_scheduler(scheduler) -> None:
    """Refuse a scheduler that names nothing (before any file is written): threads, serial,
    processes, a ``host:port`` address or a ``distributed.Client`` are accepted."""
    if scheduler is None or not isinstance(scheduler, str):
        return
    if scheduler in LOCAL_SCHEDULERS or ":" in scheduler:
        return
    raise SchedulerError(f"scheduler must be threads, processes, serial or a Dask scheduler "
                         f"address like tcp://host:8786, got {scheduler!r}")


def run_tasks(
    task: Callable, shared, arguments: Sequence, emit: Callable[[int, object], None], *,
    scheduler=None, name: str = "task", resumes: bool = False,
) -> None:
    """Call ``task(shared, argument, kernel_threads)`` for every argument and
    ``emit(index, result)`` for each, in this thread, as soon as it finishes (completion order,
    not index order). ``task`` must be importable by workers (a module-level function) for
    process and cluster schedulers. A task lost on a Dask scheduler raises ``TaskLostError``,
    whose message says a rerun resumes where ``resumes`` (the caller keeps each result as it
    lands: a probe folder, a study's cache)."""
    check_scheduler(scheduler)
    if not arguments:
        return
    if scheduler == "serial":
        for index, argument in enumerate(arguments):
            emit(index, task(shared, argument, None))
    elif scheduler is None or scheduler == "threads":
        _run_threads(task, shared, arguments, emit)
    else:
        with scheduler_client(scheduler) as client:
            _run_client(client, task, shared, arguments, emit, name,
                        where=_cluster_name(scheduler, client), resumes=resumes)


#: Tasks in flight per thread: enough that a thread never waits for the next, few enough that
#: results are handed over (and released) as they land, not held until the job ends.
TASKS_AHEAD_PER_THREAD = 2


def _run_threads(task, shared, arguments, emit) -> None:
    """A pool of threads in this process, the shared argument read in place by every task.
    Results are handed over in this thread as they land, in task order when several land
    together; an error or Ctrl-C cancels the tasks not yet started and waits for those
    running (one per thread) before it is raised."""
    cores = os.cpu_count() or 1
    workers = max(1, min(len(arguments), cores))
    # The cores shared out: a few big tasks still use them all.
    kernel_threads = None if workers == 1 else max(1, cores // workers)
    upcoming = iter(enumerate(arguments))
    running: dict = {}
    with ThreadPoolExecutor(workers, thread_name_prefix="voxfield-task",
                            initializer=use_threads_in_this_thread,
                            initargs=(kernel_threads,)) as pool:
        try:
            while True:
                for index, argument in itertools.islice(
                        upcoming, TASKS_AHEAD_PER_THREAD * workers - len(running)):
                    running[pool.submit(task, shared, argument, kernel_threads)] = index
                if not running:
                    return
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in sorted(done, key=running.get):
                    emit(running.pop(future), future.result())
        except BaseException:
            for future in running:
                future.cancel()
            raise


def _run_client(client, task, shared, arguments, emit, name: str, *,
                where: str = "the Dask scheduler", resumes: bool = False) -> None:
    """Scatter the shared argument once, submit one task per argument, deliver results as
    they finish; a task that ends without a result raises ``TaskLostError`` (a task that
    raised raises its own error).

    No ``retries``: Dask already reruns a task whose worker died on another worker that holds
    the shared argument (``distributed.scheduler.allowed-failures`` times, then
    ``KilledWorker``), and ``retries`` reruns only tasks that raised, which are pure and would
    raise again. Once the last worker holding the shared argument is gone the scheduler cannot
    make it again (scattered data is not computed) and cancels the tasks; so does the client
    when the scheduler goes. ``as_completed(with_results=True)`` hands such a cancellation over
    as if it were the task's result, so it is caught here rather than reaching ``emit``."""
    # heavy: Dask loads only when a job runs on a scheduler
    from distributed import KilledWorker, as_completed

    # In a list, the shared argument is one object even when it is a tuple or a dict.
    try:
        [scattered] = client.scatter([shared], broadcast=True, hash=False)
    except TimeoutError as exc:  # no worker joined while Dask waited for one
        raise SchedulerError(f"{where} has no workers to run the job; start them with "
                             "`dask worker ADDRESS`") from exc
    except OSError as exc:  # the connection broke (Dask's CommClosedError)
        raise SchedulerError(f"{where} went away while the job's data was sent ({exc}); "
                             "rerun once it is back") from exc
    run = uuid.uuid4().hex[:12]  # keys unique per job on a shared cluster
    futures = [client.submit(task, scattered, argument, 1, key=f"voxfield-{name}-{run}-{i}",
                             pure=False) for i, argument in enumerate(arguments)]
    index_of = {f.key: i for i, f in enumerate(futures)}

    def lost(key, why: str) -> TaskLostError:
        which = (f"{name} task {index_of[key] + 1} of {len(futures)}" if key in index_of
                 else f"a {name} task")
        rerun = "rerun to resume (what finished is kept)" if resumes else "rerun to start again"
        return TaskLostError(f"{where} lost {which}: {why}; {rerun}")

    try:
        for future, result in as_completed(futures, with_results=True):
            if future.status != "finished":
                connection = (getattr(result, "reason", None) == "scheduler-connection-lost"
                              or client.status != "running")
                raise lost(future.key, "the connection to the scheduler broke" if connection
                           else "the workers holding the job's shared data went away (or the "
                           "scheduler did)")
            emit(index_of[future.key], result)
            future.release()
    except KilledWorker as exc:
        deaths = exc.allowed_failures + 1
        raise lost(exc.task, f"the workers running it died {deaths} time"
                   f"{'s' if deaths > 1 else ''} (out of memory?)") from None
    finally:
        for future in futures:
            future.release()
        scattered.release()


def _cluster_name(scheduler, client) -> str:
    """Where the tasks ran, for an error message."""
    if scheduler == "processes":
        return "the local Dask cluster"
    address = (scheduler if isinstance(scheduler, str)
               else getattr(getattr(client, "scheduler", None), "address", None))
    return f"the Dask scheduler at {address}" if address else "the Dask scheduler"


def local_cluster(workers: int, *, processes: bool, quiet: bool = False):
    """A ``distributed.LocalCluster`` of single-threaded workers (processes, or threads in this
    process) with no dashboard. Its scheduler serves its HTTP routes on a free loopback port:
    without a dashboard it still took Dask's default 8787, so two clusters at once (two jobs,
    or a job beside a user's own cluster) fought over it and the second warned. ``quiet``:
    Dask logs nothing, here or in the worker processes (its ``silence_logs``; warnings
    otherwise), for a job that reports its own failures."""
    # heavy: Dask loads only when a job runs on a scheduler
    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                        dashboard_address=None,
                        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                        silence_logs=logging.CRITICAL + 1 if quiet else logging.WARNING)


@contextlib.contextmanager
def _ctrl_c_held():
    """A Ctrl-C inside the block is held back and raised as KeyboardInterrupt at its end (in
    the main thread; elsewhere Python raises none), so starting a local cluster and its
    client, or closing them, is never left half done: a Ctrl-C there left a cluster nothing
    closed (Dask's own logs, and a coroutine never awaited, after ``voxfield:
    interrupted``). A second SIGINT does land during the first one's cleanup: a user presses
    Ctrl-C twice, and ``timeout -s INT`` signals both the command and its process group."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []

    def hold(signum, _frame) -> None:
        caught.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None
                      else previous)
    if caught:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _sigint_kept_from_new_threads():
    """SIGINT blocked in this thread inside the block, and so in every thread started there
    (a local cluster's event loop, the threads that spawn and respawn its workers) and in
    every process those start: a blocked signal stays blocked through fork and exec, and
    Python installs its Ctrl-C handler without unblocking it. On Ctrl-C the terminal
    signals the whole process group, and each worker process raised KeyboardInterrupt (a
    traceback apiece, some 70 lines after ``voxfield: interrupted``) while this process was
    shutting them down anyway. Python runs signal handlers in the main thread whichever
    thread a signal reaches, so this does not hold Ctrl-C back here (``_ctrl_c_held``)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:  # not POSIX
        yield
        return
    # The first process multiprocessing starts launches its resource tracker, and unblocks
    # SIGINT in the thread that launched it (its own child's guard): launched now, before.
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    before = mask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, before)


#: Seconds to wait for a scheduler's answer, the handshake included.
CONNECT_SECONDS = 10.0


def _connect(client_type, address: str):
    """``Client(address)``, or ``TimeoutError`` once ``CONNECT_SECONDS`` pass. Dask's own
    timeout covers opening the connection, not the handshake after it: a server that accepts
    and never answers (a web server on the dashboard's port 8787) kept the job waiting for
    ever, and one that answers something else made Dask read its reply as a message length
    (a 3 EiB allocation). The attempt runs in a daemon thread that is left behind if it
    hangs; any error from it means nothing at the address speaks Dask."""
    outcome: dict = {}

    def attempt() -> None:
        try:
            outcome["client"] = client_type(address, timeout=f"{CONNECT_SECONDS}s")
        except Exception as exc:  # noqa: BLE001 - whatever answered, it is not a scheduler
            outcome["error"] = exc

    thread = threading.Thread(target=attempt, name="voxfield-dask-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_SECONDS + 2.0)
    if thread.is_alive():
        raise TimeoutError(f"no answer in {CONNECT_SECONDS + 2.0:g} s; is it a scheduler's "
                           "address (port 8786, not the dashboard's 8787)?")
    error = outcome.get("error")
    if isinstance(error, (OSError, TimeoutError, ValueError)):
        raise error
    if error is not None:
        first_line = str(error).splitlines()[0] if str(error) else ""
        detail = type(error).__name__ + (f": {first_line}" if first_line else "")
        raise OSError(f"what answered is not a Dask scheduler ({detail})")
    return outcome["client"]


def _unusable_address(address: str) -> str | None:
    """Why this process cannot open a connection to ``address`` whatever listens there, or
    None. Dask fails such an attempt with a TypeError before anything answers, which
    ``_connect`` would have to report as a server that answered something else: a tls://
    address without certificates (voxfield takes none; Dask's configuration can hold them,
    and ``Client`` reads them there), a scheme whose support is not installed (ucx://)."""
    # heavy: Dask loads only when a job runs on a scheduler
    from distributed.comm import parse_address
    from distributed.comm.registry import get_backend
    from distributed.security import Security

    try:
        scheme, _ = parse_address(address)
        backend = get_backend(scheme)
    except (TypeError, ValueError):
        return None  # the attempt names what is wrong
    if scheme == "tls" and Security().get_connection_args("client")["ssl_context"] is None:
        return ("tls:// needs TLS certificates, and voxfield takes none itself: set them in "
                "Dask's configuration (distributed.comm.tls.ca-file, client.cert and "
                "client.key) or use a tcp:// address")
    try:
        backend.get_connector()
    except Exception as exc:  # noqa: BLE001 - whatever the reason, no connection can open
        detail = str(exc).splitlines()[0] if str(exc) else ""
        return (f"Dask cannot open {scheme}:// connections here ({type(exc).__name__}"
                + (f": {detail})" if detail else ")"))
    return None


class scheduler_client:
    """A context manager yielding a ``distributed.Client`` for ``scheduler``: a local
    process cluster for ``"processes"``, a connection for an address, or the given client.

    While it holds a client of its own, Dask's log records in this process are withheld
    (``_dask_logs_withheld``): what goes wrong reaches the caller as one error, where Dask
    also logged tracebacks (a lost scheduler's closed connection, the reconnect cancelled on
    close). A ``Client`` passed in is used as it is, its logging untouched."""

    def __init__(self, scheduler) -> None:
        self.scheduler = scheduler
        self.stack = contextlib.ExitStack()

    def __enter__(self):
        # heavy: Dask loads only when a job runs on a scheduler
        from distributed import Client

        s = self.scheduler
        if isinstance(s, Client):
            return s
        if not isinstance(s, str) or not (s == "processes" or ":" in s):
            raise SchedulerError(f"scheduler must be threads, processes, serial or a Dask "
                                 f"scheduler address like tcp://host:8786, got {s!r}")
        stack = contextlib.ExitStack()
        try:
            stack.enter_context(_dask_logs_withheld())
            if s == "processes":
                # Its workers never see Ctrl-C: this process closes them. A Ctrl-C while
                # they start lands once the cluster and its client are here to be closed.
                with _ctrl_c_held(), _sigint_kept_from_new_threads():
                    cluster = local_cluster(os.cpu_count() or 1, processes=True, quiet=True)
                    stack.callback(cluster.close)
                    client = Client(cluster)
                    stack.callback(client.close)
            else:
                why = _unusable_address(s)
                if why:
                    raise SchedulerError(f"cannot use the Dask scheduler {s!r}: {why}")
                client = _connect(Client, s)
                stack.callback(client.close)
        except BaseException as exc:
            self.stack = stack
            self.__exit__()
            if isinstance(exc, (OSError, TimeoutError, ValueError)):
                raise SchedulerError(
                    f"cannot reach the Dask scheduler {s!r} ({exc}); start one with "
                    "`dask scheduler` and workers with `dask worker ADDRESS`, or use "
                    "--scheduler threads|processes"
                ) from exc
            raise
        self.stack = stack
        return client

    def __exit__(self, *exc) -> None:
        with _ctrl_c_held():  # closed whole, a Ctrl-C or two notwithstanding
            self.stack.close()


@contextlib.contextmanager
def _dask_logs_withheld():
    """Dask's log records in this process reach no one inside the block. Dask sends them
    all through the stream handlers of its ``distributed`` logger, whose level it raises
    the same way to silence a local cluster (``distributed.utils.silence_logging_cmgr``)."""
    handlers = [h for h in logging.getLogger("distributed").handlers
                if isinstance(h, logging.StreamHandler)]
    levels = [h.level for h in handlers]
    for handler in handlers:
        handler.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for handler, level in zip(handlers, levels, strict=True):
            handler.setLevel(level)
