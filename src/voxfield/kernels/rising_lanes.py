"""Rising any-hit walks (``upward_rays.rising_ray_query``) of many rays at once, one ray per
SIMD lane.

The sun bake's sky rays and the batch any-hit queries (``ray_batch.occlude_rays``) walk the
column-top pyramid one ray after another, and each of a walk's decisions ("above the cell,
in its gap, or down a level?") that the branch predictor gets wrong stalls it. Here, as in
``lane_walk`` (whose lanes, groups, selects and packed cell records this module shares),
``LANES`` rays take one cell each per pass, every decision a select, and a lane whose ray
stops takes the next ray of the queue. A ray's verdict, time and steps are
``rising_ray_query``'s, bit for bit: the same operations on the same values. A walk that
stops below a column's top is settled against the column's top run when it is recorded,
one scalar read for the few rays that get there.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.column_walk import cell_holding
from voxfield.kernels.lane_walk import (
    GROUPS,
    LANE_WALK_PAYS,
    LANES,
    SLOTS,
    lane_child,
    next_lane_cell,
    pick,
    unpack_record,
)
from voxfield.kernels.memory_hints import prefetch
from voxfield.kernels.scalar_ops import face_time
from voxfield.kernels.stack_arrays import stack_matrix
from voxfield.kernels.upward_rays import (
    BLOCKED,
    CLEAR,
    MIN_RISE,
    UNDECIDED,
    rising_ray_query,
    rising_walk_start,
)

#: Columns of a queued rising ray: ``ox, oy, oz, dx, dy, dz, tmax, t_clear``
#: (``rising_ray_query``'s arguments; ``t_clear`` 0 walks from the origin).
RISING_RAY_COLUMNS = 8

# Rows of the lanes' float state: the ray as ``rising_ray_query`` prepares it, its time and
# where it stops.
_OX, _IX, _OY, _IY, _OZ, _IZ, _T, _TMAX = range(8)
_FLOAT_ROWS = 8
# Rows of the integer state: the cell and its level; cells visited; whether the ray walks
# and whether it stopped below a column's top; its row in the queue; the face ahead and the
# step on x and z; the next pass's cell index and whether that cell is off the footprint.
(_CX, _CZ, _LEVEL, _STEPS, _LIVE, _BELOW, _RAY, _AHEAD_X, _AHEAD_Z, _STEP_X, _STEP_Z, _CELL,
 _OUTSIDE) = range(13)
_INT_ROWS = 13


@njit(cache=True, nogil=True)
def new_rising_walks(count: int):
    """Rows for ``count`` queued rising rays (``RISING_RAY_COLUMNS``, ``t_clear`` 0) and
    their walks' verdicts, times and steps."""
    return (np.zeros((count, RISING_RAY_COLUMNS)), np.empty(count, np.int64), np.empty(count),
            np.empty(count, np.int64))


@njit(cache=True, nogil=True, inline="always")
def lanes_walk_rising(columns) -> bool:
    """Whether ``walk_rising_rays`` walks ``columns``' rays in lanes: where they pay
    (``LANE_WALK_PAYS``) and the pyramid packs its cell records."""
    return LANE_WALK_PAYS and columns.cell_records.shape[0] > 0


@borrowing
def walk_rising_rays(rays: np.ndarray, count: int, columns, verdicts: np.ndarray,
                     times: np.ndarray, steps: np.ndarray) -> None:
    """``rising_ray_query`` of the queued rays ``rays[:count]`` (``RISING_RAY_COLUMNS``) into
    ``verdicts``, ``times`` and ``steps``: in lanes where they pay and the pyramid has cell
    records, else one ray after another."""
    if lanes_walk_rising(columns):
        walk_rising_in_lanes(rays, count, columns, verdicts, times, steps)
        return
    for k in range(count):
        verdicts[k], times[k], steps[k] = rising_ray_query(
            rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], rays[k, 6],
            columns, rays[k, 7])


@borrowing
def walk_rising_in_lanes(rays: np.ndarray, count: int, columns, verdicts: np.ndarray,
                         times: np.ndarray, steps: np.ndarray) -> None:
    """``walk_rising_rays`` in lanes, ``SLOTS`` rays at a time, a lane whose ray stops taking
    the next: ``columns`` must have ``cell_records``. Compiled for targets without AVX-512
    as well (the tests walk in lanes everywhere), where it is slower than one by one."""
    floats = stack_matrix(_FLOAT_ROWS, SLOTS, np.float64)
    ints = stack_matrix(_INT_ROWS, SLOTS, np.int64)
    walking = stack_matrix(1, GROUPS, np.int64)[0]
    # Every lane starts as one that has stopped with no ray: the start is compiled once.
    for lane in range(SLOTS):
        ints[_LIVE, lane] = 0
        ints[_RAY, lane] = -1
    queued = 0
    for group in range(GROUPS):
        walking[group], queued = _refill_group(rays, count, queued, columns, floats, ints,
                                               group * LANES, verdicts, times, steps)
    busy = True
    while busy:
        busy = False
        for group in range(GROUPS):
            if walking[group] > 0:
                first = group * LANES
                live = _rising_pass(floats, ints, columns, first)
                if live < walking[group] and queued < count:
                    live, queued = _refill_group(rays, count, queued, columns, floats, ints,
                                                 first, verdicts, times, steps)
                walking[group] = live
                for lane in range(first, first + LANES):
                    prefetch(columns.cell_records, np.uint64(ints[_CELL, lane]))
                busy = True
    for lane in range(SLOTS):
        _record_lane(floats, ints, columns, lane, verdicts, times, steps)


