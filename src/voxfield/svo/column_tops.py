"""Column tops: how high each vertical column of voxels reaches, as a maximum pyramid.

Rays towards the sky (the bake's sky and sun rays) leave the ground and then run above it,
where an octree still walks many small nodes: every cube the ray passes reaches down into
the ground beside it. In a pyramid of column tops (a "maximum mipmap", as height-field
tracers use, after Tevs, Ihrke and Seidel 2008) a rising ray that is above an area's highest
voxel when it enters the area stays above it, so it skips the whole area in one step. The
pyramid also keeps where each column's top run of voxels begins, so a ray that dips below a
column's top and meets that run is known to be blocked without the octree, and the empty gap
under that run per area (above the highest thing below a gap, below the lowest run bottom),
so a ray under an area's runs (under a canopy, inside a hollow shell) skips it too.
``kernels.upward_rays`` walks it; both are derived from the voxels alone, so they are exact.

Level 0 has one cell per column ``(x, z)`` of the voxels' footprint, ``0 <= x < width``; a
cell of level ``l`` covers ``2^l × 2^l`` columns and holds the largest top among them. A top
is the ``y`` of the top face of a column's highest voxel (0 for an empty column).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

__all__ = ["GAP_OPEN", "MAX_COLUMNS", "ColumnTops", "column_tops", "no_column_tops",
           "octree_column_tops", "tops_ahead"]

#: Largest footprint (columns) given a pyramid: 2^27 columns keep it near 1 GiB. Larger
#: worlds trace their rising rays through the octree alone, with the same results.
MAX_COLUMNS = 1 << 27
#: ``gap_ceiling`` of a cell with no voxel: no run above the gap.
GAP_OPEN = 1 << 30


class ColumnTops(NamedTuple):
    """The pyramid as flat arrays a kernel reads (``kernels.upward_rays``); no levels means
    none was built."""

    tops: np.ndarray  # int32, every level's cells, level after level, x-major
    level_offset: np.ndarray  # int64 (levels,): first cell of each level in ``tops``
    level_width: np.ndarray  # int64 (levels,): cells along x
    level_depth: np.ndarray  # int64 (levels,): cells along z
    run_bottom: np.ndarray  # int32 (level-0 cells,): lowest y of each column's top run
    top_node: np.ndarray  # int64 (level-0 cells,): node of each column's top voxel (-1: none);
    #                       empty when the voxels' nodes are not known
    # Cells as in ``tops``: the gap every column of the cell has free under its top run.
    gap_floor: np.ndarray  # int32: the highest ``under_top`` of the cell's columns
    gap_ceiling: np.ndarray  # int32: the lowest ``run_bottom`` of its columns (empty: GAP_OPEN)

    @property
    def under_top(self) -> np.ndarray:
        """Per column (level-0 cell): the top of what lies under its top run's gap, or 0."""
        return self.gap_floor[: self.run_bottom.shape[0]]


def no_column_tops() -> ColumnTops:
    """An empty pyramid: every rising ray goes through the octree."""
    empty = np.zeros(0, np.int64)
    none = np.zeros(0, np.int32)
    return ColumnTops(none, empty, empty, empty, none, empty, none, none)


def column_tops(voxels: np.ndarray, max_columns: int = MAX_COLUMNS,
                first_node: int | None = None) -> ColumnTops:
    """The pyramid of the voxels with corners ``voxels`` (``(n, 3)`` integer, octree units),
    or ``no_column_tops()`` when there are none or the footprint exceeds ``max_columns``.
    ``first_node``: the node index of ``voxels[0]``, the others following in order (an
    octree's leaves, ``Octree.level_slice(depth)``), so each column's top voxel keeps its
    node; None leaves ``top_node`` empty."""
    if len(voxels) == 0:
        return no_column_tops()
    width = int(voxels[:, 0].max()) + 1
    depth = int(voxels[:, 2].max()) + 1
    if width * depth > max_columns:
        return no_column_tops()
    top, bottom, under, top_voxel = _tops_and_run_bottoms(voxels, width, depth)
    levels = [top]
    floors = [under]
    ceilings = [np.where(top == 0, np.int32(GAP_OPEN), bottom)]
    while levels[-1].shape != (1, 1):
        levels.append(_coarser(levels[-1]))
        floors.append(_coarser(floors[-1]))
        ceilings.append(_coarser(ceilings[-1], lowest=True))
    sizes = np.array([level.size for level in levels], np.int64)
    return ColumnTops(
        tops=np.concatenate([level.ravel() for level in levels]),
        level_offset=np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64),
        level_width=np.array([level.shape[0] for level in levels], np.int64),
        level_depth=np.array([level.shape[1] for level in levels], np.int64),
        run_bottom=bottom.ravel(),
        top_node=(np.zeros(0, np.int64) if first_node is None else
                  np.where(top_voxel >= 0, top_voxel + first_node, -1).ravel()),
        gap_floor=np.concatenate([f.ravel() for f in floors]),
        gap_ceiling=np.concatenate([c.ravel() for c in ceilings]),
    )


def octree_column_tops(octree, voxels: np.ndarray | None = None) -> ColumnTops:
    """The pyramid of an octree's voxels, worked out once per structure (``Octree.derived``);
    ``voxels``, the octree's leaf corners, saves working them out again."""
    def build() -> ColumnTops:
        corners = octree.node_coords(octree.depth) if voxels is None else voxels
        return column_tops(corners, first_node=octree.level_slice(octree.depth).start)
    return octree.derived(("column_tops",), build)


