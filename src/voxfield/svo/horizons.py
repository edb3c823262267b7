"""Horizon slopes: per column and heading, how steeply a rising ray must climb to clear
everything ahead of it.

Most sky rays leave the ground and never meet anything, yet the column-top pyramid
(``svo.column_tops``) still walks each of them up its levels until it rises past the world's
highest voxel: a dozen cells a ray on a 2048² desert. A column's horizon settles such a ray
with one number. A ray heading into quadrant ``q`` (the signs of ``dx`` and ``dz``) only
crosses columns ahead of its start column ``c`` on both axes, and it reaches a column ``c'``
no sooner than after the horizontal gap between the two squares. So a ray that starts at or
above ``top(c)`` and rises with slope ``dy / |d_xz|`` above

    max over c' ahead of (top(c') - top(c)) / gap(c, c')

stays above every voxel: it is clear. An adjacent column ahead that is higher (gap 0) makes
the slope infinite, and a quadrant with nothing higher ahead has none (stored as ``-1``).

The slopes are upper bounds, exact only near the column. Columns up to ``2·RING - 1`` away on
both axes count with their exact gap; further out, the cells of each pyramid level ``l >= 1``
whose Chebyshev offset from the column's own level-``l`` cell is ``k`` (``RING <= k < 2·RING``)
count with their highest top and a gap of ``(k - 1)·2^l``, less than any column in them can
be away. Those rings tile every column ahead: level ``l`` reaches past where level ``l - 1``
stops. Each slope is widened by a relative and absolute ``1e-6`` before it is stored as a
float32, so a ray the test calls clear passes every voxel by far more than float rounding:
the verdict is the octree's. ``kernels.upward_rays.clears_horizon`` reads them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.upward_rays import quadrant_steps
from voxfield.svo.column_tops import ColumnTops

__all__ = ["NOTHING_AHEAD", "RING", "horizon_slopes", "no_horizon_slopes"]

#: Chebyshev offsets below ``RING`` at a coarse level are left to the finer levels.
RING = 2
#: Stored for a quadrant with nothing higher ahead: every rising ray clears it.
NOTHING_AHEAD = -1.0
_WIDEN = 1e-6


def no_horizon_slopes() -> np.ndarray:
    """No slopes: ``clears_horizon`` then settles nothing."""
    return np.zeros((0, 4), np.float32)


def horizon_slopes(columns: ColumnTops, ring: int = RING) -> np.ndarray:
    """``(columns, 4)`` float32: per level-0 cell of the pyramid and quadrant
    (``kernels.upward_rays.quadrant``), an upper bound on the slope a ray starting there at
    or above the column's top must rise with to clear everything ahead (module docstring);
    empty without a pyramid."""
    if columns.level_width.shape[0] == 0:
        return no_horizon_slopes()
    if ring < 2:
        raise ValueError(f"ring must be at least 2, got {ring}")
    levels = columns.level_width.shape[0]
    first_coarse = int(columns.level_offset[1]) if levels > 1 else columns.tops.shape[0]
    rings = np.zeros((columns.tops.shape[0] - first_coarse, 4, ring), np.int32)
    for level in range(1, levels):
        _ring_tops(columns.tops, int(columns.level_offset[level]), first_coarse,
                   int(columns.level_width[level]), int(columns.level_depth[level]), ring,
                   rings)
    out = np.empty((int(columns.level_width[0] * columns.level_depth[0]), 4), np.float32)
    _slopes(columns.tops, columns.level_offset, columns.level_width, columns.level_depth,
            ring, rings, first_coarse, out)
    return out


@njit(cache=True, nogil=True, parallel=True)
def _ring_tops(tops: np.ndarray, first: int, first_coarse: int, width: int, depth: int,
               ring: int, out: np.ndarray) -> None:
    """Per cell of one coarse level (cells from ``first``) and quadrant: the highest top of
    the cells at Chebyshev offset ``k`` ahead, ``ring <= k < 2·ring``, in ``out[cell -
    first_coarse, q, k - ring]``."""
    for x in prange(width):
        for z in range(depth):
            row = first - first_coarse + x * depth + z
            for q in range(4):
                step_x, step_z = quadrant_steps(q)
                for k in range(ring, 2 * ring):
                    highest = 0
                    far_x = x + step_x * k
                    far_z = z + step_z * k
                    if 0 <= far_x < width:
                        for j in range(k + 1):
                            zj = z + step_z * j
                            if not 0 <= zj < depth:
                                break
                            highest = max(highest, tops[first + far_x * depth + zj])
                    if 0 <= far_z < depth:
                        for i in range(k):
                            xi = x + step_x * i
                            if not 0 <= xi < width:
                                break
                            highest = max(highest, tops[first + xi * depth + far_z])
                    out[row, q, k - ring] = highest


@njit(cache=True, nogil=True, parallel=True)
def _slopes(tops: np.ndarray, level_offset: np.ndarray, level_width: np.ndarray,
            level_depth: np.ndarray, ring: int, rings: np.ndarray, first_coarse: int,
            out: np.ndarray) -> None:
    """``horizon_slopes`` per column from the near columns and the coarse rings. Gaps are
    applied as reciprocals: the product may be one rounding below the quotient, which the
    widening covers."""
    width = level_width[0]
    depth = level_depth[0]
    levels = level_width.shape[0]
    reach = 2 * ring
    near = np.zeros((reach, reach))  # 1 / gap to a column ``(i, j)`` ahead; 0: touching
    for i in range(reach):
        for j in range(reach):
            gap_x = max(i - 1, 0)
            gap_z = max(j - 1, 0)
            if gap_x > 0 or gap_z > 0:
                near[i, j] = 1.0 / math.sqrt(gap_x * gap_x + gap_z * gap_z)
    far = np.zeros((levels, ring))  # 1 / gap to ring ``k`` of a level
    for level in range(1, levels):
        for k in range(ring, 2 * ring):
            far[level, k - ring] = 1.0 / float((k - 1) << level)
    for x in prange(width):
        slope = np.zeros(4)
        wall = np.zeros(4, np.bool_)
        for z in range(depth):
            base = tops[x * depth + z]
            for q in range(4):
                step_x, step_z = quadrant_steps(q)
                steepest = 0.0
                touching = False
                for i in range(reach):
                    xi = x + step_x * i
                    if not 0 <= xi < width:
                        break
                    for j in range(reach):
                        zj = z + step_z * j
                        if not 0 <= zj < depth:
                            break
                        rise = float(tops[xi * depth + zj] - base)
                        if near[i, j] == 0.0:
                            touching |= rise > 0.0  # a higher column touching this one ahead
                        else:
                            steepest = max(steepest, rise * near[i, j])
                slope[q] = steepest
                wall[q] = touching
            for level in range(1, levels):
                cell = (level_offset[level] - first_coarse
                        + (x >> level) * level_depth[level] + (z >> level))
                for q in range(4):
                    for k in range(ring):
                        slope[q] = max(slope[q], (rings[cell, q, k] - base) * far[level, k])
            for q in range(4):
                if wall[q]:
                    out[x * depth + z, q] = np.inf
                elif slope[q] == 0.0:
                    out[x * depth + z, q] = NOTHING_AHEAD
                else:
                    out[x * depth + z, q] = slope[q] * (1.0 + _WIDEN) + _WIDEN