@borrowing
def _refill_group(rays: np.ndarray, count: int, queued: int, columns, floats: np.ndarray,
                  ints: np.ndarray, first: int, verdicts: np.ndarray, times: np.ndarray,
                  steps: np.ndarray) -> tuple[int, int]:
    """Record the rays that stopped in the group from ``first`` and give their lanes, and
    any idle, the next rays that walk: ``(rays walking in the group, next ray not yet
    taken)``. Compiled apart, as most passes stop no ray."""
    live = 0
    for lane in range(first, first + LANES):
        if ints[_LIVE, lane] == 0:
            _record_lane(floats, ints, columns, lane, verdicts, times, steps)
            # An idle lane still computes: keep its values finite, its cell in the pyramid.
            for row in range(_FLOAT_ROWS):
                floats[row, lane] = 0.0
            for row in range(_INT_ROWS):
                ints[row, lane] = 0
            ints[_RAY, lane] = -1
            while queued < count:
                queued += 1
                if _start_lane(rays, queued - 1, columns, floats, ints, lane, verdicts, times,
                               steps):
                    break
        live += ints[_LIVE, lane]
    return live, queued


@njit(cache=True, nogil=True, inline="always")
def _start_lane(rays: np.ndarray, k: int, columns, floats: np.ndarray, ints: np.ndarray,
                lane: int, verdicts: np.ndarray, times: np.ndarray, steps: np.ndarray) -> bool:
    """Put ray ``k`` in the cleared ``lane`` as ``rising_ray_query`` starts it, or record its
    answer where it takes no step and leave the lane (False)."""
    ox, oy, oz, dx, dy, dz = rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5]
    tmax, t_clear = rays[k, 6], rays[k, 7]
    level_width, level_depth = columns.level_width, columns.level_depth
    if level_width.shape[0] == 0 or not dy > MIN_RISE:
        _record(verdicts, times, steps, k, UNDECIDED, 0.0, 0)
        return False
    ox, dx, ix, oz, dz, iz, cx, cz, toward = rising_walk_start(ox, dx, oz, dz, level_width,
                                                                level_depth)
    if toward:
        _record(verdicts, times, steps, k, UNDECIDED, 0.0, 0)
        return False
    t = 0.0
    if t_clear > 0.0:
        if not t_clear < tmax:
            _record(verdicts, times, steps, k, CLEAR, t_clear, 0)
            return False
        t = t_clear
        cx = cell_holding(ox, dx, ix, t, 0, -1, level_width[0])
        cz = cell_holding(oz, dz, iz, t, 0, -1, level_depth[0])
    if cx < 0 or cz < 0 or cx >= level_width[0] or cz >= level_depth[0]:
        _record(verdicts, times, steps, k, CLEAR, t, 0)  # beside the footprint, leaving it
        return False
    state = (ox, ix, oy, 1.0 / dy, oz, iz, t, tmax)  # the float rows, in order
    for row in range(_FLOAT_ROWS):
        floats[row, lane] = state[row]
    ints[_CX, lane] = cx
    ints[_CZ, lane] = cz
    # The face ahead on each axis; for a zero component (mid-cell, infinite inverse) the
    # face above, crossed at +inf, as ``rising_ray_query``'s explicit infinity.
    ints[_AHEAD_X, lane] = 0 if dx < 0.0 else 1
    ints[_AHEAD_Z, lane] = 0 if dz < 0.0 else 1
    ints[_STEP_X, lane] = 1 if dx > 0.0 else -1
    ints[_STEP_Z, lane] = 1 if dz > 0.0 else -1
    ints[_CELL, lane] = columns.level_offset[0] + cx * level_depth[0] + cz
    ints[_RAY, lane] = k
    ints[_LIVE, lane] = 1
    return True


@njit(cache=True, nogil=True, inline="always")
def _record(verdicts: np.ndarray, times: np.ndarray, steps: np.ndarray, k: int, verdict: int,
            t: float, cells: int) -> None:
    verdicts[k] = verdict
    times[k] = t
    steps[k] = cells


