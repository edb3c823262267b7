"""Any-hit queries for rising rays over the column-top pyramid (``svo.column_tops``).

A ray with ``dy > 0`` walks the pyramid's cells in 2D, coarse where it can: in a cell whose
highest top it is above when it enters, it stays above every voxel until it leaves (it
only rises), so the cell is skipped whole and the walk climbs a level; below a cell's top
the walk descends. In a single column below its top, a ray that meets the column's top run
of voxels is blocked; one that passes under it (an overhang, a canopy, a hollow shell) and
is above whatever lies below it crosses the column clear, and any other is handed to the
octree from that point on, ``UNDECIDED`` with its time. Under the runs, a cell whose columns
all leave a gap the ray stays in (above every ``under_top``, below every run bottom) is
skipped whole as well, coarse where it can be.

**Exactness.** Every time is the traversal's ``face_time`` of an integer plane, so a skipped
cell holds no voxel whose interval (``kernels.traversal``'s contract) meets the skipped
stretch, nor does a gap or a column passed under its run (the runs above are boxes the ray
stays below, everything else ends at or under the floor it stays above), and a blocked
verdict means a voxel's interval meets ``[0, tmax)``: the answers are those of ``occluded``
over the whole ray, and ``occluded`` from the hand-over time finishes an undecided ray with
the answer the whole ray would get.

**Steps.** Each cell the walk visits counts as one traversal step, as each octree node does.

``parallel_rays_clear`` answers for a bundle of parallel rays at once (a face's shadow rays
towards one sun): the same walk for the bundle's rear corner over the tops of each cell and
the cells just ahead of it, which is clear only when every ray of the bundle is. Where it
stops unanswered every ray is still clear up to there, so each ray's own walk starts there.

``clears_horizon`` settles a clear ray before any walk, from its start column's horizon
slope (``svo.horizons``): one cell read, counted as one step.
"""

from __future__ import annotations

import math

from numba import njit

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.column_walk import cell_holding, in_the_gap, step_across, step_down
from voxfield.kernels.scalar_ops import face_time
from voxfield.kernels.traversal import axis_setup, floor_float

CLEAR = 0
BLOCKED = 1
UNDECIDED = 2
#: Rays flatter than this (``dy``) gain nothing from columns: they go to the octree.
MIN_RISE = 1e-9


@njit(cache=True, nogil=True, inline="always")
def _start_cell(o: float, d: float, inv: float) -> int:
    """The unit cell ``[k, k + 1)`` of one axis the ray is in at ``t = 0`` under the
    contract: a ray on a plane and running down is in the cell below it. Origins far beside
    the footprint are clamped to a cell still beside it (no footprint reaches 2^52), so the
    integer never overflows."""
    k = int(min(max(floor_float(o), -2.0), 4503599627370496.0))
    if d < 0.0 and not 0.0 < face_time(k, o, inv):
        k -= 1
    return k


@njit(cache=True, nogil=True, inline="always")
def rising_walk_start(ox: float, dx: float, oz: float, dz: float, level_width, level_depth):
    """Where a rising walk starts: each horizontal axis as the traversal prepares it
    (``axis_setup``), the start cell, and whether the ray starts beside the footprint
    running towards it (no walk from there: nothing there tells where it enters)."""
    ox, dx, ix = axis_setup(ox, dx)
    oz, dz, iz = axis_setup(oz, dz)
    cx = _start_cell(ox, dx, ix)
    cz = _start_cell(oz, dz, iz)
    toward = ((cx < 0 and dx > 0.0) or (cx >= level_width[0] and dx < 0.0)
              or (cz < 0 and dz > 0.0) or (cz >= level_depth[0] and dz < 0.0))
    return ox, dx, ix, oz, dz, iz, cx, cz, toward


@njit(cache=True, nogil=True, inline="always")
def _heading(d: float) -> tuple[int, int]:
    """``(ahead, step)`` of one axis: the exit plane of cell ``c`` of side ``2^l`` is
    ``(c + ahead) << l``, and the next cell is ``c + step``."""
    return (1, 1) if d > 0.0 else (0, -1)


