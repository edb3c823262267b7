"""Direct lighting with importance-sampled shadow rays (EA thesis §3.2.2, figs 3.4–3.6).

Primary rays sample the voxels (LOD 0); the shadow rays towards the emitting voxel faces sample
the octree at a LOD chosen by ``shadow_lod``: ``reference`` (LOD 0), ``distance`` (the LOD grows
with the distance from the shadow ray's origin — the thesis's baseline, which cuts the beam of
its test scene off abruptly) or ``error-aware`` (the baseline, refined one LOD at a time
wherever the error table says the node the ray hit is a poor stand-in for its children). See
``voxfield.kernels.direct_light`` for the estimator and the refinement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from voxfield.checks import integer_in, seed_value
from voxfield.error_table.table import (
    ENCODINGS,
    THESIS_DECAY,
    THESIS_THRESHOLD,
    ErrorTable,
    load_error_table,
)
from voxfield.errors import VoxfieldError
from voxfield.kernels.bundles import PixelOutputs
from voxfield.kernels.direct_light import (
    SHADOW_DISTANCE,
    SHADOW_ERROR_AWARE,
    SHADOW_REFERENCE,
    Emitters,
    ShadowLod,
    ShadowMaps,
    ShadowScene,
    direct_light_points,
    render_direct_light_rows,
)
from voxfield.kernels.error_aware import ENCODING_OCT, ENCODING_SH
from voxfield.parallel import run_in_bands, thread_count, threads_for
from voxfield.render.camera import Camera
from voxfield.render.result import RenderResult
from voxfield.svo.octree import Octree

SHADOW_MODES = {
    "reference": SHADOW_REFERENCE,
    "distance": SHADOW_DISTANCE,
    "error-aware": SHADOW_ERROR_AWARE,
}
#: Distance (voxels) from a shadow ray's origin at which the baseline switches to LOD 1;
#: LOD k starts at (2^k - 1) times it.
DEFAULT_LOD_DISTANCE = 16.0
#: Rec. 709 luminance weights: faces are sampled in proportion to the light they emit.
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
_FACE_DIRECTIONS = np.array(
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], np.int64
)


@dataclass(frozen=True)
class EmitterFaces:
    """The voxel faces that emit light into empty space, with the distribution that picks
    one: face ``i`` is the unit square on side ``axis`` (0 x, 1 y, 2 z), ``sign`` (±1) of the
    voxel at ``corner``, emitting ``radiance``; ``cdf`` is the cumulative probability of
    picking faces ``0..i`` (proportional to emitted luminance)."""

    corner: np.ndarray  # (F, 3) float64
    axis: np.ndarray  # (F,) int64
    sign: np.ndarray  # (F,) float64
    radiance: np.ndarray  # (F, 3) float64
    cdf: np.ndarray  # (F,) float64, last entry 1

    def __len__(self) -> int:
        return len(self.axis)


def check_emitters(octree: Octree) -> np.ndarray:
    """Refuse a scene without light in one line saying what direct lighting needs; else
    which leaves emit (a mask over the finest level)."""
    if "emission" not in octree.attributes:
        raise VoxfieldError(
            f"scene {octree.name!r} has no emission channel; direct lighting needs emitting "
            "voxels (e.g. builtin:shadowbox or builtin:cornell)"
        )
    emission = octree.attributes["emission"][octree.level_slice(octree.depth)]
    lit = (emission.astype(np.float64) @ _LUMINANCE) > 0.0
    if not lit.any():
        raise VoxfieldError(f"scene {octree.name!r} has no voxel with positive emission")
    return lit


def emitter_faces(octree: Octree) -> EmitterFaces:
    """The exposed faces of the voxels whose ``emission`` is non-zero."""
    lit = check_emitters(octree)
    coords = octree.node_coords(octree.depth)
    # Only the emitting voxels' values, converted once.
    emission = octree.attributes["emission"][octree.level_slice(octree.depth)][lit].astype(
        np.float64)
    side = (1 << octree.depth) + 2  # keys of neighbours one voxel outside the root stay unique

    def key(c: np.ndarray) -> np.ndarray:
        return ((c[:, 0] + 1) * side + (c[:, 1] + 1)) * side + (c[:, 2] + 1)

    occupied = np.sort(key(coords))
    lights = coords[lit]
    corner, axis, sign, radiance = [], [], [], []
    for k, direction in enumerate(_FACE_DIRECTIONS):
        neighbour = key(lights + direction)
        at = np.minimum(np.searchsorted(occupied, neighbour), len(occupied) - 1)
        exposed = occupied[at] != neighbour
        corner.append(lights[exposed])
        axis.append(np.full(int(exposed.sum()), k // 2))
        sign.append(np.full(int(exposed.sum()), 1.0 if k % 2 else -1.0))
        radiance.append(emission[exposed])
    corner = np.concatenate(corner).astype(np.float64)
    if len(corner) == 0:
        raise VoxfieldError(f"every emitting voxel of {octree.name!r} is enclosed; no light")
    radiance = np.concatenate(radiance)
    weight = radiance @ _LUMINANCE
    cdf = np.cumsum(weight) / weight.sum()
    cdf[-1] = 1.0
    return EmitterFaces(corner, np.concatenate(axis).astype(np.int64), np.concatenate(sign),
                        radiance, cdf)


@dataclass(frozen=True)
class _ShadowSetup:
    """Everything the kernels need besides the rays, checked once."""

    grid: tuple[int, int]
    scene: ShadowScene
    emitters: Emitters
    lod: ShadowLod
    params: dict


def _sample_grid(samples: int) -> tuple[int, int]:
    """The most square ``m × n = samples`` CMJ grid."""
    m = int(np.sqrt(samples))
    while samples % m:
        m -= 1
    return m, samples // m


def _setup(
    octree: Octree, *, shadow_lod: str, light_samples: int, lod_distance: float,
    threshold: float, decay: float, max_refinements: int | None, table: ErrorTable | None,
    encoding: str | None, seed: int,
) -> _ShadowSetup:
    if shadow_lod not in SHADOW_MODES:
        raise VoxfieldError(
            f"unknown shadow LOD {shadow_lod!r}; choose one of {', '.join(SHADOW_MODES)}"
        )
    light_samples = integer_in(light_samples, "light samples", 1, 4096)
    seed = seed_value(seed)
    if not (np.isfinite(lod_distance) and lod_distance > 0):
        raise VoxfieldError(f"the LOD distance must be a positive number, got {lod_distance}")
    if np.isnan(threshold) or not (np.isfinite(decay) and decay >= 0):
        raise VoxfieldError("threshold must be a number (inf: never refine) and decay >= 0")
    if max_refinements is not None:
        max_refinements = integer_in(max_refinements, "refinements (at most the octree's depth)",
                                     0, octree.depth)
    table = load_error_table() if table is None else table
    encoding = encoding or table.default_encoding
    if encoding not in ENCODINGS:
        raise VoxfieldError(f"unknown encoding {encoding!r}; choose one of {ENCODINGS}")
    faces = emitter_faces(octree)
    emission = octree.attributes["emission"]
    node_is_light = ((emission.astype(np.float64) @ _LUMINANCE) > 0.0).astype(np.uint8)
    refinements = octree.depth if max_refinements is None else int(max_refinements)
    scene = ShadowScene(octree.inner_nodes, octree.depth, octree.all_node_coords(),
                        node_is_light)
    emitters = Emitters(faces.corner, faces.axis, faces.sign, faces.radiance, faces.cdf)
    lod = ShadowLod(
        SHADOW_MODES[shadow_lod], float(lod_distance), refinements, float(threshold),
        float(decay), ENCODING_SH if encoding == "sh" else ENCODING_OCT,
        *table.kernel_maps,
    )
    params = {
        "shadow_lod": shadow_lod, "light_samples": int(light_samples), "seed": seed,
        "emitter_faces": len(faces),
    }
    if shadow_lod != "reference":
        params["lod_distance"] = float(lod_distance)
    if shadow_lod == "error-aware":
        params.update(threshold=float(threshold), decay=float(decay), encoding=encoding,
                      max_refinements=refinements)
    return _ShadowSetup(_sample_grid(int(light_samples)), scene, emitters, lod, params)


def render_direct_light(
    octree: Octree, camera: Camera, *, shadow_lod: str = "reference", light_samples: int = 16,
    lod_distance: float = DEFAULT_LOD_DISTANCE, threshold: float = THESIS_THRESHOLD,
    decay: float = THESIS_DECAY, max_refinements: int | None = None,
    table: ErrorTable | None = None, encoding: str | None = None, seed: int = 0,
    threads: int | None = None, progress: bool = False,
) -> RenderResult:
    """Direct light on a Lambertian world, ``light_samples`` samples per pixel (each a CMJ
    sub-pixel primary ray at LOD 0 and one importance-sampled shadow ray).

    ``shadow_lod`` picks the shadow rays' LOD (module docstring); ``lod_distance`` is where the
    baseline reaches LOD 1; ``threshold``, ``decay``, ``max_refinements`` (levels below the
    baseline LOD, None: down to the voxels) and ``table``/``encoding`` steer the error-aware
    refinement. The image is clamped to [0, 1]. Counters: ``ray_count`` and ``steps`` include
    the shadow rays' traversals (a refinement re-traverses from the root, as a new ray would);
    ``maps["shadow_rays"]`` counts the shadow rays cast, ``maps["shadow_traversals"]``,
    ``maps["shadow_steps"]`` and ``maps["shadow_refinements"]`` their traversals, steps and
    refinements; ``maps["shadow_lod"]`` is the mean over a pixel's shadow rays of the LOD each
    used — the finest it sampled (-1: none cast).
    """
    setup = _setup(octree, shadow_lod=shadow_lod, light_samples=light_samples,
                   lod_distance=lod_distance, threshold=threshold, decay=decay,
                   max_refinements=max_refinements, table=table, encoding=encoding, seed=seed)
    colors = octree.channel("albedo")
    emission = octree.attributes["emission"]
    h, w = camera.height, camera.width
    threads = threads_for(h * w * setup.params["light_samples"], threads)
    result = RenderResult.allocate(h, w, renderer=f"direct-{shadow_lod}")
    shadow_rays = np.empty((h, w), np.int32)
    shadow_traversals = np.empty((h, w), np.int32)
    shadow_steps = np.empty((h, w), np.int64)
    shadow_lod_map = np.empty((h, w), np.float32)
    refinements = np.empty((h, w), np.int32)
    cam = camera.params

    def band(rows: slice) -> None:
        maps = ShadowMaps(shadow_rays[rows], shadow_traversals[rows], shadow_steps[rows],
                          shadow_lod_map[rows], refinements[rows])
        render_direct_light_rows(cam, w, h, rows.start, rows.stop, seed, *setup.grid,
                                 setup.scene, colors, emission, setup.emitters, setup.lod,
                                 PixelOutputs(*result.buffers(rows)), maps,
                                 numba.get_num_threads())

    result.seconds = run_in_bands(h, band, label=f"direct light ({shadow_lod})",
                                  threads=threads, progress=progress)
    result.params = setup.params
    result.maps.update(shadow_rays=shadow_rays, shadow_traversals=shadow_traversals,
                       shadow_steps=shadow_steps, shadow_lod=shadow_lod_map,
                       shadow_refinements=refinements)
    return result


def light_on_surface(
    octree: Octree, points: np.ndarray, normals: np.ndarray, *,
    shadow_lod: str = "reference", light_samples: int = 64,
    lod_distance: float = DEFAULT_LOD_DISTANCE, threshold: float = THESIS_THRESHOLD,
    decay: float = THESIS_DECAY, max_refinements: int | None = None,
    table: ErrorTable | None = None, encoding: str | None = None, seed: int = 0,
    threads: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radiance a white Lambertian surface reflects at ``points`` (N×3, on the surface) with
    unit ``normals`` (N×3), shadow rays as in ``render_direct_light``: the light reaching a
    region, whatever the camera. Returns ``(radiance (N, 3), shadow steps (N,), mean LOD used
    by the shadow rays (N,), -1 where none was cast)``."""
    pts = np.ascontiguousarray(points, np.float64)
    nrm = np.ascontiguousarray(normals, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or nrm.shape != pts.shape:
        raise VoxfieldError(f"points and normals must both be N×3, got {pts.shape} and "
                            f"{nrm.shape}")
    if not (np.isfinite(pts).all() and np.isfinite(nrm).all()):
        raise VoxfieldError("points and normals must be finite")
    lengths = np.linalg.norm(nrm, axis=1)
    if len(nrm) and not np.allclose(lengths, 1.0, atol=1e-6):
        raise VoxfieldError("normals must be unit vectors")
    setup = _setup(octree, shadow_lod=shadow_lod, light_samples=light_samples,
                   lod_distance=lod_distance, threshold=threshold, decay=decay,
                   max_refinements=max_refinements, table=table, encoding=encoding, seed=seed)
    n = len(pts)
    radiance = np.empty((n, 3))
    steps = np.empty(n, np.int64)
    lod = np.empty(n, np.float32)
    with thread_count(threads_for(n * setup.params["light_samples"], threads)):
        direct_light_points(pts, nrm, seed, *setup.grid, setup.scene, setup.emitters, setup.lod,
                            radiance, steps, lod)
    return radiance, steps, lod
