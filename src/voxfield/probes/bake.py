"""Probe baking straight from the octree (probe thesis §5.2 without its cube-map conversion).

The probe thesis rasterises six cube faces per probe and converts them to an octahedral map,
and names that conversion the bottleneck. Here the octahedral camera (``Camera.octahedral``)
casts one ray family per texel directly, so any renderer bakes the map in one pass and the
texel-footprint cone chooses the LOD — the EA thesis's motivating use (§1.3, §5.5).

Each probe costs two passes: the radiance pass (the chosen renderer) and the geometry pass —
one LOD-0 ray through every texel centre, giving the exact radial distance and face normal.
When the radiance pass is itself that pass (``lod`` at LOD 0, or ``reference`` with 1 sample)
it is reused and the geometry pass costs nothing. Both passes are counted in ``BakeCost``.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from voxfield.checks import integer_in
from voxfield.errors import VoxfieldError
from voxfield.probes.probe_set import (
    MIN_RESOLUTION,
    BakeCost,
    BakeOptions,
    ProbeMaps,
    ProbeSet,
    encode_normals,
)
from voxfield.progress import progress_bar
from voxfield.render.camera import MAX_IMAGE_SIDE, Camera, cube_cameras
from voxfield.render.primary import render_lod
from voxfield.render.registry import render, renderer_options
from voxfield.render.result import RenderResult
from voxfield.svo.octree import Octree, check_octree


def warm_up(octree: Octree, position, options: BakeOptions, *,
            threads: int | None = None) -> None:
    """One probe at the smallest maps with ``options``' baker, its maps dropped: a timed
    bake that follows no longer holds the loading (or compiling) of the baker's kernels
    (a first 16² bake took 20 times a 32² one)."""
    bake_probe(octree, position, dataclasses.replace(options, resolution=MIN_RESOLUTION),
               threads=threads)


def bake_probe(octree: Octree, position, options: BakeOptions, *,
               threads: int | None = None) -> ProbeMaps:
    """Bake one probe at ``position`` (world units): a pure function of the octree, position
    and options — the same inputs give bit-identical maps and counts on any thread count, so
    it may run in any process (arguments and result pickle) and be retried or resumed."""
    check_bake_options(octree, options)
    _warm_up(octree, position, options, threads)
    camera = Camera.octahedral(position, options.resolution)
    radiance, geometry = _passes(octree, camera, options, threads)
    cost = BakeCost(
        radiance_rays=radiance.total_rays, radiance_steps=radiance.total_steps,
        radiance_seconds=float(radiance.seconds),
        geometry_rays=0 if geometry is radiance else geometry.total_rays,
        geometry_steps=0 if geometry is radiance else geometry.total_steps,
        geometry_seconds=0.0 if geometry is radiance else float(geometry.seconds),
    )
    return ProbeMaps(
        radiance=radiance.image.astype(np.float16),
        distance=geometry.depth.astype(np.float32, copy=True),
        normal=encode_normals(geometry.normal),
        cost=cost,
    )


#: Bake configurations (options and the colour arrays' types, which pick the kernels'
#: compiled signatures) this process has compiled or loaded kernels for, and the lock
#: that makes every other probe wait, untimed, while the first compiles them.
_WARMED: set = set()
_WARM_LOCK = threading.Lock()


def _warm_up(octree: Octree, position, options: BakeOptions, threads: int | None) -> None:
    """Run both passes once on a 2×2 map before a process times its first probe. Compiling
    holds the GIL, so a kernel compiling in one thread stalls the timed passes of probes
    baking beside it, and their ``BakeCost`` seconds would include compilation."""
    stored, facing = octree.kernel_colours(options.channel)
    key = (options, stored.dtype.str, stored.ndim, facing.dtype.str, facing.ndim)
    with _WARM_LOCK:
        if key in _WARMED:
            return
        _passes(octree, Camera.octahedral(position, 2), options, threads)
        _WARMED.add(key)


def bake_probes(octree: Octree, grid, options: BakeOptions, *, progress: bool = False,
                threads: int | None = None) -> ProbeSet:
    """Bake every enabled probe of ``grid`` (anything with ``positions`` (N, 3) and
    ``enabled`` (N,) or None, e.g. ``ProbeGrid``) in grid order; disabled probes hold
    ``ProbeMaps.empty`` and are flagged in ``ProbeSet.enabled``."""
    check_bake_options(octree, options)
    if not hasattr(grid, "positions"):
        raise VoxfieldError(f"bake_probes needs a probe grid (probes.grid.ProbeGrid, or "
                            f"anything with positions (N, 3)), got {type(grid).__name__}")
    positions = np.asarray(grid.positions, np.float64).reshape(-1, 3)
    enabled = getattr(grid, "enabled", None)
    enabled = (np.ones(len(positions), bool) if enabled is None
               else np.asarray(enabled, bool).reshape(-1))
    if len(enabled) != len(positions):
        raise VoxfieldError(f"the grid has {len(positions)} probes but {len(enabled)} "
                            "enabled flags")
    if not np.isfinite(positions).all():
        raise VoxfieldError("probe positions hold NaN or infinity")
    probes: list[ProbeMaps | None] = []
    with progress_bar(total=int(enabled.sum()), desc="bake", unit="probe",
                      enabled=progress) as bar:
        for position, on in zip(positions, enabled, strict=True):
            if not on:
                probes.append(None)
                continue
            probes.append(bake_probe(octree, position, options, threads=threads))
            bar.update(1)
    return ProbeSet.assemble(grid, options, probes, octree.fingerprint(options.channel),
                             positions=positions)


def bake_cube_faces(octree: Octree, position, size: int, options: BakeOptions, *,
                    threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Six 90° cube faces at ``position`` in GL order (+x, -x, +y, -y, +z, -z; orientation of
    ``render.camera.CUBE_FACES``): radiance (6, S, S, 3) float16 from the options' renderer,
    radial distance (6, S, S) float32 from the exact LOD-0 pixel-centre ray (inf: no surface).

    Traced from the octree rather than resampled from the octahedral map: exact, no second
    filtering, and the pixel cone picks each face's LOD just as the texel cone does for the
    map. Distance is radial (the probe thesis's r_P), not the camera's z-depth."""
    check_bake_options(octree, options)
    size = integer_in(size, "cube face size", 1, MAX_IMAGE_SIDE)
    radiance = np.empty((6, size, size, 3), np.float16)
    distance = np.empty((6, size, size), np.float32)
    for k, camera in enumerate(cube_cameras(position, size)):
        colour, geometry = _passes(octree, camera, options, threads)
        radiance[k] = colour.image
        distance[k] = geometry.depth
    return radiance, distance