@njit(cache=True, nogil=True, inline="always")
def quadrant(dx: float, dz: float) -> int:
    """The heading's column of ``svo.horizons.horizon_slopes``: ``2·(dx < 0) + (dz < 0)``.
    A zero component counts as positive: a ray with no ``x`` motion stays in its column,
    which counts as ahead."""
    return (2 if dx < 0.0 else 0) + (1 if dz < 0.0 else 0)


@njit(cache=True, nogil=True, inline="always")
def quadrant_steps(q: int) -> tuple[int, int]:
    """``(step_x, step_z)`` towards the columns ahead of a heading in quadrant ``q``."""
    return (-1 if q >= 2 else 1), (-1 if q % 2 == 1 else 1)


@borrowing(inline="always")
def rising_ray_query(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmax: float, columns,
    t_clear: float = 0.0,
) -> tuple[int, float, int]:
    """``(verdict, t, steps)`` for the ray ``o + t·d``, ``0 <= t < tmax``: ``CLEAR`` (nothing
    blocks it), ``BLOCKED``, or ``UNDECIDED`` from time ``t`` on (trace ``[t, tmax)`` with
    ``occluded``). ``columns`` is a ``ColumnTops``; without levels every ray is undecided
    from 0. A caller that knows ``[0, t_clear)`` clear (``parallel_rays_clear`` found it so
    for a whole face) has the walk start there, in the column holding the ray then."""
    tops, level_offset, level_width, level_depth, run_bottom = columns[:5]
    gap_floor = columns.gap_floor
    gap_ceiling = columns.gap_ceiling
    if level_width.shape[0] == 0 or not dy > MIN_RISE:
        return UNDECIDED, 0.0, 0
    ox, dx, ix, oz, dz, iz, cx, cz, toward = rising_walk_start(ox, dx, oz, dz, level_width,
                                                                level_depth)
    iy = 1.0 / dy
    # Beside the footprint a ray is clear when it runs away from it (as every ray the walk
    # steps out of the footprint does); one that runs towards it starts in the octree.
    if toward:
        return UNDECIDED, 0.0, 0
    ahead_x, step_x = _heading(dx)
    ahead_z, step_z = _heading(dz)
    top_level = level_width.shape[0] - 1
    level = 0
    t = 0.0
    steps = 0
    if t_clear > 0.0:
        if not t_clear < tmax:
            return CLEAR, t_clear, steps
        t = t_clear
        cx = cell_holding(ox, dx, ix, t, 0, -1, level_width[0])
        cz = cell_holding(oz, dz, iz, t, 0, -1, level_depth[0])
    while True:
        if cx < 0 or cz < 0 or cx >= level_width[level] or cz >= level_depth[level]:
            return CLEAR, t, steps  # beside the footprint and leaving it
        steps += 1
        cell = level_offset[level] + cx * level_depth[level] + cz
        top = tops[cell]
        tx = face_time((cx + ahead_x) << level, ox, ix) if dx != 0.0 else math.inf
        tz = face_time((cz + ahead_z) << level, oz, iz) if dz != 0.0 else math.inf
        t_exit = min(tx, tz)
        # Above the highest voxel of the cell's columns, and rising: skip the cell. So too
        # in the gap every column of the cell leaves under its top run, all the way across.
        if t >= face_time(top, oy, iy) or in_the_gap(oy, dy, iy, t, min(t_exit, tmax),
                                                     gap_floor[cell], gap_ceiling[cell]):
            if not t_exit < tmax:
                return CLEAR, t, steps
            t = t_exit
            cx, cz, level = step_across(cx, cz, level, tx, tz, t_exit, step_x, step_z,
                                        top_level)
            continue
        if level > 0:
            cx, cz, level = step_down(cx, cz, level, ox, dx, ix, oz, dz, iz, t)
            continue
        # One column, and the ray is below its top while in it: does it meet the top run
        # ``[bottom, top)`` there? That run is a box, so the contract's interval test is exact.
        bottom = run_bottom[cx * level_depth[0] + cz]
        if max(t, face_time(bottom, oy, iy)) < min(min(t_exit, tmax), face_time(top, oy, iy)):
            return BLOCKED, t, steps
        return UNDECIDED, t, steps


