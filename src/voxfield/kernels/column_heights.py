"""Column heights: the time after which a rising ray can meet no voxel.

Why: a sky or sun ray leaving a terrain spends most of its traversal steps after it has
already risen above everything near it. The octree cannot tell: a coarse node that holds the
ground far below the ray is occupied, so the ray descends into it on its way up to the
scene's top. A max pyramid of column heights (per square tile of columns, the top of its
highest voxel) answers what the octree cannot: once a rising ray is above a tile's top it
meets nothing more in that tile. ``clear_time`` walks the ray across the pyramid's tiles, as
coarse as they stay clear, and returns when its last dangerous stretch ends; an any-hit
query clipped there gives the same answer in a third of the steps (the 2048² desert bake's
sky and sun rays: 19 steps a ray to 6).

Exact, not approximate: every decision uses the traversal's plane-time formula
(``face_time``), which is monotonic in the plane. A voxel in column ``(x, z)`` of a tile
whose top is ``h`` can hold the ray only before the ray's ``y = h`` crossing, and only while
the ray is inside the tile's ``x`` and ``z`` slabs, both by the same formula the traversal
uses, so every interval in which the traversal could find a voxel ends by the returned time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from voxfield.kernels.traversal import face_time, floor_float, flush_uninvertible

#: Side of the finest tiles, as a power of two: 8×8 columns. Finer tiles clip rays closer to
#: their last danger but cost more walking; 8 is the fastest on terrains (4 and 16 lose).
FINEST_TILE_LEVEL = 3


class ColumnHeights(NamedTuple):
    """Per tile of ``2**k × 2**k`` columns (``k`` from ``finest`` to ``depth``), the top
    (``y + 1``) of its highest voxel, 0 where it has none. Level ``k``'s tiles form a grid of
    ``2**(depth - k)`` a side, stored row-major over ``(x, z)`` from ``offsets[k]``."""

    heights: np.ndarray
    offsets: np.ndarray
    finest: int
    depth: int


@njit(cache=True, nogil=True)
def tile_tops(coords: np.ndarray, level: int, side: int) -> np.ndarray:
    """The finest pyramid level: per ``2**level`` tile of a ``side``-wide grid of tiles, the
    top of its highest voxel among ``coords`` (voxel corners, one row each)."""
    tops = np.zeros(side * side, np.int32)
    for i in range(coords.shape[0]):
        k = (coords[i, 0] >> level) * side + (coords[i, 2] >> level)
        top = coords[i, 1] + 1
        if top > tops[k]:
            tops[k] = top
    return tops


def column_heights(coords: np.ndarray, depth: int,
                   finest: int = FINEST_TILE_LEVEL) -> ColumnHeights:
    """The pyramid of an octree of ``depth`` whose voxel corners are ``coords`` (``n×3``
    integers in voxel units)."""
    finest = max(0, min(int(finest), depth))
    side = 1 << (depth - finest)
    level = tile_tops(np.ascontiguousarray(coords, np.int64), finest, side).reshape(side, side)
    levels = [level]
    while level.shape[0] > 1:
        level = np.maximum(np.maximum(level[0::2, 0::2], level[1::2, 0::2]),
                           np.maximum(level[0::2, 1::2], level[1::2, 1::2]))
        levels.append(level)
    offsets = np.zeros(depth + 2, np.int64)
    offsets[finest + 1:] = np.cumsum([a.size for a in levels])
    heights = np.concatenate([a.ravel() for a in levels]).astype(np.int32)
    return ColumnHeights(heights, offsets, finest, depth)


@njit(cache=True, nogil=True, inline="always")
def column_at(o: float, d: float, inv: float, t: float, side: int) -> int:
    """The column (``floor`` of the coordinate) that holds the ray at time ``t`` on one axis
    under the traversal's half-open slabs, or -1 when it is outside ``0..side-1``."""
    if d == 0.0:
        c = floor_float(o)
    else:
        p = o + t * d
        if not (p > -2.0 and p < side + 2.0):
            return -1
        c = floor_float(p)
        # Rounding in ``o + t·d`` may put ``p`` across a plane from where the plane times say
        # the ray is: the plane times decide (one move fixes it; a few more cost nothing).
        placed = False
        for _ in range(4):
            near = c if d > 0.0 else c + 1.0
            far = c + 1.0 if d > 0.0 else c
            if t < face_time(int(near), o, inv):
                c -= 1.0 if d > 0.0 else -1.0
            elif not t < face_time(int(far), o, inv):
                c += 1.0 if d > 0.0 else -1.0
            else:
                placed = True
                break
        if not placed:
            return -1
    if not (c >= 0.0 and c < side):
        return -1
    return int(c)