def export_cube_faces(probe_set: ProbeSet, octree: Octree, probe: int, size: int | None = None,
                      *, threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Probe ``probe``'s six cube-map faces for engines, traced straight from ``octree``
    (which must be the baked one): see ``bake_cube_faces``. ``size`` defaults to R/2."""
    if not -probe_set.count <= probe < probe_set.count:
        raise VoxfieldError(f"probe index {probe} is outside 0..{probe_set.count - 1}")
    if octree.fingerprint(probe_set.options.channel) != probe_set.fingerprint:
        raise VoxfieldError("this octree (or channel) is not the one the probes were "
                            "baked from; open the baked scene to export its cube faces")
    size = max(1, probe_set.resolution // 2) if size is None else size
    return bake_cube_faces(octree, probe_set.positions[probe], size, probe_set.options,
                           threads=threads)


def check_bake_options(octree: Octree, options: BakeOptions) -> None:
    """Refuse options this octree cannot bake (a LOD deeper than it goes, a channel it
    lacks) in one line, before anything is traced or written."""
    check_octree(octree, "a probe bake")
    if not isinstance(options, BakeOptions):
        raise VoxfieldError(f"bake options must be BakeOptions, got {type(options).__name__}")
    if options.lod is not None and options.lod > octree.depth:
        raise VoxfieldError(f"lod {options.lod} is deeper than this octree allows "
                            f"(0..{octree.depth})")
    octree.channel(options.channel)


def _exact_pass_is_radiance(options: BakeOptions) -> bool:
    return ((options.renderer == "lod" and options.lod == 0)
            or (options.renderer == "reference" and options.samples == 1))


def _passes(octree: Octree, camera: Camera, options: BakeOptions,
            threads: int | None) -> tuple[RenderResult, RenderResult]:
    """(radiance render, exact geometry render) of one camera; the same object when shared."""
    radiance = _radiance(octree, camera, options, threads)
    if _exact_pass_is_radiance(options):
        return radiance, radiance
    geometry = render_lod(octree, camera, lod=0, side=1, seed=options.seed,
                          channel=options.channel, threads=threads)
    return radiance, geometry


#: Per radiance renderer, the bake's flat, file-recorded fields it takes, and as which of its
#: own options; the rest mean nothing to it.
RADIANCE_FIELDS = {
    "reference": {"samples": "side"},
    "lod": {"lod": "lod", "cone_scale": "cone_scale"},
    # The adaptive renderer's first pass picks the cone LOD at scale 1 (no scale option).
    "adaptive": {"lod": "base_lod"},
    "error-aware": {"threshold": "threshold", "decay": "decay", "lod": "base_lod",
                    "cone_scale": "cone_scale"},
}


def radiance_renderer(options: BakeOptions) -> tuple[str, object]:
    """The registered renderer and its options for a bake's radiance pass."""
    fields = {theirs: getattr(options, ours)
              for ours, theirs in RADIANCE_FIELDS[options.renderer].items()}
    return options.renderer, renderer_options(options.renderer, **fields)


def _radiance(octree: Octree, camera: Camera, options: BakeOptions,
              threads: int | None) -> RenderResult:
    name, renderer_settings = radiance_renderer(options)
    return render(octree, camera, name, renderer_settings, seed=options.seed,
                  channel=options.channel, threads=threads)
