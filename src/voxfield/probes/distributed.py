"""Scale-out probe baking: probes bake independently, so each is one task (``scaleout``).

``bake_probe`` is a pure function of (octree, position, options), so where a probe runs does
not change its maps or counts: every scheduler of ``voxfield.scaleout`` gives arrays
identical to the plain loop of ``bake.bake_probes``. The octree (with the options) is the
shared argument, scattered to a cluster's workers once; each task receives a probe position.
Results are handed to a callback in completion order — ``folder_bake`` writes each one at
once, which is what makes a killed bake resumable.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.probes.bake import bake_probe
from voxfield.probes.probe_set import ProbeSet
from voxfield.progress import progress_bar
from voxfield.scaleout import SchedulerError, check_scheduler, run_tasks

__all__ = ["SchedulerError", "bake_each", "bake_probes_dask", "check_scheduler"]


def bake_probe_task(shared, position, kernel_threads: int | None = None):
    """One probe, as a task runs it: ``shared`` is (octree, options, baker)."""
    octree, options, baker = shared
    return baker(octree, np.asarray(position, np.float64), options, threads=kernel_threads)


def bake_each(
    octree, grid, options, indices: Sequence[int], on_result: Callable[[int, object], None], *,
    scheduler=None, progress: bool = False, baker: Callable | None = None,
    resumes: bool = False,
) -> None:
    """Bake the probes ``indices`` of ``grid`` and call ``on_result(index, maps)`` for each, in
    this thread, as soon as it finishes (completion order, not index order).

    ``baker(octree, position, options, threads=...)`` replaces ``bake_probe`` (it must be
    picklable for process or cluster schedulers). ``resumes``: ``on_result`` keeps each
    probe, so a lost task's error says a rerun resumes (``scaleout.run_tasks``).
    """
    positions = np.asarray(grid.positions, np.float64).reshape(-1, 3)
    indices = [int(i) for i in indices]
    if not indices:
        return
    if not np.isfinite(positions[indices]).all():
        raise VoxfieldError("probe positions hold NaN or infinity")
    shared = (octree, options, bake_probe if baker is None else baker)
    with progress_bar(total=len(indices), desc="bake", unit="probe", enabled=progress) as bar:
        def emit(task_index: int, maps) -> None:
            on_result(indices[task_index], maps)
            bar.update(1)

        run_tasks(bake_probe_task, shared, [positions[i] for i in indices], emit,
                  scheduler=scheduler, name="probe", resumes=resumes)


def bake_probes_dask(octree, grid, options, *, scheduler=None, progress: bool = False):
    """``bake.bake_probes`` through a scheduler of ``scaleout``, in memory: the same
    ``ProbeSet``."""
    enabled = np.asarray(grid.enabled, bool).reshape(-1)
    probes: list = [None] * len(enabled)

    def keep(index: int, maps) -> None:
        probes[index] = maps

    bake_each(octree, grid, options, np.flatnonzero(enabled), keep, scheduler=scheduler,
              progress=progress)
    return ProbeSet.assemble(grid, options, probes,
                             octree.fingerprint(options.channel))
