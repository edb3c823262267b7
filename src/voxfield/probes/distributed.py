"""Scale-out probe baking with Dask: probes bake independently, so each is one task.

``bake_probe`` is a pure function of (octree, position, options), so where a probe runs does
not change its maps or counts: every scheduler here gives arrays identical to the plain loop
of ``bake.bake_probes``. Schedulers (the ``scheduler`` argument, ``voxfield bake --scheduler``):

- ``None`` or ``"threads"``: Dask's local threaded scheduler in this process. The octree is
  shared, not copied; the Numba kernels release the GIL, so probes overlap on all cores.
- ``"processes"``: a ``distributed.LocalCluster`` of one single-threaded worker process per
  core, started for the bake and closed after it.
- ``"serial"``: no Dask; one probe after another in this process (each probe's kernels use
  every core instead).
- any other string: the address of a running Dask scheduler (``tcp://host:8786``), reached
  with ``distributed.Client``; its workers need voxfield installed.
- a ``distributed.Client``: used as it is (and left open).

With a ``distributed`` client the octree is scattered to the workers once (it is the large
argument) and each task receives only a probe position. Results come back to this process as
they complete and are handed to a callback in completion order — ``folder_bake`` writes each one at
once, which is what makes a killed bake resumable.

Inside a task the kernels run single-threaded when several probes run at once, so probes,
not pixels, are the parallel axis and the cores are not oversubscribed.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Sequence

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.probes.bake import bake_probe
from voxfield.probes.probe_set import ProbeSet
from voxfield.progress import progress_bar

LOCAL_SCHEDULERS = ("threads", "processes", "serial")


class SchedulerError(VoxfieldError):
    """The Dask scheduler could not be reached or started."""


def bake_probe_task(octree, position, options, kernel_threads: int | None = None):
    """One probe, as a Dask task runs it (module level so workers can import it)."""
    return bake_probe(octree, np.asarray(position, np.float64), options,
                      threads=kernel_threads)


def bake_each(
    octree, grid, options, indices: Sequence[int], on_result: Callable[[int, object], None], *,
    scheduler=None, progress: bool = False, baker: Callable | None = None,
) -> None:
    """Bake the probes ``indices`` of ``grid`` and call ``on_result(index, maps)`` for each, in
    this thread, as soon as it finishes (completion order, not index order).

    ``baker(octree, position, options, threads=...)`` replaces ``bake_probe`` (it must be
    picklable for process or cluster schedulers).
    """
    positions = np.asarray(grid.positions, np.float64).reshape(-1, 3)
    indices = [int(i) for i in indices]
    if not indices:
        return
    if not np.isfinite(positions[indices]).all():
        raise VoxfieldError("probe positions hold NaN or infinity")
    task = bake_probe_task if baker is None else baker
    with progress_bar(total=len(indices), desc="bake", unit="probe", enabled=progress) as bar:
        def emit(index: int, maps) -> None:
            on_result(index, maps)
            bar.update(1)

        if scheduler == "serial":
            for i in indices:
                emit(i, task(octree, positions[i], options))
        elif scheduler is None or scheduler == "threads":
            _run_threads(task, octree, positions, options, indices, emit)
        else:
            with _client(scheduler) as client:
                _run_client(client, task, octree, positions, options, indices, emit)


def bake_probes_dask(octree, grid, options, *, scheduler=None, progress: bool = False):
    """``bake.bake_probes`` through a Dask scheduler, in memory: the same ``ProbeSet``."""
    enabled = np.asarray(grid.enabled, bool).reshape(-1)
    probes: list = [None] * len(enabled)

    def keep(index: int, maps) -> None:
        probes[index] = maps

    bake_each(octree, grid, options, np.flatnonzero(enabled), keep, scheduler=scheduler,
              progress=progress)
    return ProbeSet.assemble(grid, options, probes,
                             octree.fingerprint(options.channel))


def _run_threads(task, octree, positions, options, indices, emit) -> None:
    """Dask's threaded scheduler; a post-task callback hands each result over as it lands
    (the local scheduler runs callbacks in the calling thread)."""
    # heavy: Dask loads only when a bake runs on a scheduler
    import dask
    from dask.callbacks import Callback

    workers = max(1, min(len(indices), os.cpu_count() or 1))
    kernel_threads = 1 if workers > 1 else None
    # A named, untraversed delayed: Dask neither hashes the octree's arrays nor walks its
    # fields; every task reads the same object.
    shared = dask.delayed(octree, name="voxfield-octree", traverse=False)
    bake = dask.delayed(task, pure=True)
    keys = {f"voxfield-probe-{i}": i for i in indices}
    tasks = [bake(shared, positions[i], options, kernel_threads, dask_key_name=key)
             for key, i in keys.items()]

    class Deliver(Callback):
        def _posttask(self, key, result, dsk, state, worker_id):
            if key in keys:
                emit(keys[key], result)

    with Deliver():
        dask.compute(*tasks, scheduler="threads", num_workers=workers)


def _run_client(client, task, octree, positions, options, indices, emit) -> None:
    """Scatter the octree once, submit one task per probe, deliver results as they finish."""

    # heavy: Dask loads only when a bake runs on a scheduler
    from distributed import as_completed

    shared = client.scatter(octree, broadcast=True, hash=False)
    run = uuid.uuid4().hex[:12]  # keys unique per bake on a shared cluster
    futures = [client.submit(task, shared, positions[i], options, 1,
                             key=f"voxfield-probe-{run}-{i}", pure=False) for i in indices]
    index_of = {f.key: i for f, i in zip(futures, indices, strict=True)}
    try:
        for future, maps in as_completed(futures, with_results=True):
            emit(index_of[future.key], maps)
            future.release()
    finally:
        for future in futures:
            future.release()
        shared.release()


def check_scheduler(scheduler) -> None:
    """Refuse a scheduler that names nothing (before any file is written): threads, serial,
    processes, a ``host:port`` address or a ``distributed.Client`` are accepted."""
    if scheduler is None or not isinstance(scheduler, str):
        return
    if scheduler in ("threads", "serial", "processes") or ":" in scheduler:
        return
    raise SchedulerError(f"scheduler must be threads, processes, serial or a Dask scheduler "
                         f"address like tcp://host:8786, got {scheduler!r}")


class _client:
    """A context manager yielding a ``distributed.Client`` for ``scheduler``: a local
    process cluster for ``"processes"``, a connection for an address, or the given client."""

    def __init__(self, scheduler) -> None:
        self.scheduler = scheduler
        self.owned: list = []

    def __enter__(self):
        # heavy: Dask loads only when a bake runs on a scheduler
        from distributed import Client, LocalCluster

        s = self.scheduler
        if isinstance(s, Client):
            return s
        if not isinstance(s, str) or not (s == "processes" or ":" in s):
            raise SchedulerError(f"scheduler must be threads, processes, serial or a Dask "
                                 f"scheduler address like tcp://host:8786, got {s!r}")
        try:
            if s == "processes":
                cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                                       processes=True, dashboard_address=None)
                self.owned.append(cluster)
                client = Client(cluster)
            else:
                client = Client(s, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            self.__exit__(None, None, None)
            raise SchedulerError(
                f"cannot reach the Dask scheduler {s!r} ({exc}); start one with "
                "`dask scheduler` and workers with `dask worker ADDRESS`, or use "
                "--scheduler threads|processes"
            ) from exc
        self.owned.insert(0, client)
        return client

    def __exit__(self, *exc) -> None:
        for thing in self.owned:
            thing.close()
        self.owned.clear()
