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

from voxfield.kernels.column_walk import RECORD_FIELD_BITS, TOP_RUN_NODES
from voxfield.kernels.lane_walk import LANE_WALK_PAYS

__all__ = ["GAP_OPEN", "GAP_OPEN_16", "MAX_COLUMNS", "RECORD_FIELD_BITS", "TOP_RUN_NODES",
           "ColumnTops",
           "column_tops", "gap_open", "height_type", "no_column_tops", "octree_column_tops",
           "tops_ahead"]

#: Largest footprint (columns) given a pyramid: 2^27 columns keep it near 1 GiB. Larger
#: worlds trace their rising rays through the octree alone, with the same results.
MAX_COLUMNS = 1 << 27
#: ``gap_ceiling`` (and ``floors``) of a cell with no voxel, above every height: no run
#: above the gap. Pyramids of worlds under ``GAP_OPEN_16`` voxels high keep their heights
#: as int16, which walks read in half the cache lines (2048² mountain terrain, one ray a
#: pixel: the column walk 1.1-1.2× as fast); higher worlds keep int32 and ``GAP_OPEN``, the
#: largest value a record's field holds. Worlds that reach ``GAP_OPEN`` (2^20 voxels high,
#: octrees of depth 21 and more) get no pyramid: every ray goes through the octree alone.
GAP_OPEN = (1 << (RECORD_FIELD_BITS - 1)) - 1
GAP_OPEN_16 = (1 << 15) - 1


def height_type(highest_top: int) -> type:
    """The integer type a pyramid keeps its heights in, for tops up to ``highest_top``."""
    return np.int16 if highest_top < GAP_OPEN_16 else np.int32


def gap_open(columns_or_type) -> int:
    """``GAP_OPEN`` as a pyramid (or its height type) stores it."""
    tops = getattr(columns_or_type, "tops", None)
    dtype = np.dtype(columns_or_type if tops is None else tops.dtype)
    return GAP_OPEN_16 if dtype == np.int16 else GAP_OPEN


class ColumnTops(NamedTuple):
    """The pyramid as flat arrays a kernel reads (``kernels.upward_rays``); no levels means
    none was built."""

    # Heights (tops, run bottoms, gaps, floors) are int16 or int32 (``height_type``).
    tops: np.ndarray  # every level's cells, level after level, x-major
    level_offset: np.ndarray  # int64 (levels,): first cell of each level in ``tops``
    level_width: np.ndarray  # int64 (levels,): cells along x
    level_depth: np.ndarray  # int64 (levels,): cells along z
    # Cells as in ``tops``: the lowest y of each column's top run (level 0) and, for a cell
    # of level l, the lowest y (a multiple of 2^l) from which every node of side 2^l up to
    # the cell's top node holds a voxel, as far as its children's runs show (``_coarser_runs``)
    run_bottom: np.ndarray
    top_nodes: np.ndarray  # int32 (level-0 cells × TOP_RUN_NODES,): per column, the nodes of
    #                        its top run's highest voxels, top down (-1 past the run's bottom
    #                        or in an empty column); empty when the voxels' nodes are not
    #                        known or exceed int32
    # Cells as in ``tops``: the gap every column of the cell has free under its top run.
    gap_floor: np.ndarray  # the highest ``under_top`` of the cell's columns
    gap_ceiling: np.ndarray  # the lowest ``run_bottom`` of its columns (empty: ``gap_open``)
    # Cells as in ``tops``: the lowest voxel's ``y`` among the cell's columns (empty:
    # ``gap_open``), so that every voxel of a cell lies in ``[floors, tops)``.
    floors: np.ndarray
    # Per cell as in ``tops``: top, gap floor and gap ceiling as three signed fields of
    # ``RECORD_FIELD_BITS`` in one int64 (``kernels.lane_walk`` gathers one per cell); empty
    # where no walk reads them (``column_tops``'s ``records``).
    cell_records: np.ndarray

    @property
    def under_top(self) -> np.ndarray:
        """Per column (level-0 cell): the top of what lies under its top run's gap, or 0."""
        return self.gap_floor[: int(self.level_width[0] * self.level_depth[0])]


def no_column_tops() -> ColumnTops:
    """An empty pyramid: every rising ray goes through the octree."""
    empty = np.zeros(0, np.int64)
    none = np.zeros(0, height_type(0))  # the common height type: kernels compile once
    return ColumnTops(none, empty, empty, empty, none, np.zeros(0, np.int32), none, none, none,
                      empty)