def tops_ahead(columns: ColumnTops, step_x: int, step_z: int) -> np.ndarray:
    """Per cell of every level (as ``columns.tops``), the highest top of the cell and of
    its neighbours one cell ahead along ``x`` (``step_x``: +1 or -1), along ``z`` and along
    both: the cells parallel rays travelling that way reach from a shared rear corner
    (``kernels.upward_rays.parallel_rays_clear``). Beyond the footprint there is nothing."""
    if step_x not in (-1, 1) or step_z not in (-1, 1):
        raise ValueError(f"steps must be +1 or -1, got {step_x}, {step_z}")
    out = np.empty_like(columns.tops)
    for level in range(columns.level_width.shape[0]):
        _highest_ahead(columns.tops, int(columns.level_offset[level]),
                       int(columns.level_width[level]), int(columns.level_depth[level]),
                       step_x, step_z, out)
    return out


@njit(cache=True, nogil=True, parallel=True)
def _highest_ahead(tops: np.ndarray, first: int, width: int, depth: int, step_x: int,
                   step_z: int, out: np.ndarray) -> None:
    """``tops_ahead`` of one level: its cells start at ``first``, x-major."""
    for x in prange(width):
        ahead_x = x + step_x
        has_x = 0 <= ahead_x < width
        for z in range(depth):
            ahead_z = z + step_z
            has_z = 0 <= ahead_z < depth
            highest = tops[first + x * depth + z]
            if has_x:
                highest = max(highest, tops[first + ahead_x * depth + z])
            if has_z:
                highest = max(highest, tops[first + x * depth + ahead_z])
                if has_x:
                    highest = max(highest, tops[first + ahead_x * depth + ahead_z])
            out[first + x * depth + z] = highest


def _coarser(level: np.ndarray, lowest: bool = False) -> np.ndarray:
    """The next level: the maximum of each 2×2 block of cells (an odd edge pads with 0), or
    with ``lowest`` the minimum (padding with ``GAP_OPEN``)."""
    w, d = (level.shape[0] + 1) // 2, (level.shape[1] + 1) // 2
    padded = np.full((2 * w, 2 * d), GAP_OPEN if lowest else 0, level.dtype)
    padded[: level.shape[0], : level.shape[1]] = level
    blocks = padded.reshape(w, 2, d, 2)
    return blocks.min(axis=(1, 3)) if lowest else blocks.max(axis=(1, 3))


@njit(cache=True, nogil=True)
def _column_heights(voxels: np.ndarray, width: int, depth: int):
    """Each voxel's ``y`` bucketed by column (counting sort): per-column start offsets, the
    heights and the voxels' indices."""
    starts = np.zeros(width * depth + 1, np.int64)
    for i in range(voxels.shape[0]):
        starts[voxels[i, 0] * depth + voxels[i, 2] + 1] += 1
    for c in range(width * depth):
        starts[c + 1] += starts[c]
    fill = starts[:-1].copy()
    heights = np.empty(voxels.shape[0], np.int32)
    index = np.empty(voxels.shape[0], np.int64)
    for i in range(voxels.shape[0]):
        c = voxels[i, 0] * depth + voxels[i, 2]
        heights[fill[c]] = voxels[i, 1]
        index[fill[c]] = i
        fill[c] += 1
    return starts, heights, index


@njit(cache=True, nogil=True)
def _column_block(first: int, last: int, depth: int, starts: np.ndarray, heights: np.ndarray,
                  index: np.ndarray, top: np.ndarray, bottom: np.ndarray, under: np.ndarray,
                  top_voxel: np.ndarray) -> None:
    """Tops, top-run bottoms, tops under the runs and top voxels of the columns
    ``x = first..last-1`` (every ``z``)."""
    present = np.zeros(0, np.bool_)  # per column: is there a voxel at y = lowest + index?
    for x in range(first, last):
        for z in range(depth):
            c = x * depth + z
            begin, end = starts[c], starts[c + 1]
            if begin == end:
                continue
            low = heights[begin]
            high = heights[begin]
            highest = begin
            for k in range(begin + 1, end):
                low = min(low, heights[k])
                if heights[k] > high:
                    high = heights[k]
                    highest = k
            if present.shape[0] < high - low + 1:
                present = np.zeros(high - low + 1, np.bool_)
            for k in range(begin, end):
                present[heights[k] - low] = True
            run = high
            while run > low and present[run - 1 - low]:
                run -= 1
            below = run - 1  # the highest voxel under the gap below the run, if any
            while below >= low and not present[below - low]:
                below -= 1
            for k in range(begin, end):
                present[heights[k] - low] = False
            top[x, z] = high + 1
            bottom[x, z] = run
            under[x, z] = below + 1 if below >= low else 0
            top_voxel[x, z] = index[highest]


@njit(cache=True, nogil=True, parallel=True)
def _tops_and_run_bottoms(voxels: np.ndarray, width: int, depth: int):
    """Per column, the top (highest voxel's ``y`` + 1, 0 when empty), the lowest ``y`` of
    the unbroken run of voxels that ends there (0 when empty), the top of the highest voxel
    under the gap below that run (0 when none) and the index of the highest voxel (-1 when
    empty)."""
    starts, heights, index = _column_heights(voxels, width, depth)
    top = np.zeros((width, depth), np.int32)
    bottom = np.zeros((width, depth), np.int32)
    under = np.zeros((width, depth), np.int32)
    top_voxel = np.full((width, depth), -1, np.int64)
    blocks = 64
    per_block = (width + blocks - 1) // blocks
    for b in prange(blocks):
        _column_block(min(width, b * per_block), min(width, (b + 1) * per_block), depth,
                      starts, heights, index, top, bottom, under, top_voxel)
    return top, bottom, under, top_voxel
