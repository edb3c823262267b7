"""How close a probe render comes to what its probes allow, and where it goes wrong.

- ``perfect_trace_image``: the bound. Each pixel is given its true hit point (from the octree's
  own render of the same rays) and reads a probe that sees that point, chosen and read as the
  trace reads a hit (``LightFieldOptions.colour_probe`` and ``colour_filter``). A trace that
  finds every hit exactly gets this image, so the gap between a method's PSNR and the
  bound's is what the trace loses.
- ``depth_agreement``: |depth - octree depth| over the pixels where the octree sees a surface.
- ``pixel_classes``: correct hits, hits on a neighbouring voxel, false hits, wrong misses and
  fallbacks, with each class's share of the squared error.
"""

from __future__ import annotations

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.probe_multi import perfect_trace_rays
from voxfield.lightfield.packed import PackedProbes
from voxfield.lightfield.trace import (
    COLOUR_FILTERS,
    COLOUR_PROBES,
    FALLBACK,
    HIT,
    MISS,
    UNKNOWN,
)
from voxfield.parallel import thread_count, threads_for
from voxfield.render.camera import Camera

#: A probe "sees" a point when its stored distance there is within this of the point's
#: distance (voxels), plus half the depth the texel's surface spans: the tolerance the trace
#: uses to pick a hit's colour (``LightFieldOptions.epsilon_value`` + 0.5 by default).
SEEN_TOLERANCE = 1.0
#: Depth classes, in voxels.
CORRECT_DEPTH = 1.0
NEIGHBOUR_DEPTH = 2.0
CLASSES = ("correct", "neighbour", "false hit", "wrong miss", "fallback", "unknown",
           "false surface")


def perfect_trace_image(packed: PackedProbes, camera: Camera, depth: np.ndarray, *,
                       colour_filter: str = "bilinear", colour_probe: str = "footprint",
                       threads: int | None = None) -> np.ndarray:
    """The bound: (H, W, 3) float32 radiance read at every pixel's true hit point (``depth``
    = t along the pixel-centre ray, inf where nothing is hit; black there) from the enabled
    probe best by ``colour_probe`` among those whose stored distance agrees with the point's
    (the best of all when none agrees), read as the trace reads a hit (``colour_filter``
    ``"bilinear"``, or ``"nearest"`` texel)."""
    h, w = camera.height, camera.width
    depth = np.asarray(depth, np.float64)
    if depth.shape != (h, w):
        raise VoxfieldError(f"depth must be {h}×{w} for this camera, got {depth.shape}")
    if colour_filter not in COLOUR_FILTERS:
        raise VoxfieldError(f"unknown colour filter {colour_filter!r}")
    if colour_probe not in COLOUR_PROBES:
        raise VoxfieldError(f"unknown colour probe rule {colour_probe!r}")
    origins, dirs = camera.rays(side=1)
    hit = np.isfinite(depth.reshape(-1))
    points = np.ascontiguousarray(origins[hit] + depth.reshape(-1)[hit, None] * dirs[hit])
    colour = np.zeros((len(points), 3), np.float64)
    probe = np.empty(len(points), np.int64)
    with thread_count(threads_for(len(points), threads)):
        perfect_trace_rays(packed.positions, packed.enabled, packed.normals, packed.mips,
                           packed.radiance_bordered, packed.distance_bordered,
                           packed.resolution, points, np.ascontiguousarray(dirs[hit]),
                           SEEN_TOLERANCE, colour_filter == "bilinear",
                           COLOUR_PROBES[colour_probe], colour, probe)
    image = np.zeros((h * w, 3), np.float32)
    image[hit] = colour
    return image.reshape(h, w, 3)


def depth_agreement(depth: np.ndarray, reference_depth: np.ndarray) -> dict:
    """Median and 99th percentile of |depth - reference| (voxels) over the pixels where the
    reference sees a surface (a missing depth there counts as infinitely wrong), and the
    share of those pixels within ``CORRECT_DEPTH``."""
    ref = np.asarray(reference_depth, np.float64)
    seen = np.isfinite(ref)
    if not seen.any():
        return {"pixels": 0, "median": 0.0, "p99": 0.0, "within_1": 1.0}
    error = np.abs(np.asarray(depth, np.float64)[seen] - ref[seen])
    error = np.where(np.isnan(error), np.inf, error)
    return {"pixels": int(seen.sum()), "median": float(np.percentile(error, 50, method="higher")),
            "p99": float(np.percentile(error, 99, method="higher")),
            "within_1": float(np.mean(error <= CORRECT_DEPTH))}


def pixel_classes(kind: np.ndarray, depth: np.ndarray, image: np.ndarray,
                  reference_depth: np.ndarray, reference_image: np.ndarray) -> dict:
    """Every pixel in one class, with its count and its share of the image's squared error:
    ``correct`` (a hit within 1 voxel of the octree's), ``neighbour`` (1–2 voxels),
    ``false hit`` (2 or more, or a hit where the octree sees nothing: ``false surface``),
    ``wrong miss`` (a miss where the octree sees a surface), ``fallback`` and ``unknown``.
    Pixels where both see nothing are left out."""
    kind = np.asarray(kind)
    ref = np.asarray(reference_depth, np.float64)
    seen = np.isfinite(ref)
    # Only where the octree sees a surface: where neither does, inf - inf has no error.
    error = np.full(ref.shape, np.inf)
    error[seen] = np.abs(np.asarray(depth, np.float64)[seen] - ref[seen])
    sq = np.sum((np.asarray(image, np.float64) - np.asarray(reference_image, np.float64)) ** 2,
                axis=-1)
    hit = kind == HIT
    masks = {
        "correct": hit & seen & (error < CORRECT_DEPTH),
        "neighbour": hit & seen & (error >= CORRECT_DEPTH) & (error < NEIGHBOUR_DEPTH),
        "false hit": hit & seen & ~(error < NEIGHBOUR_DEPTH),
        "false surface": hit & ~seen,
        "wrong miss": (kind == MISS) & seen,
        "fallback": kind == FALLBACK,
        "unknown": kind == UNKNOWN,
    }
    total = float(sq.sum()) or 1.0
    return {name: {"pixels": int(m.sum()), "share_of_error": float(sq[m].sum()) / total}
            for name, m in masks.items()}