def column_tops(voxels: np.ndarray, max_columns: int = MAX_COLUMNS,
                first_node: int | None = None, records: bool = LANE_WALK_PAYS) -> ColumnTops:
    """The pyramid of the voxels with corners ``voxels`` (``(n, 3)`` integer, octree units),
    or ``no_column_tops()`` when there are none, the footprint exceeds ``max_columns`` or
    the voxels reach ``GAP_OPEN``.
    ``first_node``: the node index of ``voxels[0]``, the others following in order (an
    octree's leaves, ``Octree.level_slice(depth)``), so each column's top run keeps the
    nodes of its highest voxels; None (or node indices past int32) leaves ``top_nodes``
    empty. ``records``: whether to pack ``cell_records`` (8 bytes a cell, 42 MiB at 2048²),
    by default only where the walks read them (``kernels.lane_walk.LANE_WALK_PAYS``)."""
    if len(voxels) == 0:
        return no_column_tops()
    width = int(voxels[:, 0].max()) + 1
    depth = int(voxels[:, 2].max()) + 1
    highest_top = int(voxels[:, 1].max()) + 1
    if width * depth > max_columns or highest_top >= GAP_OPEN:
        return no_column_tops()
    shapes = [(width, depth)]
    while shapes[-1] != (1, 1):
        shapes.append(((shapes[-1][0] + 1) // 2, (shapes[-1][1] + 1) // 2))
    sizes = np.array([w * d for w, d in shapes], np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    # Every level lands in its place in one flat array per quantity: no level is built
    # apart and copied after (on a 2048² terrain those copies and the 2×2 reductions as
    # NumPy views took 0.4 s).
    heights = height_type(highest_top)
    open_value = gap_open(heights)
    tops = np.empty(int(sizes.sum()), heights)
    gap_floor = np.empty_like(tops)
    gap_ceiling = np.empty_like(tops)
    floors = np.empty_like(tops)
    bottom = np.empty_like(tops)
    with_nodes = first_node is not None and first_node + len(voxels) <= np.iinfo(np.int32).max
    top_nodes = np.empty(width * depth * TOP_RUN_NODES if with_nodes else 0, np.int32)
    # Scratch for the column sort: the voxel each sorted slot holds, int32 below 2^31
    # voxels (1.4 GB less at 8192²).
    index = np.empty(len(voxels), np.int32 if len(voxels) < 2**31 else np.int64)
    _tops_and_run_bottoms(voxels, width, depth, tops, bottom, gap_floor, floors, top_nodes,
                          first_node if with_nodes else 0, index, open_value)
    _open_ceilings(tops, bottom, gap_ceiling, open_value)
    for level in range(1, len(shapes)):
        w, d = shapes[level - 1]
        source, target = int(offsets[level - 1]), int(offsets[level])
        _coarser(tops, source, w, d, target, False, open_value)
        _coarser(gap_floor, source, w, d, target, False, open_value)
        _coarser(gap_ceiling, source, w, d, target, True, open_value)
        _coarser(floors, source, w, d, target, True, open_value)
        _coarser_runs(tops, bottom, source, w, d, target, level)
    return ColumnTops(
        tops=tops,
        level_offset=offsets,
        level_width=np.array([w for w, _ in shapes], np.int64),
        level_depth=np.array([d for _, d in shapes], np.int64),
        run_bottom=bottom,
        top_nodes=top_nodes,
        gap_floor=gap_floor,
        gap_ceiling=gap_ceiling,
        floors=floors,
        cell_records=(cell_records(tops, gap_floor, gap_ceiling) if records
                      else np.zeros(0, np.int64)),
    )


def cell_records(tops: np.ndarray, gap_floor: np.ndarray, gap_ceiling: np.ndarray) -> np.ndarray:
    """``ColumnTops.cell_records``: per cell, its top, gap floor and gap ceiling as the low,
    second and third signed ``RECORD_FIELD_BITS``-bit fields of one int64, so that a
    vectorised walk loads a cell with one gather (``kernels.lane_walk``). Every height a
    pyramid keeps fits (``GAP_OPEN``), in either height type."""
    records = np.empty(len(tops), np.int64)
    _pack_records(tops, gap_floor, gap_ceiling, records)
    return records


@njit(cache=True, nogil=True, parallel=True)
def _pack_records(tops: np.ndarray, gap_floor: np.ndarray, gap_ceiling: np.ndarray,
                  records: np.ndarray) -> None:
    low = np.int64((1 << RECORD_FIELD_BITS) - 1)
    for i in prange(len(tops)):
        records[i] = ((np.int64(tops[i]) & low)
                      | ((np.int64(gap_floor[i]) & low) << RECORD_FIELD_BITS)
                      | ((np.int64(gap_ceiling[i]) & low) << (2 * RECORD_FIELD_BITS)))


def octree_column_tops(octree, voxels: np.ndarray | None = None) -> ColumnTops:
    """The pyramid of an octree's voxels, worked out once per structure (``Octree.derived``);
    ``voxels``, the octree's leaf corners, saves working them out again."""
    def build() -> ColumnTops:
        # int32 corners: half the memory of int64 (4.2 GB less on an 8192² terrain's leaves).
        corners = octree.node_coords(octree.depth, np.int32) if voxels is None else voxels
        return column_tops(corners, first_node=octree.level_slice(octree.depth).start)
    return octree.derived(("column_tops",), build)


def tops_ahead(columns: ColumnTops, step_x: int, step_z: int,
               out: np.ndarray | None = None) -> np.ndarray:
    """Per cell of every level (as ``columns.tops``), the highest top of the cell and of
    its neighbours one cell ahead along ``x`` (``step_x``: +1 or -1), along ``z`` and along
    both: the cells parallel rays travelling that way reach from a shared rear corner
    (``kernels.upward_rays.parallel_rays_clear``). Beyond the footprint there is nothing.
    ``out``, an integer array shaped like ``columns.tops``, takes them instead of a new
    one."""
    if step_x not in (-1, 1) or step_z not in (-1, 1):
        raise ValueError(f"steps must be +1 or -1, got {step_x}, {step_z}")
    if out is None:
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


@njit(cache=True, nogil=True, parallel=True)
def _coarser(cells: np.ndarray, first: int, width: int, depth: int, out_first: int,
             lowest: bool, open_value: int) -> None:
    """The next level of the level at ``cells[first:]`` (``width × depth``, x-major), at
    ``cells[out_first:]``: the maximum of each 2×2 block of cells (an odd edge pads with 0),
    or with ``lowest`` the minimum (padding with ``open_value``)."""
    out_depth = (depth + 1) // 2
    for x in prange((width + 1) // 2):
        for z in range(out_depth):
            best = open_value if lowest else 0
            for cx in range(2 * x, min(2 * x + 2, width)):
                for cz in range(2 * z, min(2 * z + 2, depth)):
                    value = cells[first + cx * depth + cz]
                    best = min(best, value) if lowest else max(best, value)
            cells[out_first + x * out_depth + z] = best


@njit(cache=True, nogil=True, parallel=True)
def _coarser_runs(tops: np.ndarray, run_bottom: np.ndarray, first: int, width: int, depth: int,
                  out_first: int, level: int) -> None:
    """``run_bottom`` of level ``level`` from the level below (at ``first``, ``width × depth``
    cells), whose ``tops`` are filled: a node of side ``2^level`` holds a voxel where it
    meets a child's known run (each of the child's nodes there holds one), so the cell's
    known run is the unbroken union of its children's, in nodes of this level, down from
    the top node. The children's runs, not their columns': a bound, which only leaves rays
    to the octree that a finer account would settle. On the 2048² mountain terrain this
    pass costs the pyramid's build 0.02 s (0.23 -> 0.25 s)."""
    size = 1 << level
    out_depth = (depth + 1) // 2
    for x in prange((width + 1) // 2):
        for z in range(out_depth):
            x_cells = range(2 * x, min(2 * x + 2, width))
            z_cells = range(2 * z, min(2 * z + 2, depth))
            top_node = 0
            bottom = 0
            for cx in x_cells:
                for cz in z_cells:
                    child = first + cx * depth + cz
                    high = (tops[child] + size - 1) >> level
                    if tops[child] > 0 and high > top_node:
                        top_node = high
                        bottom = run_bottom[child] >> level
            # Runs that reach the known run's bottom extend it, one at least a round.
            for _ in range(3):
                for cx in x_cells:
                    for cz in z_cells:
                        child = first + cx * depth + cz
                        low = run_bottom[child] >> level
                        if (tops[child] > 0 and ((tops[child] + size - 1) >> level) >= bottom
                                and low < bottom):
                            bottom = low
            run_bottom[out_first + x * out_depth + z] = bottom << level


@njit(cache=True, nogil=True, parallel=True)
def _open_ceilings(tops: np.ndarray, bottom: np.ndarray, gap_ceiling: np.ndarray,
                   open_value: int) -> None:
    """Level 0 of ``gap_ceiling``: each column's run bottom, ``open_value`` where it is
    empty."""
    for c in prange(bottom.shape[0]):
        gap_ceiling[c] = open_value if tops[c] == 0 else bottom[c]


@njit(cache=True, nogil=True)
def _column_heights(voxels: np.ndarray, width: int, depth: int, index: np.ndarray):
    """Each voxel's ``y`` bucketed by column (counting sort): per-column start offsets and
    the heights, with the voxels' indices written to ``index``."""
    starts = np.zeros(width * depth + 1, np.int64)
    for i in range(voxels.shape[0]):
        starts[voxels[i, 0] * depth + voxels[i, 2] + 1] += 1
    for c in range(width * depth):
        starts[c + 1] += starts[c]
    fill = starts[:-1].copy()
    heights = np.empty(voxels.shape[0], np.int32)
    for i in range(voxels.shape[0]):
        c = voxels[i, 0] * depth + voxels[i, 2]
        heights[fill[c]] = voxels[i, 1]
        index[fill[c]] = i
        fill[c] += 1
    return starts, heights


@njit(cache=True, nogil=True)
def _column_block(first: int, last: int, depth: int, starts: np.ndarray, heights: np.ndarray,
                  index: np.ndarray, top: np.ndarray, bottom: np.ndarray, under: np.ndarray,
                  lowest: np.ndarray, top_nodes: np.ndarray, first_node: int) -> None:
    """Tops, top-run bottoms, tops under the runs, lowest voxels and top-run nodes (when
    ``top_nodes`` has room for them) of the columns ``x = first..last-1`` (every ``z``)."""
    present = np.zeros(0, np.int64)  # per y above the column's lowest: its voxel's slot + 1
    with_nodes = top_nodes.shape[0] > 0
    for x in range(first, last):
        for z in range(depth):
            c = x * depth + z
            begin, end = starts[c], starts[c + 1]
            if begin == end:
                continue
            low = heights[begin]
            high = heights[begin]
            for k in range(begin + 1, end):
                low = min(low, heights[k])
                high = max(high, heights[k])
            if present.shape[0] < high - low + 1:
                present = np.zeros(high - low + 1, np.int64)
            for k in range(begin, end):
                present[heights[k] - low] = k + 1
            run = high
            while run > low and present[run - 1 - low] > 0:
                run -= 1
            below = run - 1  # the highest voxel under the gap below the run, if any
            while below >= low and present[below - low] == 0:
                below -= 1
            if with_nodes:
                for k in range(TOP_RUN_NODES):
                    y = high - k
                    if y >= run:
                        top_nodes[c * TOP_RUN_NODES + k] = first_node + index[
                            present[y - low] - 1]
            for k in range(begin, end):
                present[heights[k] - low] = 0
            top[c] = high + 1
            bottom[c] = run
            under[c] = below + 1 if below >= low else 0
            lowest[c] = low


@njit(cache=True, nogil=True, parallel=True)
def _tops_and_run_bottoms(voxels: np.ndarray, width: int, depth: int, top: np.ndarray,
                          bottom: np.ndarray, under: np.ndarray, lowest: np.ndarray,
                          top_nodes: np.ndarray, first_node: int, index: np.ndarray,
                          open_value: int) -> None:
    """Per column (the first ``width × depth`` entries, x-major), the top (highest voxel's
    ``y`` + 1, 0 when empty), the lowest ``y`` of the unbroken run of voxels that ends there
    (0 when empty), the top of the highest voxel under the gap below that run (0 when none),
    the lowest voxel's ``y`` (``open_value`` when empty) and, when ``top_nodes`` is not empty,
    ``first_node`` plus the indices of the run's highest voxels (``ColumnTops.top_nodes``).
    ``index``: scratch, one entry per voxel."""
    starts, heights = _column_heights(voxels, width, depth, index)
    columns = width * depth
    for c in prange(columns):
        top[c] = 0
        bottom[c] = 0
        under[c] = 0
        lowest[c] = open_value
    for i in prange(top_nodes.shape[0]):
        top_nodes[i] = -1
    blocks = 64
    per_block = (width + blocks - 1) // blocks
    for b in prange(blocks):
        _column_block(min(width, b * per_block), min(width, (b + 1) * per_block), depth,
                      starts, heights, index, top, bottom, under, lowest, top_nodes,
                      first_node)