@njit(cache=True, nogil=True, inline="always")
def _record_lane(floats: np.ndarray, ints: np.ndarray, columns, lane: int,
                 verdicts: np.ndarray, times: np.ndarray, steps: np.ndarray) -> None:
    """Record the answer of the ray that stopped in ``lane``, if any, and leave the lane
    idle. A ray below its column's top is ``BLOCKED`` when it meets the column's top run
    there (a box: the contract's interval test is exact), else ``UNDECIDED``."""
    k = ints[_RAY, lane]
    if k < 0:
        return
    ints[_RAY, lane] = -1
    t = floats[_T, lane]
    verdict = CLEAR
    if ints[_BELOW, lane] != 0:
        cx, cz = ints[_CX, lane], ints[_CZ, lane]
        ox, ix, oy, iy = floats[_OX, lane], floats[_IX, lane], floats[_OY, lane], floats[_IY, lane]
        oz, iz, tmax = floats[_OZ, lane], floats[_IZ, lane], floats[_TMAX, lane]
        column = cx * columns.level_depth[0] + cz
        top = columns.tops[columns.level_offset[0] + column]
        t_exit = min(face_time(cx + ints[_AHEAD_X, lane], ox, ix),
                     face_time(cz + ints[_AHEAD_Z, lane], oz, iz))
        bottom = columns.run_bottom[column]
        verdict = UNDECIDED
        if max(t, face_time(bottom, oy, iy)) < min(min(t_exit, tmax), face_time(top, oy, iy)):
            verdict = BLOCKED
    _record(verdicts, times, steps, k, verdict, t, ints[_STEPS, lane])


@njit(cache=True, nogil=True, inline="always")
def _rising_pass(floats: np.ndarray, ints: np.ndarray, columns, first: int) -> int:
    """One cell of ``rising_ray_query`` for every walking lane of the group from ``first``,
    as selects; the rays still walking. A ray that stops keeps its cell, time and steps;
    ``_BELOW`` says it stopped below a column's top (else it is clear). Each lane's cell
    index is worked out a pass ahead, so a pass starts with the loads of its records."""
    records, level_offset = columns.cell_records, columns.level_offset
    width0, depth0 = columns.level_width[0], columns.level_depth[0]
    top_level = columns.level_width.shape[0] - 1
    ox_, ix_, oy_, iy_ = floats[_OX], floats[_IX], floats[_OY], floats[_IY]
    oz_, iz_, t_, tmax_ = floats[_OZ], floats[_IZ], floats[_T], floats[_TMAX]
    cx_, cz_, level_, steps_, live_ = ints[_CX], ints[_CZ], ints[_LEVEL], ints[_STEPS], ints[_LIVE]
    below_, ahead_x_, ahead_z_ = ints[_BELOW], ints[_AHEAD_X], ints[_AHEAD_Z]
    step_x_, step_z_, cell_, outside_ = ints[_STEP_X], ints[_STEP_Z], ints[_CELL], ints[_OUTSIDE]
    live = 0
    for index in range(LANES):
        lane = np.uint64(first + index)  # unsigned: no wrap-around select in the address
        walking = live_[lane] != 0
        visits = walking & (outside_[lane] == 0)
        record = records[np.uint64(cell_[lane])]
        ox, ix, oy, iy = ox_[lane], ix_[lane], oy_[lane], iy_[lane]
        oz, iz, t, tmax = oz_[lane], iz_[lane], t_[lane], tmax_[lane]
        cx, cz, level = cx_[lane], cz_[lane], level_[lane]
        ahead_x, ahead_z = ahead_x_[lane], ahead_z_[lane]
        top, floor, ceiling = unpack_record(record)
        tx = (float((cx + ahead_x) << level) - ox) * ix
        tz = (float((cz + ahead_z) << level) - oz) * iz
        t_exit = min(tx, tz)
        # Above the cell's voxels when it enters and rising, or in the gap every column of
        # the cell leaves under its top run all the way across (``column_walk.in_the_gap``).
        skip = ((t >= (float(top) - oy) * iy)
                | ((t >= (float(floor) - oy) * iy)
                   & (min(t_exit, tmax) <= (float(ceiling) - oy) * iy)))
        leaves = skip & (not t_exit < tmax)
        # Across to the next cell, a level up when it lies in another parent
        # (``column_walk.step_across``).
        next_cx = cx + pick(tx <= t_exit, step_x_[lane], 0)
        next_cz = cz + pick(tz <= t_exit, step_z_[lane], 0)
        climbs = (level < top_level) & ((((next_cx ^ cx) | (next_cz ^ cz)) >> 1) != 0)
        # Down to the child that holds the ray at ``t``.
        child_cx, child_cz = lane_child(cx, cz, level, ox, ix, oz, iz, ahead_x, ahead_z, t)
        across = visits & skip & (not leaves)
        down = visits & (not skip) & (level > 0)
        below = visits & (not skip) & (level == 0)
        still = visits & (not leaves) & (not below)
        cx = pick(across, pick(climbs, next_cx >> 1, next_cx),
                  pick(down, child_cx, cx))
        cz = pick(across, pick(climbs, next_cz >> 1, next_cz),
                  pick(down, child_cz, cz))
        level = pick(across, pick(climbs, level + 1, level), pick(down, level - 1, level))
        cx_[lane] = cx
        cz_[lane] = cz
        level_[lane] = level
        t_[lane] = pick(across, t_exit, t)
        steps_[lane] += pick(visits, 1, 0)
        live_[lane] = pick(still, 1, 0)
        below_[lane] = pick(below, 1, below_[lane])
        live += pick(still, 1, 0)
        outside_[lane], cell_[lane] = next_lane_cell(cx, cz, level, still, width0, depth0,
                                                    level_offset)
    return live
