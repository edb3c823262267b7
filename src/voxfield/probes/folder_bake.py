"""The resumable bake: a probe grid baked into a probe-set folder (``probes.probe_folder``),
each probe's file written as soon as it is baked, so a stopped bake continues where it
stopped and a finished one is never baked again."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from voxfield.checks import path_value, spoken_list
from voxfield.folder_lock import FolderLock
from voxfield.json_output import to_json
from voxfield.memory import check_fits_in_memory
from voxfield.probes.bake import check_bake_options
from voxfield.probes.distributed import bake_each, check_scheduler
from voxfield.probes.probe_folder import (
    HEADER_NAME,
    ProbeSetMismatchError,
    ProbeStorageError,
    clear_folder,
    differences,
    identity,
    new_header,
    open_probe_set,
    read_header,
    reconcile_probes,
    verified_probes,
    write_atlases,
    write_header,
    write_probe,
)

#: Seconds between header rewrites while baking: a probe whose record missed the last
#: rewrite is simply baked again on resume, so this bounds lost work, not correctness.
HEADER_FLUSH_SECONDS = 1.0
#: Peak bytes a texel costs when a finished bake assembles its probe set and writes the
#: atlases from it: 45.5 measured (`voxfield bake builtin:sphere --resolution 64`, peak RSS
#: of 4,000 probes less that of 1,000).
FINISH_BYTES_PER_TEXEL = 48


def check_finish_memory(count: int, resolution: int) -> None:
    """Refuse a bake whose finished set this machine cannot assemble, before any probe is
    baked: a 64×64×64 grid of 64² maps baked for over an hour, and would then have needed
    about 48 GiB to write its atlases."""
    check_fits_in_memory(
        count * resolution * resolution * FINISH_BYTES_PER_TEXEL,
        f"{count:,} probes of {resolution}² texels: assembling the finished set and its "
        "atlases", "bake fewer probes or a lower resolution")


def checked_folder_path(out) -> Path:
    """``out`` as a probe folder's path, refused where a file stands there or where a
    folder holds other files (``check_bake_folder``)."""
    folder = path_value(out, "a probe-set folder")
    if folder.exists() and not folder.is_dir():
        raise ProbeStorageError(f"{folder} exists and is not a folder; pick another --out")
    check_bake_folder(folder)
    return folder


def check_bake_folder(folder: Path) -> None:
    """Refuse a folder that holds files but no probe-set header: a study's results, or a
    user's own files, which a bake would mix its files into (or, with ``--fresh``, delete
    those named like its own). A bake goes into a new or empty folder, or a probe set."""
    if not folder.is_dir() or (folder / HEADER_NAME).exists():
        return
    # Dot files are skipped: a write stopped part-way leaves its hidden temporary file.
    others = sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))
    if others:
        shown = ", ".join(others[:3]) + (f" and {len(others) - 3} more" if len(others) > 3
                                         else "")
        raise ProbeStorageError(
            f"{folder} holds {shown} but no {HEADER_NAME}: it is not a probe set; give the "
            "bake a new or empty folder as --out")


def bake_to_folder(octree, grid, options, out, *, scheduler=None, fresh: bool = False,
                   progress: bool = False, source: dict | None = None, relocation=None,
                   baker=None):
    """Bake ``grid`` into the probe-set folder ``out`` and return the finished ``ProbeSet``.

    The header is written first; each probe's file is written (atomically) as soon as it is
    baked, and the header records it. Re-running on a folder baked from the same scene,
    grid and options bakes only the probes that are missing or fail their checksum, so a
    killed bake continues where it stopped. A folder from another scene, grid or options is
    refused with ``ProbeSetMismatchError`` unless ``fresh`` (start over, deleting its
    probe files). ``scheduler`` picks where probes run (see ``voxfield.probes.distributed``);
    ``baker`` replaces ``bake_probe`` (tests count calls with it).

    ``source`` (how to reopen the scene, e.g. the CLI's scene argument and options) and
    ``relocation`` (a ``RelocationReport``) are recorded for ``voxfield probes show``; they
    are not part of what must match on resume. ``last_run`` in the header says how many
    probes this run baked and reused, on which scheduler, in how many wall-clock seconds.
    """

    started = time.perf_counter()
    check_scheduler(scheduler)
    # Before the header is written: a refused --lod left a header that refused the next,
    # corrected run ("holds probes baked with other bake options (lod)") without --fresh.
    check_bake_options(octree, options)
    check_finish_memory(grid.count, options.resolution)
    folder = checked_folder_path(out)
    # One bake writes a folder at a time: another one's --fresh or header would undo it.
    with FolderLock(folder, "probe bake") as claim:
        claim.take()  # a folder that exists is claimed before it is read or cleared
        channel = getattr(options, "channel", "albedo")
        header = new_header(grid=grid, options=options,
                            fingerprint=octree.fingerprint(channel), channel=channel,
                            scene_name=getattr(octree, "name", "scene"))
        if source is not None:
            header["scene"]["source"] = to_json(source, finite=False)
        if relocation is not None:
            report = relocation.to_dict() if hasattr(relocation, "to_dict") else dict(relocation)
            report.pop("offsets", None)  # the grid holds them
            header["relocation"] = to_json(report, finite=False)
        if fresh:
            clear_folder(folder)
        elif (folder / HEADER_NAME).exists():
            old = read_header(folder)
            differs = differences(identity(old), identity(header))
            if differs:
                raise ProbeSetMismatchError(
                    f"{folder} holds probes baked {spoken_list(differs)}; use another --out, or "
                    "--fresh to discard them"
                )
            header["probes"] = old["probes"]
        claim.take(make=True)  # a new folder is claimed as it is made

        positions = grid.positions
        reconcile_probes(folder, header, positions)
        done = verified_probes(folder, header, positions)
        header["probes"] = {str(i): header["probes"][str(i)] for i in sorted(done)}
        enabled = np.asarray(grid.enabled, bool).reshape(-1)
        todo = [i for i in range(grid.count) if enabled[i] and i not in done]
        header["complete"] = False
        header.pop("atlas", None)
        header["last_run"] = {"baked": 0, "reused": len(done),  # counted up as probes are stored
                              "scheduler": _scheduler_name(scheduler)}
        write_header(folder, header)

        last_flush = time.monotonic()

        def store(index: int, maps) -> None:
            nonlocal last_flush
            header["probes"][str(index)] = write_probe(folder, index, maps, positions[index])
            # what the run did so far, not what it set out to do: a killed run's header says so
            header["last_run"]["baked"] = len(header["probes"]) - len(done)
            if time.monotonic() - last_flush >= HEADER_FLUSH_SECONDS:
                write_header(folder, header)
                last_flush = time.monotonic()

        try:
            bake_each(octree, grid, options, todo, store, scheduler=scheduler, progress=progress,
                      baker=baker, resumes=True)
        finally:
            # Whatever finished before an error or Ctrl-C is kept for the next run.
            write_header(folder, header)

        probe_set = open_probe_set(folder)
        header["atlas"] = write_atlases(folder, probe_set.radiance, probe_set.distance,
                                        probe_set.normal)
        header["complete"] = True
        header["last_run"]["wall_seconds"] = time.perf_counter() - started
        write_header(folder, header)
        return probe_set


def _scheduler_name(scheduler) -> str:
    if scheduler is None or isinstance(scheduler, str):
        return scheduler or "threads"
    address = getattr(getattr(scheduler, "scheduler", None), "address", None)
    return str(address or type(scheduler).__name__)
