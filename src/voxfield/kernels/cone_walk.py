"""Cone-LOD rays over the column-top pyramid: skip the air, then let the octree find the hit.

A cone-LOD ray (``traversal.trace_ray`` with a cone) samples a node once the node is no
larger than the cone's width where the ray enters it, so the level it stops at grows along
the ray and the fixed-level walk (``surface_approach``) does not apply. This walk follows
the cone instead. In a cell it asks for the largest node the cone accepts by the time the
ray leaves the cell (the cone only widens), ``K``: a cell smaller than that is left for
its parent, and a cell the ray is above (its top rounded up to nodes of side ``2^K``), or
in the gap under its top runs (rounded in), holds no node the cone would take there, as
every node it could take lies inside the cell and under that top. A cell the ray dips
below is walked at its children until the cell's level is ``K``; there the ray lands on
the cell's top node when the cone accepts exactly that level at the node's entry
(``surface_approach.top_node_hit``), else the octree takes over from the cell's time.

**Exactness.** The octree restarted at a time ``t`` judges the nodes that already hold the
ray with the cone at ``t``, where the ray from its start judged them at their own entry.
Only nodes the cone accepts at ``t`` could differ, no larger than ``2^k(t)``, and the walk
only hands over at ``t`` in a cell no smaller than that which it reached at ``t`` (across
a face, or down or up from one): such a node lies inside the cell, so the ray entered it
at ``t`` or later. The footprint is rounded out to the pyramid's top cell, so nodes that
reach past its edge are walked too. Steps count the cells, then the octree's nodes (one
for a landing), as ``surface_approach`` counts them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.column_walk import (
    cell_holding,
    clear_of_cell,
    step_across,
    step_down,
)
from voxfield.kernels.scalar_ops import face_time
from voxfield.kernels.surface_approach import (
    NEAR_START_LEVELS,
    WALKS,
    landed_node,
    level_of_height,
    level_shape,
    prefetch_landing,
    top_node_hit,
    walk_entry,
)
from voxfield.kernels.traversal import (
    MISS,
    NO_NORMAL,
    cone_width,
    traverse,
)

#: ``walk_cone_over_columns``'s cell for a ray that meets nothing.
MISSED_ALL = -2
#: The time ``cone_level`` judges a cone at for a ray that never leaves a cell.
_LONGEST = 1e300


@njit(cache=True, nogil=True, inline="always")
def cone_level(t: float, radius: float, spread: float, depth: int) -> int:
    """The level (node side ``2^level``) of the largest node the cone ``radius + spread·t``
    accepts at ``t``, by ``traversal.traverse``'s own test; 0 (voxels) when none larger.
    ``t`` may be infinite (a vertical ray never leaves its column): it is judged at a finite
    time, where a cone of no spread (an orthographic camera's) keeps its width rather than
    ``0 · inf``, no width."""
    cone = cone_width(radius, spread, min(t, _LONGEST))
    level = 0
    while level < depth and float(2 << level) <= cone:
        level += 1
    return level


@borrowing
def walk_cone_over_columns(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmin: float,
    radius: float, spread: float, depth: int, columns,
) -> tuple[float, int, int, int, int]:
    """The pyramid's part of a cone-LOD primary ray from ``tmin``: ``(t, cells, cx, cz,
    level)``, the octree to go on from ``t``, with ``(cx, cz)`` the cell of ``level`` the
    walk stopped in where the ray may land on its top node (``cx = -1`` where not;
    ``MISSED_ALL`` where the ray leaves the pyramid's top cell and meets nothing)."""
    levels = columns.level_width.shape[0]
    top_level = levels - 1
    (entry, t, t_end, ox, dx, ix, dy, iy, oz, dz, iz, _, _, _) = walk_entry(
        ox, oy, oz, dx, dy, dz, tmin, math.inf, top_level, top_level, columns)
    start = cone_level(t, radius, spread, depth)
    if entry != WALKS or start > top_level:
        return tmin, 0, -1, -1, 0  # the octree from the start (or nodes past the top cell)
    # From a start bound (near the surface) a level above the nodes the cone takes there,
    # from the camera at the level of its height (``surface_approach.BY_HEIGHT``); a cell
    # past the footprint's is nothing.
    if tmin > 0.0:
        level = min(start + NEAR_START_LEVELS, top_level)
    else:
        level = level_of_height(ox, dx, ix, oy, dy, oz, dz, iz, t, start, columns)
    cx = cell_holding(ox, dx, ix, t, level, -1, columns.level_width[level])
    cz = cell_holding(oz, dz, iz, t, level, -1, columns.level_depth[level])
    tops, gap_floor, gap_ceiling = columns.tops, columns.gap_floor, columns.gap_ceiling
    ahead_x = 0 if dx < 0.0 else 1
    ahead_z = 0 if dz < 0.0 else 1
    step_x = 1 if dx > 0.0 else -1
    step_z = 1 if dz > 0.0 else -1
    width, depth_cells, offset = level_shape(columns, level)
    cells = 0
    while True:
        # Cells past the footprint's (inside the top cell) hold nothing.
        inside = np.uint64(cx) < np.uint64(width) and np.uint64(cz) < np.uint64(depth_cells)
        cells += 1
        cell = np.uint64(offset + cx * depth_cells + cz) if inside else np.uint64(0)
        tx = face_time((cx + ahead_x) << level, ox, ix)
        tz = face_time((cz + ahead_z) << level, oz, iz)
        t_exit = min(tx, tz)
        t_leave = min(t_exit, t_end)
        accepted = cone_level(t_leave, radius, spread, depth)
        if level < accepted:
            if level >= top_level:
                return t, cells, -1, -1, 0
            cx >>= 1
            cz >>= 1
            level += 1
            width, depth_cells, offset = level_shape(columns, level)
            continue
        round_up = (1 << accepted) - 1
        top = (tops[cell] + round_up) & ~round_up if inside else 0
        if (clear_of_cell(oy, dy, iy, t, t_exit, t_leave, top, gap_floor, gap_ceiling, cell,
                          round_up)
                or top == 0):
            if not t_exit < t_end:
                # Out of the top cell: nothing lies past it, and no node larger than it
                # is taken on the way.
                return t, cells, MISSED_ALL, -1, 0
            t = t_exit
            cx, cz, next_level = step_across(cx, cz, level, tx, tz, t_exit, step_x, step_z,
                                             top_level)
            if next_level != level:
                level = next_level
                width, depth_cells, offset = level_shape(columns, level)
            continue
        if level > accepted:
            cx, cz, level = step_down(cx, cz, level, ox, dx, ix, oz, dz, iz, t)
            width, depth_cells, offset = level_shape(columns, level)
            continue
        return t, cells, cx, cz, level


@borrowing
def trace_cone_over_columns(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmin: float,
    inner_nodes: np.ndarray, depth: int, radius: float, spread: float, scratch, columns,
) -> tuple[int, int, float, int, int]:
    """``traversal.trace_ray`` of a cone-LOD primary ray (``stop_level`` the voxels, no
    ``tmax``) through the pyramid first: the same node, level, time and entry face; the
    steps count the pyramid's cells, then the octree's nodes or one for a landing. It is
    ``walk_cone_over_columns`` then ``settle_cone_walk``."""
    walk = walk_cone_over_columns(ox, oy, oz, dx, dy, dz, tmin, radius, spread, depth,
                                  columns)
    return settle_cone_walk(ox, oy, oz, dx, dy, dz, tmin, inner_nodes, depth, radius, spread,
                            scratch, columns, walk)


@njit(cache=True, nogil=True, inline="always")
def prefetch_cone_landing(columns, walk) -> None:
    """Start loading what ``settle_cone_walk`` reads to land a walk on its cell's top node
    (``surface_approach.prefetch_landing``)."""
    _, _, cx, cz, level = walk
    if cx >= 0 and level < columns.level_width.shape[0]:
        prefetch_landing(columns, cx, cz, level)


@njit(cache=True, nogil=True, inline="always")
def settle_cone_walk(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmin: float,
    inner_nodes: np.ndarray, depth: int, radius: float, spread: float, scratch, columns,
    walk,
) -> tuple[int, int, float, int, int]:
    """``trace_cone_over_columns``'s answer from its walk: the cell's top node where the
    cone takes it, else the octree's from the walk's time."""
    t, cells, cx, cz, level = walk
    if cx == MISSED_ALL:
        return MISS, 0, math.inf, NO_NORMAL, cells
    if cx >= 0 and level < depth:  # (a cone that takes the root takes it at its entry)
        y, t_hit, normal = top_node_hit(ox, oy, oz, dx, dy, dz, tmin, t, math.inf, cx, cz,
                                        level, columns)
        # The cone takes the top node where it accepts exactly its level at the node's
        # entry: no larger node around it, entered no later, yet.
        if y >= 0 and cone_level(t_hit, radius, spread, depth) == level:
            # (A voxel's node from the pyramid rather than the root made 16-ray renders of
            # the 2048² mountain 1.06-1.07× as fast from the top, 1.02-1.04× elsewhere.)
            node = landed_node(inner_nodes, depth, level, cx, cz, y, scratch, columns)
            return node, depth - level, t_hit, normal, cells + 1
    node, node_level, t_hit, normal, steps = traverse(
        ox, oy, oz, dx, dy, dz, tmin, math.inf, inner_nodes, depth, depth, radius, spread,
        scratch, False, max(t, tmin))
    return node, node_level, t_hit, normal, cells + steps