@borrowing(inline="always")
def parallel_rays_clear(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmax: float, columns,
    tops_ahead,
) -> tuple[bool, int, float]:
    """``(clear, steps, t_clear)``: True when every ray ``p + t·d``,
    ``0 <= t < (y_top - p.y) / dy``, is ``CLEAR``, for every ``p`` at or above ``o`` and ahead
    of it by less than one along ``x`` and ``z`` in the direction of travel (``+`` for a zero
    component), with ``tmax`` the bound for ``o`` (``(y_top - o.y) / dy``): the shadow rays
    of one face towards one sun, from its rear corner. False says nothing about them.

    The walk is ``rising_ray_query``'s for the corner, over ``tops_ahead``
    (``svo.column_tops.tops_ahead`` with the steps of ``d``). At a time ``t`` when the corner
    is in a cell, each ray is in that cell or one of the three ahead of it (it is less than
    one column ahead on each axis, every cell is at least one wide) and no lower: so the
    corner above the highest of those four tops has every ray above what is under it, and
    rising they stay there; the corner leaving the footprint or rising past ``tmax`` has
    every ray past it too. Anything else (a cell the corner is not above at level 0, a start
    beside the footprint running towards it) ends the walk unanswered, with every ray still
    clear over ``[0, t_clear)``, where it stopped: a ray walked on its own after it can start
    there (``rising_ray_query``'s ``t_clear``)."""
    level_offset, level_width, level_depth = columns[1:4]
    if level_width.shape[0] == 0 or not dy > MIN_RISE:
        return False, 0, 0.0
    ox, dx, ix, oz, dz, iz, cx, cz, toward = rising_walk_start(ox, dx, oz, dz, level_width,
                                                                level_depth)
    if toward:
        return False, 0, 0.0
    iy = 1.0 / dy
    ahead_x, step_x = _heading(dx)
    ahead_z, step_z = _heading(dz)
    level = 0
    t = 0.0
    steps = 0
    while 0 <= cx < level_width[level] and 0 <= cz < level_depth[level]:
        steps += 1
        cell = level_offset[level] + cx * level_depth[level] + cz
        tx = face_time((cx + ahead_x) << level, ox, ix) if dx != 0.0 else math.inf
        tz = face_time((cz + ahead_z) << level, oz, iz) if dz != 0.0 else math.inf
        t_exit = min(tx, tz)
        if t >= face_time(tops_ahead[cell], oy, iy):
            if not t_exit < tmax:
                return True, steps, t
            t = t_exit
            cx, cz, level = step_across(cx, cz, level, tx, tz, t_exit, step_x, step_z,
                                        level_width.shape[0] - 1)
            continue
        if level == 0:
            return False, steps, t
        cx, cz, level = step_down(cx, cz, level, ox, dx, ix, oz, dz, iz, t)
    return True, steps, t  # beside the footprint and leaving it


@njit(cache=True, nogil=True, inline="always")
def clears_horizon(ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
                   columns, horizons) -> bool:
    """True when the ray ``o + t·d``, ``t >= 0``, is ``CLEAR``: it starts in a column of the
    footprint at or above its top and rises more steeply than that column's horizon slope
    for its heading (``svo.horizons.horizon_slopes``, empty: never). False says nothing.
    The heading and start column are the walk's (``rising_walk_start``), so a component too
    small to invert counts as zero, as it does for the octree."""
    tops, level_width, level_depth = columns[0], columns[2], columns[3]
    if horizons.shape[0] == 0 or not dy > MIN_RISE:
        return False
    ox, dx, ix, oz, dz, iz, cx, cz, _ = rising_walk_start(ox, dx, oz, dz, level_width,
                                                          level_depth)
    if not (0 <= cx < level_width[0] and 0 <= cz < level_depth[0]):
        return False
    cell = cx * level_depth[0] + cz
    if tops[cell] > oy:
        return False
    slope = horizons[cell, quadrant(dx, dz)]
    return slope < 0.0 or dy * dy >= slope * slope * (dx * dx + dz * dz)
