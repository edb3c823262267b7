"""The sun lighting bake: one lit colour channel per sun, ready for every renderer.

For each voxel and sun, ``lit = albedo × (irradiance × direct + sky × sky_visibility)``
(``voxfield.kernels.sun_bake`` defines the two visibility terms). Voxels without an exposed
face are never seen at LOD 0 and get black; coarse levels average the lit voxels weighted by
how much sky each one sees (``voxfield.svo.channels``), so those hidden voxels, and faces
turned to the ground, do not darken the LOD images.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numba
import numpy as np

from voxfield.checks import integer_in, seed_value
from voxfield.errors import VoxfieldError
from voxfield.kernels.colour import FLOAT32, RGB9E5, SRGB8, storage_of
from voxfield.kernels.sun_bake import bake_sun_visibility, lit_colours
from voxfield.lighting.sun import SunLight
from voxfield.parallel import thread_count
from voxfield.progress import progress_bar
from voxfield.scaleout import run_tasks
from voxfield.svo.channels import (
    check_channel_storage,
    new_channel_block,
    with_channel_block,
)
from voxfield.svo.column_tops import no_column_tops, octree_column_tops, tops_ahead
from voxfield.svo.horizons import horizon_slopes
from voxfield.svo.lod_colours import exposed_faces
from voxfield.svo.octree import Octree

__all__ = ["BakeReport", "SunVisibility", "bake_sun_lighting", "sun_visibility"]

#: Surface voxels per kernel call: small enough for a lively progress bar (a call takes about
#: 0.2 s on a 2048² desert), large enough that the calls' overhead stays small (2^15 cost
#: the desert's kernel 4 % more, in 274 calls instead of 68).
CHUNK_VOXELS = 1 << 17
#: The rays a voxel casts that ``CHUNK_VOXELS`` is sized for (16 sky rays, 4 shadow rays
#: for each of 4 suns); a bake casting more a voxel takes fewer voxels a call, down to
#: ``MIN_CHUNK_VOXELS``, so that Ctrl-C (heard between calls) is still heard within a second.
CHUNK_RAYS_PER_VOXEL = 32
MIN_CHUNK_VOXELS = 1 << 10
MAX_RAYS = 1024


def chunk_voxels(sky_rays: int, shadow_rays: int, suns: int) -> int:
    """Surface voxels a kernel call: ``CHUNK_VOXELS`` at the default rays, fewer in
    proportion to more rays a voxel (whole multiples of ``MIN_CHUNK_VOXELS``)."""
    rays = max(1, sky_rays + shadow_rays * suns)
    chunk = CHUNK_VOXELS * CHUNK_RAYS_PER_VOXEL // rays
    return int(min(CHUNK_VOXELS, max(MIN_CHUNK_VOXELS, chunk // MIN_CHUNK_VOXELS
                                     * MIN_CHUNK_VOXELS)))


@dataclass
class SunVisibility:
    """Per-voxel visibility terms (one row per voxel in leaf order; zero where buried),
    float32 like the channels they make (a 2048² terrain has over 20M voxels)."""

    direct: np.ndarray  # (suns, voxels): Σ w·cos·V / Σ w
    sky: np.ndarray  # (voxels,): sky visibility
    weight: np.ndarray  # (voxels,): how much sky the voxel's faces see
    surface: np.ndarray  # (voxels,) bool: has an exposed face

    @property
    def seen(self) -> np.ndarray:
        """Voxels with a face that sees the sky: the ones the coarse levels average."""
        return self.weight > 0.0


@dataclass
class BakeReport:
    """What a bake cost; ``rays`` and ``traversal_steps`` are the hardware-independent part
    (the steps count column-top cells as well as octree nodes, ``kernels.sun_bake``)."""

    voxels: int
    surface_voxels: int
    suns: list[str]
    sky_rays_per_voxel: int
    shadow_rays_per_face: int
    sky_rays: int
    shadow_rays: int
    traversal_steps: int
    seconds: float
    threads: int
    #: Per sun, the fraction of the voxels that see the sky which get direct sun.
    sunlit_fraction: dict[str, float] = field(default_factory=dict)

    @property
    def rays(self) -> int:
        return self.sky_rays + self.shadow_rays

    def as_dict(self) -> dict:
        return {**asdict(self), "rays": self.rays}

    def summary(self) -> str:
        rate = self.rays / self.seconds / 1e6 if self.seconds > 0 else float("inf")
        lit = ", ".join(f"{k} {v:.0%}" for k, v in self.sunlit_fraction.items())
        return (
            f"sun bake: {len(self.suns)} sun{'' if len(self.suns) == 1 else 's'} over "
            f"{self.surface_voxels:,} surface voxels "
            f"(of {self.voxels:,}); {self.sky_rays:,} sky + {self.shadow_rays:,} shadow rays, "
            f"{self.traversal_steps:,} steps ({self.traversal_steps / max(self.rays, 1):.1f}"
            f"/ray), {self.seconds:.2f} s on {self.threads} threads ({rate:.2f} Mrays/s); "
            f"in sun: {lit}"
        )


def _check_suns(suns: Sequence[SunLight]) -> list[SunLight]:
    suns = list(suns)
    if not suns:
        raise VoxfieldError("no sun to bake; give at least one time of day")
    for sun in suns:
        if not isinstance(sun, SunLight):
            raise VoxfieldError(f"expected SunLight objects, got {type(sun).__name__}")
    names = [s.name for s in suns]
    if len(set(names)) != len(names):
        raise VoxfieldError(f"two suns share a channel name: {names}")
    return suns


def sun_visibility(
    octree: Octree, sun_dirs: np.ndarray, *, sky_rays: int = 16, shadow_rays: int = 4,
    seed: int = 0, threads: int | None = None, progress: bool = False, scheduler=None,
    columns: bool = True,
) -> tuple[SunVisibility, dict]:
    """Trace the visibility terms of every surface voxel for unit directions ``sun_dirs``
    (suns×3, towards the sun); returns them and the cost counters.

    The rays rise, so they first walk the column-top pyramid (``svo.column_tops``), which
    settles most of them, and only the rest go through the octree; ``columns=False`` sends
    every ray through the octree, with the same visibility (for comparisons and tests). A
    sky ray that rises above its start column's horizon slope (``svo.horizons``) is clear
    without either, and so are a face's shadow rays when the face's rear corner is.

    Chunks of ``chunk_voxels`` surface voxels are independent (each voxel's rays are hashed
    from its index and ``seed``): without a ``scheduler`` they run one after another here,
    each on every core; with one (``voxfield.scaleout``) they run as tasks, the octree's
    descriptors shared, and merge by voxel index, so the result is bit-identical."""
    sky_rays = integer_in(sky_rays, "sky rays per voxel", 0, MAX_RAYS)
    shadow_rays = integer_in(shadow_rays, "shadow rays per face", 1, MAX_RAYS)
    seed = seed_value(seed)
    dirs = np.asarray(sun_dirs, np.float64)
    if dirs.ndim != 2 or dirs.shape[1] != 3 or not np.all(np.isfinite(dirs)):
        raise VoxfieldError(f"sun directions must be finite suns×3 vectors, got {dirs.shape}")
    if not np.allclose(np.linalg.norm(dirs, axis=1), 1.0):
        raise VoxfieldError("sun directions must be unit vectors")
    faces = exposed_faces(octree)
    surface = np.flatnonzero(faces)
    leaves = octree.node_coords(octree.depth, np.int32)
    n = octree.voxel_count
    vis = SunVisibility(
        direct=np.zeros((len(dirs), n), np.float32), sky=np.zeros(n, np.float32),
        weight=np.zeros(n, np.float32), surface=faces != 0,
    )
    counters = {"sky_rays": 0, "shadow_rays": 0, "traversal_steps": 0}
    inner, depth = octree.inner_nodes, octree.depth
    y_top = float(octree.voxel_bounds[1][1])
    tops = octree_column_tops(octree, leaves) if columns else no_column_tops()
    sun_tops = _tops_ahead_per_sun(tops, dirs)
    horizons = _horizon_slopes(tops)

    # Everything large is shared (scattered to a cluster once); a chunk is a range of it.
    shared = {"inner": inner, "depth": depth, "y_top": y_top, "columns": tops,
              "sun_tops": sun_tops, "horizons": horizons, "dirs": dirs,
              "sky_rays": sky_rays, "shadow_rays": shadow_rays, "seed": int(seed),
              "leaves": leaves, "faces": faces, "surface": surface}
    chunk = chunk_voxels(sky_rays, shadow_rays, len(dirs))
    ranges = [(first, min(len(surface), first + chunk))
              for first in range(0, len(surface), chunk)]
    options = {"total": len(surface), "desc": "sun bake", "unit": "voxel", "enabled": progress}
    visibility_task(shared, (0, 0))  # loads (or compiles) the kernel outside the timed region
    start = time.perf_counter()
    with progress_bar(**options) as bar:
        def count(chunk: tuple[int, int], sky_cast: int, shadow_cast: int, steps: int) -> None:
            counters["sky_rays"] += sky_cast
            counters["shadow_rays"] += shadow_cast
            counters["traversal_steps"] += steps
            bar.update(chunk[1] - chunk[0])

        if scheduler is not None and scheduler != "serial":
            # Tasks return their chunk's rows, scattered here by voxel index (a fancy-indexed
            # copy per chunk; about a second over a 2048² terrain, which the local path,
            # writing in place, does not pay).
            def merge(index: int, result) -> None:
                ids = surface[slice(*ranges[index])]
                direct, sky, weight, *counts = result
                vis.direct[:, ids] = direct
                vis.sky[ids] = sky
                vis.weight[ids] = weight
                count(ranges[index], *counts)

            run_tasks(visibility_task, shared, ranges, merge, scheduler=scheduler,
                      name="sun-chunk")
        else:  # one chunk after another, each on every core (or ``threads``), in place
            for chunk in ranges:
                count(chunk, *visibility_task(shared, chunk, threads, into=vis))
    counters["seconds"] = time.perf_counter() - start
    return vis, counters


def _tops_ahead_per_sun(columns, dirs: np.ndarray) -> np.ndarray:
    """``(suns, cells)``: per sun, the pyramid's tops ahead in its direction
    (``svo.column_tops.tops_ahead``), with which a face's shadow rays are settled together;
    ``(suns, 0)`` without a pyramid."""
    if columns.level_width.shape[0] == 0 or len(dirs) == 0:
        return np.zeros((len(dirs), 0), np.int32)
    out = np.empty((len(dirs), columns.tops.shape[0]), np.int32)
    done = {}  # steps -> the row that has them
    for k, d in enumerate(dirs):
        steps = (1 if d[0] >= 0.0 else -1, 1 if d[2] >= 0.0 else -1)
        if steps in done:
            out[k] = out[done[steps]]
        else:
            tops_ahead(columns, *steps, out=out[k])
            done[steps] = k
    return out


def _horizon_slopes(columns) -> np.ndarray:
    """The pyramid's horizon slopes (``svo.horizons``), with which most sky rays and many
    faces' shadow rays are settled without a walk: one place the bake builds them, so a test
    can switch them off."""
    return horizon_slopes(columns)


def visibility_task(shared: dict, chunk: tuple[int, int], kernel_threads: int | None = None,
                    into: SunVisibility | None = None):
    """One chunk of ``sun_visibility`` as a scheduler runs it: surface voxels
    ``chunk[0]..chunk[1]-1`` against the shared descriptors, voxels and bake settings;
    returns their visibility terms (float32, in chunk order) and summed counters. With
    ``into``, the kernel writes the terms straight into its rows of every voxel (no copy of
    them; on a 2048² terrain the copies and the scatter after took 1.4 s) and only the
    counters come back."""
    ids = shared["surface"][chunk[0]:chunk[1]]
    corners, faces = shared["leaves"][ids], shared["faces"][ids]
    m = len(ids)
    dirs = shared["dirs"]
    if into is None:
        out = (np.zeros((len(dirs), m), np.float32), np.zeros(m, np.float32),
               np.zeros(m, np.float32))
        rows = np.arange(m)
    else:
        out = (into.direct, into.sky, into.weight)
        rows = ids
    sky_cast, shadow_cast, steps = (np.zeros(m, np.int64) for _ in range(3))
    with thread_count(kernel_threads):
        bake_sun_visibility(
            np.ascontiguousarray(corners, np.int64), ids, faces, dirs, shared["sky_rays"],
            shared["shadow_rays"], shared["seed"], shared["inner"], shared["depth"],
            shared["y_top"], shared["columns"], shared["sun_tops"], shared["horizons"], rows,
            *out, sky_cast, shadow_cast, steps, numba.get_num_threads(),
        )
    counts = (int(sky_cast.sum()), int(shadow_cast.sum()), int(steps.sum()))
    return counts if into is not None else (*out, *counts)


def bake_sun_lighting(
    octree: Octree, suns: Sequence[SunLight], *, sky_rays: int = 16, shadow_rays: int = 4,
    seed: int = 0, threads: int | None = None, progress: bool = False, scheduler=None,
    storage: str | None = None,
) -> tuple[Octree, BakeReport]:
    """A new octree with one lit channel per sun, named after the sun, and the bake's cost.

    ``sky_rays`` cosine-weighted rays per surface voxel estimate sky visibility (0: no sky
    light, black shadows as in the EA thesis's data); ``shadow_rays`` stratified rays per
    sun-facing face estimate sun visibility (1: one ray from the face centre). Results are
    bit-identical for any ``threads`` or ``scheduler`` (``sun_visibility``) and depend only
    on the inputs and ``seed``.

    ``storage`` keeps the channels as ``rgb9e5`` (4 bytes a node, ``kernels.colour``) or
    ``float32`` (12); by default they are as compact as the albedo: RGB9E5 beside 8-bit
    sRGB, float32 beside float32. Coarse levels are averaged from the float32 voxels either
    way.
    """
    suns = _check_suns(suns)
    _note_dark_suns(suns)
    if storage is None:
        storage = RGB9E5 if storage_of(octree.attributes["color"]) == SRGB8 else FLOAT32
    check_channel_storage(storage)
    dirs = np.array([s.direction() for s in suns])
    vis, cost = sun_visibility(
        octree, dirs, sky_rays=sky_rays, shadow_rays=shadow_rays, seed=seed,
        threads=threads, progress=progress, scheduler=scheduler,
    )
    lit = _with_lit_channels(octree, suns, vis, storage)
    surface_count = int(vis.surface.sum())
    seen = vis.seen
    seen_count = max(int(seen.sum()), 1)
    report = BakeReport(
        voxels=octree.voxel_count,
        surface_voxels=surface_count,
        suns=[s.name for s in suns],
        sky_rays_per_voxel=int(sky_rays),
        shadow_rays_per_face=int(shadow_rays),
        sky_rays=cost["sky_rays"],
        shadow_rays=cost["shadow_rays"],
        traversal_steps=cost["traversal_steps"],
        seconds=cost["seconds"],
        threads=_threads_used(threads),
        sunlit_fraction={
            s.name: float(np.count_nonzero((vis.direct[k] > 0) & seen) / seen_count)
            for k, s in enumerate(suns)
        },
    )
    return lit, report


def _with_lit_channels(octree: Octree, suns: list[SunLight], vis: SunVisibility,
                       storage: str) -> Octree:
    """The octree with each sun's lit channel, one sun at a time: its voxels are lit
    straight into a float32 channel's voxel rows, its coarse levels averaged there, and the
    channel kept, packed as ``storage`` if that is RGB9E5. Packed channels reuse one float32
    channel's room (250 MB on a 2048² terrain instead of a gigabyte for four suns)."""
    voxels = octree.level_slice(octree.depth)
    albedo = octree.attributes["color"][voxels]
    lit = octree
    block = None
    for k, sun in enumerate(suns):
        if block is None or storage == FLOAT32:  # a float32 channel keeps its rows
            block = new_channel_block(octree, 1)
        lit_colours(albedo, vis.direct[k:k + 1], vis.sky,
                    np.array([sun.irradiance], np.float64), np.array([sun.sky], np.float64),
                    block[:, voxels])
        _keep_in_display_range(sun, block[0, voxels])
        lit = with_channel_block(lit, [sun.name], block, vis.weight, storage)
    return lit


def _note_dark_suns(suns: list[SunLight]) -> None:
    """A note, before the bake, for each sun that gives no light at all (below the
    horizon): its channel will be black."""
    for sun in suns:
        if not (any(sun.irradiance) or any(sun.sky)):
            why = (f"elevation {sun.elevation_deg:g}°, below the horizon"
                   if sun.elevation_deg <= 0 else "sun and sky colours of zero")
            warnings.warn(f"sun {sun.name!r} gives no light ({why}): its channel is black",
                          stacklevel=3)


def _keep_in_display_range(sun: SunLight, rows: np.ndarray) -> None:
    """Clamp a sun's lit voxel colours to 1, with a note where any was brighter: the
    presets keep open ground near 1, but a sun set high over bright albedo lit past it, and
    every measuring command then failed after its renders (the metrics take [0, 1])."""
    peak = float(rows.max()) if rows.size else 0.0
    if peak > 1.0:
        over = int(np.count_nonzero((rows > 1.0).any(axis=1)))
        np.minimum(rows, np.float32(1.0), out=rows)
        warnings.warn(f"sun {sun.name!r} lit {over:,} of {len(rows):,} voxels brighter than 1 "
                      f"(up to {peak:.3g}); they are kept at 1, the range images and metrics "
                      "take", stacklevel=3)


def _threads_used(threads: int | None) -> int:

    if threads is None:
        return numba.get_num_threads()
    return min(int(threads), numba.config.NUMBA_NUM_THREADS)
