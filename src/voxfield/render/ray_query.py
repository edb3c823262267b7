"""Arbitrary ray queries against an octree: the batch form of the primary-ray traversal."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from voxfield.checks import flag, integer_in, ray_arrays, real_number
from voxfield.errors import VoxfieldError
from voxfield.kernels.ray_batch import occlude_rays, trace_rays
from voxfield.parallel import thread_count, threads_for
from voxfield.svo.column_tops import no_column_tops, octree_column_tops
from voxfield.svo.octree import Octree, check_octree


@dataclass
class RayHits:
    """Per-ray results; ``node`` is -1 and ``t`` is inf where a ray hits nothing.

    ``normal_code`` is 0..5 for the -x, +x, -y, +y, -z, +z face entered, -1 when the ray
    starts inside the node it hits; ``steps`` counts the octree nodes visited. ``level``
    counts the hit node's level down from the root (0), as the kernels do; ``lod`` counts up
    from the voxels (0), as ``trace(lod=...)`` and the renderers do, -1 where nothing is hit.
    """

    node: np.ndarray
    level: np.ndarray
    t: np.ndarray
    normal_code: np.ndarray
    steps: np.ndarray
    lod: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.node >= 0


def trace(
    octree: Octree, origins, directions, *, lod: int = 0, tmin: float = 0.0,
    tmax: float = math.inf, threads: int | None = None, columns: bool = False,
) -> RayHits:
    """First node at ``lod`` hit by each ray ``o + t·d`` with ``tmin <= t < tmax``.

    Directions need not be normalised; ``t`` is in units of each direction's length.
    ``columns=True`` lets each ray cross the air in the octree's column-top pyramid first
    (``kernels.surface_approach``): the same hits, faster for rays that leave a surface;
    the steps then count the pyramid's cells.
    """
    check_octree(octree, "trace")
    columns = flag(columns, "columns")
    o, d = _rays_with_times(origins, directions)
    lod = integer_in(lod, "LOD", 0, octree.depth)
    tmin, tmax = _checked_interval(tmin, tmax)
    n = len(o)
    hits = RayHits(
        node=np.empty(n, np.int64), level=np.empty(n, np.int64), t=np.empty(n),
        normal_code=np.empty(n, np.int64), steps=np.empty(n, np.int64),
        lod=np.empty(n, np.int64),
    )
    with thread_count(threads_for(n, threads)):
        trace_rays(
            o, d, tmin, tmax, octree.inner_nodes, octree.depth, octree.depth - lod,
            hits.node, hits.level, hits.t, hits.normal_code, hits.steps,
            octree_column_tops(octree) if columns else None, numba.get_num_threads(),
        )
    np.subtract(octree.depth, hits.level, out=hits.lod)
    hits.lod[hits.node < 0] = -1
    return hits


@dataclass
class Occlusions:
    """Per-ray any-hit results: ``blocked`` where a voxel lies on the segment."""

    blocked: np.ndarray
    steps: np.ndarray


def occluded(
    octree: Octree, origins, directions, *, tmin: float = 0.0, tmax: float = math.inf,
    threads: int | None = None, columns: bool = False,
) -> Occlusions:
    """Whether a voxel (LOD 0) blocks each segment ``o + t·d``, ``tmin <= t < tmax``: the
    query shadow and visibility rays need. It stops at the first occupied node met (a
    solid node counts the moment it is entered), so it is cheaper than ``trace``; which
    rays are blocked is exactly ``trace(...).hit``.

    ``columns=True`` lets rising rays (with ``tmin`` 0) walk the octree's column-top
    pyramid first (``svo.column_tops``, worked out once per octree), as the sun bake's do:
    the same verdicts, usually far fewer steps, and the steps then count pyramid cells too.
    """
    check_octree(octree, "occluded")
    columns = flag(columns, "columns")
    o, d = _rays_with_times(origins, directions)
    tmin, tmax = _checked_interval(tmin, tmax)
    n = len(o)
    result = Occlusions(blocked=np.empty(n, bool), steps=np.empty(n, np.int64))
    pyramid = octree_column_tops(octree) if columns else no_column_tops()
    with thread_count(threads_for(n, threads)):
        occlude_rays(o, d, tmin, tmax, octree.inner_nodes, octree.depth,
                     pyramid, result.blocked, result.steps, numba.get_num_threads())
    return result


def _rays_with_times(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """``checks.ray_arrays``, and no direction whose components are all subnormal: times
    here are in units of the direction's length, so along such a one every hit lies past
    the largest float (the traversal flushed the components it cannot invert and reported
    a miss, without a word). One normal component is enough."""
    o, d = ray_arrays(origins, directions)
    tiny = np.finfo(np.float64).tiny
    short = np.flatnonzero(np.abs(d).max(axis=1) < tiny)
    if short.size:
        raise VoxfieldError(f"ray {short[0]}'s direction {d[short[0]].tolist()} is too short "
                            f"to measure times along (every component under {tiny:.4g}); "
                            "scale it up")
    return o, d


def _checked_interval(tmin, tmax) -> tuple[float, float]:
    """The segment's ends: ``tmin`` finite, ``tmax`` any number but NaN (an empty segment,
    ``tmax <= tmin``, misses, as in Embree); a NaN would turn every ray into a miss."""
    return real_number(tmin, "tmin"), real_number(tmax, "tmax", finite=False)