@njit(cache=True, nogil=True)
def clear_time(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
               tmin: float, tmax: float, columns: ColumnHeights) -> float:
    """A time in ``[tmin, tmax]`` after which the ray meets no voxel before ``tmax``: an
    any-hit query on ``[tmin, clear_time)`` answers as one on ``[tmin, tmax)``. Only a ray
    that rises (``dy > 0``) and starts inside the grid's columns gets a bound below ``tmax``.
    """
    heights, offsets, finest, depth = columns
    dx = flush_uninvertible(dx)
    dy = flush_uninvertible(dy)
    dz = flush_uninvertible(dz)
    if not (dy > 0.0 and tmin < tmax and math.isfinite(tmin) and math.isfinite(ox)
            and math.isfinite(oy) and math.isfinite(oz) and math.isfinite(dx)
            and math.isfinite(dy) and math.isfinite(dz)):
        return tmax
    ix = 1.0 / dx if dx != 0.0 else 0.0
    iy = 1.0 / dy
    iz = 1.0 / dz if dz != 0.0 else 0.0
    side = 1 << depth
    cx = column_at(ox, dx, ix, tmin, side)
    cz = column_at(oz, dz, iz, tmin, side)
    if cx < 0 or cz < 0:
        return tmax
    step_x = 1 if dx > 0.0 else -1
    step_z = 1 if dz > 0.0 else -1
    level = finest
    cx >>= finest
    cz >>= finest
    clear = tmin
    t = tmin
    # A walk moves forward one tile per step and descends at most ``depth`` times between
    # steps; past that bound something is wrong with the input, and no clip is safe.
    budget = (depth + 2) * (2 * (side >> finest) + 2)
    while t < tmax:
        budget -= 1
        if budget < 0:
            return tmax
        size = 1 << level
        top = heights[offsets[level] + cx * (side >> level) + cz]
        t_top = face_time(top, oy, iy)
        ex = math.inf if dx == 0.0 else face_time(cx * size + (size if dx > 0.0 else 0), ox, ix)
        ez = math.inf if dz == 0.0 else face_time(cz * size + (size if dz > 0.0 else 0), oz, iz)
        t_exit = min(ex, ez)
        if t_top > t:
            # Below the tile's top: look at the quarter that holds the ray, or, at the
            # finest tiles, count the stretch to the tile's top or exit as dangerous.
            if level > finest:
                level -= 1
                half = size >> 1
                cx = 2 * cx + half_at(cx * size + half, ox, dx, ix, t)
                cz = 2 * cz + half_at(cz * size + half, oz, dz, iz, t)
                continue
            clear = max(clear, min(t_exit, t_top))
        t = t_exit
        if ex <= t_exit:
            cx += step_x
        if ez <= t_exit:
            cz += step_z
        tiles = side >> level
        if cx < 0 or cz < 0 or cx >= tiles or cz >= tiles:
            break
        if level < depth:  # try the next coarser tile first: it may be clear as a whole
            level += 1
            cx >>= 1
            cz >>= 1
    return min(clear, tmax)


@njit(cache=True, nogil=True, inline="always")
def half_at(centre: int, o: float, d: float, inv: float, t: float) -> int:
    """1 when the ray is past (``d > 0``) or still before (``d < 0``) the centre plane at
    time ``t``, so in a tile's upper half on that axis; a ray parallel to the axis is where
    its origin is."""
    if d == 0.0:
        return 1 if o >= centre else 0
    passed = face_time(centre, o, inv) <= t
    return 1 if passed == (d > 0.0) else 0
