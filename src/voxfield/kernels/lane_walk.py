"""The column-pyramid walk of many rays at once, one ray per SIMD lane.

``surface_approach.approach_surface`` walks one ray: in every cell it asks "above the
cell, in its gap, or down a level?", the answers change from cell to cell and from ray to
ray, and each one the branch predictor gets wrong stalls the walk. Here ``LANES`` rays take
one cell each per pass and every decision is a select, so the compiler turns the pass into
vector instructions (one gather of the cells' records, masked moves) with no branch on a
ray's route. In a render's batch (``walk_to_voxels_in_lanes``, ``walk_to_nodes_in_lanes``
for coarser nodes) a ray that has stopped idles in its lane until its group's pass finds
none walking; in a queue of ray queries (``walk_queue_in_lanes``) its lane takes the next
ray. ``GROUPS`` groups step in turn, each pass prefetching the cells its group reads next
while the other groups step. Cells, times, verdicts and step counts are
``approach_surface``'s, bit for bit: the same operations on the same values.

Two things make the pass vectorise. Its state lives in ``stack_arrays.stack_matrix``
arrays, which the compiler knows no argument can overlap (arrays passed in might, and a
gather's computed index leaves it no range to check at run time). And each cell's top, gap
floor and gap ceiling come packed in one int64 (``ColumnTops.cell_records``): one 64-bit
gather, where three 16-bit ones were 24 scalar loads; its fields hold int32 heights too.

On the 2048² mountain terrain (512² images, two threads, in one process against the
one-ray walk, both orders, six rounds) renders took 0.80-0.81× the time from the top with 16
rays a pixel, 0.82-0.84× at 45°, and 0.91-0.93× with one ray a pixel; a camera low over the
ground 0.88× (one and 16 rays); on the 512² terrain 0.88-0.92×, one-ray 45° renders (12 ms)
within the noise. Images, depths and steps are the same. The walk is compiled once and
called per batch: compiled into the batch it read 1.00-1.03× as fast, and a first reference
render compiled for 57 s instead of 52 (48 s with the one-ray walk). Those figures are with
AVX-512; see ``LANE_WALK_PAYS`` for AVX2.
"""

from __future__ import annotations

import math

import numpy as np
from numba import config, njit, types
from numba.core.codegen import get_host_cpu_features
from numba.extending import intrinsic, overload

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.column_walk import RECORD_FIELD_BITS
from voxfield.kernels.memory_hints import prefetch
from voxfield.kernels.stack_arrays import stack_matrix
from voxfield.kernels.surface_approach import (
    FROM_CAMERA,
    HANDED_OVER,
    MISSED,
    WALKS,
    prefetch_landing,
    top_node_hit,
    walk_entry,
    walk_plan,
)


def compiles_wide_vectors(features: str) -> bool:
    """Whether kernels compiled for the LLVM feature string ``features`` (``+avx2,-avx512f,
    ...``) have 512-bit vectors (AVX-512)."""
    return "+avx512f" in features.split(",")


#: Whether the primary batches walk in lanes (``kernels.primary.trace_ray_batch``): where
#: Numba compiles for AVX-512, as on the machine of the figures above. Compiled for AVX2 on
#: that machine (``NUMBA_CPU_FEATURES`` without the AVX-512 features) the pass is half as
#: wide and LLVM loads the cells one by one instead of gathering them: renders took 1.4-1.6×
#: the one-ray walk's time, so other targets keep that walk. On a Zen 2 AMD EPYC (AVX2
#: hardware, 2048² mountain terrain, 512² images) the lanes compiled for it rendered at
#: 0.53-0.62× the one-ray walk's speed, top and 45° views, one and 16 rays a pixel.
LANE_WALK_PAYS = compiles_wide_vectors(
    config.CPU_FEATURES if config.CPU_FEATURES is not None else get_host_cpu_features())

#: Rays a group steps side by side: two 512-bit vectors per quantity.
LANES = 16
#: Groups stepping in turn, so that one group's loads overlap the others' work. On the 2048²
#: mountain terrain four groups (in 64-ray batches) made 16-ray renders 1.03-1.05× and
#: one-ray renders 1.08× as fast as two (in batches of 32 or 64), and two 1.00-1.04× as fast
#: as one; eight groups of 8 lanes read as four of 16, eight of 16 (128-ray batches)
#: 0.94-0.99×. Prefetching each group's next cells: 1.03-1.07×.
GROUPS = 4
#: Rays a call walks at a time.
SLOTS = GROUPS * LANES

# Rows of the lanes' float state: the ray as ``approach_surface`` prepares it (``axis_setup``),
# its time and the time it leaves the footprint.
_OX, _IX, _OY, _DY, _IY, _OZ, _IZ, _T, _T_END = range(9)
_FLOAT_ROWS = 9
# Rows of the integer state: the cell and its level; cells skipped in a row and the number
# to skip before climbing; cells visited; whether the ray walks and how it stopped; its
# row in the batch; which face is ahead and the step on x and z; the next pass's cell index
# into the pyramid and whether that cell is off the footprint.
(_CX, _CZ, _LEVEL, _SKIPS, _PATIENCE, _STEPS, _LIVE, _VERDICT, _RAY, _AHEAD_X, _AHEAD_Z,
 _STEP_X, _STEP_Z, _CELL, _OUTSIDE) = range(15)
_INT_ROWS = 15


@borrowing
def walk_to_voxels_in_lanes(rays: np.ndarray, count: int, depth: int, columns,
                            walk_ints: np.ndarray, walk_times: np.ndarray) -> None:
    """``walk_to_nodes_in_lanes`` to voxels (LOD 0), compiled apart: with the level a
    constant the rounding of each cell's top and gap to whole nodes folds away, and the
    16-ray renders of the 2048² mountain terrain ran 1.02-1.03× as fast as through the
    walk to any level."""
    _walk_batch_in_lanes(rays, count, depth, 0, columns, walk_ints, walk_times)


@borrowing
def walk_to_nodes_in_lanes(rays: np.ndarray, count: int, depth: int, finest: int, columns,
                           walk_ints: np.ndarray, walk_times: np.ndarray) -> None:
    """``approach_surface`` to nodes of side ``2^finest`` (LOD ``finest``) of the primary
    rays ``rays[:count]`` (rows ``ox, oy, oz, dx, dy, dz, tmin``) in an octree of
    ``depth``, started as ``surface_approach.walk_plan`` starts rays from the camera, into
    ``walk_ints[k, :4]`` (verdict, cells, cx, cz) and ``walk_times[k, 0]`` (the time),
    ``SLOTS`` rays at a time. ``columns`` must have ``cell_records``; a ray handed over has
    what its settling reads prefetched (``_record_lane``).

    Walked one by one instead, LOD-1 and LOD-2 renders of the 2048² mountain terrain (512²,
    16 rays a pixel) took 1.17-1.20× the time from the top and at 45°, 1.09-1.13× with one
    ray a pixel."""
    _walk_batch_in_lanes(rays, count, depth, finest, columns, walk_ints, walk_times)


@njit(cache=True, nogil=True, inline="always")
def _walk_batch_in_lanes(rays: np.ndarray, count: int, depth: int, finest: int, columns,
                         walk_ints: np.ndarray, walk_times: np.ndarray) -> None:
    """``walk_to_nodes_in_lanes``. A render's batch fills the lanes once. Refilling a lane
    whose ray stops (``walk_queue_in_lanes``) made its 64-ray batches 0.93-0.99× as fast:
    the call in the pass loop costs more than the few lanes it fills there."""
    floats = stack_matrix(_FLOAT_ROWS, SLOTS, np.float64)
    ints = stack_matrix(_INT_ROWS, SLOTS, np.int64)
    walking = stack_matrix(1, GROUPS, np.int64)[0]
    for first in range(0, count, SLOTS):
        # Every lane filled from the rays ``first..`` (``_fill_lane``, inlined here: filled
        # through ``_refill_group``'s call, as a queue's are, renders took 1.05-1.06× the
        # time), and each group's walking lanes counted.
        end = min(count, first + SLOTS)
        for group in range(GROUPS):
            walking[group] = 0
        queued = first
        for lane in range(SLOTS):
            queued = _fill_lane(rays, end, queued, depth, finest, columns, floats, ints, lane,
                                walk_ints, walk_times, FROM_CAMERA, math.inf)
            walking[lane // LANES] += ints[_LIVE, lane]
        busy = True
        while busy:
            busy = False
            for group in range(GROUPS):
                if walking[group] > 0:
                    walking[group] = _lane_pass(floats, ints, columns, group * LANES,
                                                finest)
                    _prefetch_cells(columns, ints, group)
                    busy = True
        for lane in range(SLOTS):
            _record_lane(floats, ints, columns, lane, finest, walk_ints, walk_times)


@borrowing
def walk_queue_in_lanes(rays: np.ndarray, count: int, depth: int, columns,
                        walk_ints: np.ndarray, walk_times: np.ndarray, start: int,
                        tmax: float) -> None:
    """``walk_to_nodes_in_lanes`` to voxels (LOD 0) for any rays over ``[tmin, tmax)``, started
    as ``walk_plan`` starts them from ``start`` (``surface_approach.FROM_CAMERA`` or
    ``FROM_SURFACE``), with a lane whose ray stops taking the next ray not yet walked
    (``_refill_group``): the lanes stay busy until the queue runs dry, where a batch waits for
    its longest walk. Secondary rays on the 2048² mountain terrain (a million from voxel tops,
    one thread): the walks took 0.25-0.29× the one-ray walk's time in 256-ray queues, 0.45-0.47×
    in 64-ray batches without refills."""
    floats = stack_matrix(_FLOAT_ROWS, SLOTS, np.float64)
    ints = stack_matrix(_INT_ROWS, SLOTS, np.int64)
    walking = stack_matrix(1, GROUPS, np.int64)[0]
    # Every lane starts as one that has stopped with no ray, and is filled as such: the
    # lanes' start is compiled once, in ``_refill_group`` (a first call compiles 7 s sooner).
    for lane in range(SLOTS):
        ints[_LIVE, lane] = 0
        ints[_RAY, lane] = -1
    queued = 0
    for group in range(GROUPS):
        walking[group], queued = _refill_group(rays, count, queued, depth, 0, columns,
                                               floats, ints, group * LANES, walk_ints,
                                               walk_times, start, tmax)
    busy = True
    while busy:
        busy = False
        for group in range(GROUPS):
            if walking[group] > 0:
                first = group * LANES
                live = _lane_pass(floats, ints, columns, first, 0)
                if live < walking[group] and queued < count:
                    live, queued = _refill_group(rays, count, queued, depth, 0, columns,
                                                 floats, ints, first, walk_ints, walk_times,
                                                 start, tmax)
                walking[group] = live
                _prefetch_cells(columns, ints, group)
                busy = True
    for lane in range(SLOTS):
        _record_lane(floats, ints, columns, lane, 0, walk_ints, walk_times)


@njit(cache=True, nogil=True, inline="always")
def _prefetch_cells(columns, ints: np.ndarray, group: int) -> None:
    """Start loading the records of the cells the lanes of ``group`` visit next."""
    for lane in range(group * LANES, (group + 1) * LANES):
        prefetch(columns.cell_records, np.uint64(ints[_CELL, lane]))


@njit(cache=True, nogil=True, inline="always")
def _fill_lane(rays: np.ndarray, end: int, queued: int, depth: int, finest: int, columns,
               floats: np.ndarray, ints: np.ndarray, lane: int, walk_ints: np.ndarray,
               walk_times: np.ndarray, start: int, tmax: float) -> int:
    """Put the next ray that walks, from ``queued`` on and before ``end``, in ``lane`` (idle
    when none is left); the rays before it take no step and are recorded. The next ray not
    yet taken."""
    # An idle lane still computes: keep its values finite and its cell in the pyramid.
    for row in range(_FLOAT_ROWS):
        floats[row, lane] = 0.0
    for row in range(_INT_ROWS):
        ints[row, lane] = 0
    ints[_RAY, lane] = -1
    while queued < end:
        k = queued
        queued += 1
        if _start_lane(rays, k, depth, finest, columns, floats, ints, lane, walk_ints,
                       walk_times, start, tmax):
            return queued
    return queued


@borrowing
def _refill_group(rays: np.ndarray, count: int, queued: int, depth: int, finest: int, columns,
                  floats: np.ndarray, ints: np.ndarray, first: int, walk_ints: np.ndarray,
                  walk_times: np.ndarray, start: int, tmax: float) -> tuple[int, int]:
    """Record the rays that stopped in the group from ``first`` and give their lanes, and
    any idle, the next rays: ``(rays walking in the group, next ray not yet taken)``.
    Compiled apart, as most passes stop no ray."""
    live = 0
    for lane in range(first, first + LANES):
        if ints[_LIVE, lane] == 0:
            _record_lane(floats, ints, columns, lane, finest, walk_ints, walk_times)
            queued = _fill_lane(rays, count, queued, depth, finest, columns, floats, ints, lane,
                                walk_ints, walk_times, start, tmax)
        live += ints[_LIVE, lane]
    return live, queued


@njit(cache=True, nogil=True, inline="always")
def _start_lane(rays: np.ndarray, k: int, depth: int, finest: int, columns,
                floats: np.ndarray, ints: np.ndarray, lane: int, walk_ints: np.ndarray,
                walk_times: np.ndarray, start: int, tmax: float) -> bool:
    """Put ray ``k`` in the cleared ``lane`` as ``approach_surface`` starts its walk to
    nodes of side ``2^finest`` (``walk_entry``), or record it where it takes no step and
    leave the lane (False)."""
    tmin = rays[k, 6]
    start_level, patience = walk_plan(tmin, depth, depth - finest, columns, start)[1:]
    (entry, t, t_end, ox, dx, ix, dy, iy, oz, dz, iz, level, cx, cz) = walk_entry(
        rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], tmin, tmax,
        finest, start_level, columns)
    if entry != WALKS:
        record_walk(walk_ints, walk_times, k, entry, t, 0, -1, -1)
        return False
    oy = rays[k, 1]
    ints[_RAY, lane] = k
    ints[_PATIENCE, lane] = patience
    state = (ox, ix, oy, dy, iy, oz, iz, t, t_end)  # the float rows, in order
    for row in range(_FLOAT_ROWS):
        floats[row, lane] = state[row]
    ints[_CX, lane] = cx
    ints[_CZ, lane] = cz
    ints[_LEVEL, lane] = level
    ints[_AHEAD_X, lane] = 0 if dx < 0.0 else 1
    ints[_AHEAD_Z, lane] = 0 if dz < 0.0 else 1
    ints[_STEP_X, lane] = 1 if dx > 0.0 else -1
    ints[_STEP_Z, lane] = 1 if dz > 0.0 else -1
    ints[_CELL, lane] = columns.level_offset[level] + cx * columns.level_depth[level] + cz
    ints[_LIVE, lane] = 1
    return True


@njit(cache=True, nogil=True, inline="always")
def record_walk(walk_ints: np.ndarray, walk_times: np.ndarray, k: int, verdict: int, t: float,
                cells: int, cx: int, cz: int) -> None:
    """Ray ``k``'s walk where a ray batch keeps it (``kernels.primary.new_ray_batch``)."""
    walk_ints[k, 0] = verdict
    walk_ints[k, 1] = cells
    walk_ints[k, 2] = cx
    walk_ints[k, 3] = cz
    walk_times[k, 0] = t


@njit(cache=True, nogil=True, inline="always")
def record_landing(walk_ints: np.ndarray, walk_times: np.ndarray, k: int, y: int, t: float,
                   normal: int) -> None:
    """The voxel row, time and entry face where the pyramid settled ray ``k``'s walk
    (``surface_approach.top_node_hit``; ``y = -1`` where it did not)."""
    walk_ints[k, 4] = y
    walk_ints[k, 5] = normal
    walk_times[k, 1] = t


@njit(cache=True, nogil=True, inline="always")
def walk_of(walk_ints: np.ndarray, walk_times: np.ndarray, k: int):
    """Ray ``k``'s recorded walk as ``surface_approach.walk_over_columns``'s tuple, for
    ``settle_walk``."""
    return (walk_ints[k, 0], walk_times[k, 0], walk_ints[k, 1], walk_ints[k, 2],
            walk_ints[k, 3], walk_ints[k, 4], walk_times[k, 1], walk_ints[k, 5])


@njit(cache=True, nogil=True)
def new_walk_rows(count: int):
    """Rows for ``count`` rays and their walks: the rays (``ox, oy, oz, dx, dy, dz, tmin``),
    the walks' integers (verdict, cells, cell x, z, landing y, normal code) and times
    (``t_from``, landing ``t``)."""
    return np.empty((count, 7)), np.empty((count, 6), np.int64), np.empty((count, 2))


@njit(cache=True, nogil=True, inline="always")
def land_walks(rays: np.ndarray, count: int, walk_ints: np.ndarray, walk_times: np.ndarray,
               columns, tmax: float, finest: int) -> None:
    """Complete the walks of the first ``count`` rays of a lane walk to nodes of side
    ``2^finest`` with the node each was handed over on where the pyramid settles it
    (``surface_approach.top_node_hit``): ``walk_ints[k, 4]`` (y in node units, else -1),
    ``walk_times[k, 1]`` (the time, else inf) and ``walk_ints[k, 5]`` (normal code, else
    -1), as ``walk_over_columns`` gives them."""
    for k in range(count):
        y, t, normal = -1, math.inf, -1
        if walk_ints[k, 0] != MISSED and walk_ints[k, 2] >= 0:
            y, t, normal = top_node_hit(rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3],
                                        rays[k, 4], rays[k, 5], rays[k, 6], walk_times[k, 0],
                                        tmax, walk_ints[k, 2], walk_ints[k, 3], finest,
                                        columns)
        record_landing(walk_ints, walk_times, k, y, t, normal)


@njit(cache=True, nogil=True, inline="always")
def _record_lane(floats: np.ndarray, ints: np.ndarray, columns, lane: int, finest: int,
                 walk_ints: np.ndarray, walk_times: np.ndarray) -> None:
    """Record the walk of the ray that stopped in ``lane``, if any, and leave the lane idle;
    start the loads of the settling of a ray handed over in a cell of level ``finest``
    (``surface_approach.top_node_hit``, ``top_run_node``)."""
    k = ints[_RAY, lane]
    if k < 0:
        return
    ints[_RAY, lane] = -1
    if ints[_VERDICT, lane] == MISSED:
        record_walk(walk_ints, walk_times, k, MISSED, floats[_T, lane], ints[_STEPS, lane], -1,
                    -1)
        return
    cx, cz = ints[_CX, lane], ints[_CZ, lane]
    record_walk(walk_ints, walk_times, k, HANDED_OVER, floats[_T, lane], ints[_STEPS, lane],
                cx, cz)
    prefetch_landing(columns, cx, cz, finest)


def pick(condition: bool, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false``: in compiled code one
    ``select``, both sides computed, so a lane pass has no branch on a ray's route. Compiled
    once per type (``_pick``) and left to LLVM to inline, rather than a function Numba
    inlines anew at each of its call sites (a lane pass has 21): each lane walk compiles in
    about 4 s less (the LOD-0 one in 9.5-10.8 s instead of 13.5-14.0), to the same
    instructions but for mask and compare choices, and renders as fast. Plain Python here
    for ``NUMBA_DISABLE_JIT`` (the CUDA simulator)."""
    return if_true if condition else if_false


@overload(pick)
def _pick(condition, if_true, if_false):
    if not isinstance(condition, types.Boolean):
        return None
    return lambda condition, if_true, if_false: _select(condition, if_true, if_false)


@intrinsic
def _select(typingctx, condition, if_true, if_false):
    result = typingctx.unify_pairs(types.unliteral(if_true), types.unliteral(if_false))
    if result is None:
        return None

    def codegen(context, builder, signature, args):
        condition_value, true_value, false_value = args
        _, true_type, false_type = signature.args
        return builder.select(
            condition_value,
            context.cast(builder, true_value, true_type, signature.return_type),
            context.cast(builder, false_value, false_type, signature.return_type))

    return result(condition, if_true, if_false), codegen


# A record's field is shifted up to the int64's top bits, then arithmetically back down.
_FIELD_SHIFT = 64 - RECORD_FIELD_BITS


@njit(cache=True, nogil=True, inline="always")
def unpack_record(record):
    """A cell record's three signed fields (``column_tops.cell_records``): its top, gap
    floor and gap ceiling."""
    return ((record << _FIELD_SHIFT) >> _FIELD_SHIFT,
            (record << (_FIELD_SHIFT - RECORD_FIELD_BITS)) >> _FIELD_SHIFT,
            (record << (_FIELD_SHIFT - 2 * RECORD_FIELD_BITS)) >> _FIELD_SHIFT)


@njit(cache=True, nogil=True, inline="always")
def lane_child(cx, cz, level, ox, ix, oz, iz, ahead_x, ahead_z, t):
    """The child cell (x, z) that holds a lane's ray at ``t`` (``column_walk.step_down``, as
    selects; with a zero component the mid plane is crossed at ±inf, as there). Worked out
    at level 0 too, where the pass does not use it."""
    child = level - 1
    t_mid_x = (float((2 * cx + 1) << child) - ox) * ix
    t_mid_z = (float((2 * cz + 1) << child) - oz) * iz
    upper_x = pick(ahead_x == 1, t_mid_x <= t, t < t_mid_x)
    upper_z = pick(ahead_z == 1, t_mid_z <= t, t < t_mid_z)
    return 2 * cx + pick(upper_x, 1, 0), 2 * cz + pick(upper_z, 1, 0)


@njit(cache=True, nogil=True, inline="always")
def next_lane_cell(cx, cz, level, still, width0, depth0, level_offset):
    """``(outside, cell)`` for a lane's next pass: whether cell ``(cx, cz)`` of ``level`` is
    off the footprint (a level's shape is the footprint's, halved and rounded up), and its
    index into the pyramid (0 where the ray stopped or left)."""
    round_level = (1 << level) - 1
    depth = (depth0 + round_level) >> level
    beyond = ((np.uint64(cx) >= np.uint64((width0 + round_level) >> level))
              | (np.uint64(cz) >= np.uint64(depth)))
    return (pick(beyond, 1, 0),
            pick(still & (not beyond), level_offset[np.uint64(level)] + cx * depth + cz, 0))


@njit(cache=True, nogil=True, inline="always")
def _lane_pass(floats: np.ndarray, ints: np.ndarray, columns, first: int, finest: int) -> int:
    """One cell of ``approach_surface`` to nodes of side ``2^finest`` for every walking lane
    of the group from ``first``, as selects; the rays still walking. A ray that stops keeps
    its cell, time and steps, and its verdict is in ``_VERDICT``. Each lane's cell index is
    worked out a pass ahead, so a pass starts with the loads of its cells' records."""
    records, level_offset = columns.cell_records, columns.level_offset
    width0, depth0 = columns.level_width[0], columns.level_depth[0]
    top_level = columns.level_width.shape[0] - 1
    round_up = (1 << finest) - 1
    ox_, ix_, oy_, dy_, iy_ = floats[_OX], floats[_IX], floats[_OY], floats[_DY], floats[_IY]
    oz_, iz_, t_, t_end_ = floats[_OZ], floats[_IZ], floats[_T], floats[_T_END]
    cx_, cz_, level_, skips_ = ints[_CX], ints[_CZ], ints[_LEVEL], ints[_SKIPS]
    patience_, steps_, live_ = ints[_PATIENCE], ints[_STEPS], ints[_LIVE]
    verdict_, ahead_x_, ahead_z_ = ints[_VERDICT], ints[_AHEAD_X], ints[_AHEAD_Z]
    step_x_, step_z_ = ints[_STEP_X], ints[_STEP_Z]
    cell_, outside_ = ints[_CELL], ints[_OUTSIDE]
    live = 0
    for index in range(LANES):
        lane = np.uint64(first + index)  # unsigned: no wrap-around select in the address
        walking = live_[lane] != 0
        outside = outside_[lane] != 0
        visits = walking & (not outside)
        record = records[np.uint64(cell_[lane])]
        ox, ix, oy, dy, iy = ox_[lane], ix_[lane], oy_[lane], dy_[lane], iy_[lane]
        oz, iz, t, t_end = oz_[lane], iz_[lane], t_[lane], t_end_[lane]
        cx, cz, level, skips = cx_[lane], cz_[lane], level_[lane], skips_[lane]
        ahead_x, ahead_z = ahead_x_[lane], ahead_z_[lane]
        top, floor, ceiling = unpack_record(record)
        # Rounded out to whole nodes of the finest level, as ``approach_surface`` rounds
        # them (at LOD 0, where the batches of the benchmark walk, the rounding folds away).
        top = (top + round_up) & ~round_up
        floor = (floor + round_up) & ~round_up
        ceiling = ceiling & ~round_up
        tx = (float((cx + ahead_x) << level) - ox) * ix
        tz = (float((cz + ahead_z) << level) - oz) * iz
        t_exit = min(tx, tz)
        # Above the cell's voxels for all of [t, t_exit), or in the gap under its top runs
        # (``column_walk.in_the_gap``); an empty cell's top is 0.
        t_top = (float(top) - oy) * iy
        above = pick(dy < 0.0, t_exit <= t_top, pick(dy > 0.0, t >= t_top, oy >= top))
        t_leave = min(t_exit, t_end)
        t_floor = (float(floor) - oy) * iy
        t_ceiling = (float(ceiling) - oy) * iy
        in_gap = pick(dy < 0.0, (t >= t_ceiling) & (t_leave <= t_floor),
                       pick(dy > 0.0, (t >= t_floor) & (t_leave <= t_ceiling),
                             (floor <= oy) & (oy < ceiling)))
        skip = above | (in_gap & (top != 0)) | (top == 0)
        leaves = skip & (not t_exit < t_end)
        # Across to the next cell, a level up once ``patience`` cells are skipped in a row
        # and it lies in another parent (``column_walk.step_across``).
        next_cx = cx + pick(tx <= t_exit, step_x_[lane], 0)
        next_cz = cz + pick(tz <= t_exit, step_z_[lane], 0)
        skipped = skips + 1
        climbs = ((skipped >= patience_[lane]) & (level < top_level)
                  & ((((next_cx ^ cx) | (next_cz ^ cz)) >> 1) != 0))
        # Down to the child that holds the ray at ``t``.
        child_cx, child_cz = lane_child(cx, cz, level, ox, ix, oz, iz, ahead_x, ahead_z, t)
        across = visits & skip & (not leaves)
        down = visits & (not skip) & (level > finest)
        handed = visits & (not skip) & (level == finest)
        missed = walking & (outside | leaves)
        cx = pick(across, pick(climbs, next_cx >> 1, next_cx),
                   pick(down, child_cx, cx))
        cz = pick(across, pick(climbs, next_cz >> 1, next_cz),
                   pick(down, child_cz, cz))
        level = pick(across, pick(climbs, level + 1, level), pick(down, level - 1, level))
        still = walking & (not missed) & (not handed)
        cx_[lane] = cx
        cz_[lane] = cz
        level_[lane] = level
        skips_[lane] = pick(across, pick(climbs, 0, skipped), pick(down, 0, skips))
        t_[lane] = pick(across, t_exit, t)
        steps_[lane] += pick(visits, 1, 0)
        live_[lane] = pick(still, 1, 0)
        verdict_[lane] = pick(missed, MISSED, pick(handed, HANDED_OVER, verdict_[lane]))
        live += pick(still, 1, 0)
        # The next pass's cell, whether it is off the footprint.
        outside_[lane], cell_[lane] = next_lane_cell(cx, cz, level, still, width0, depth0,
                                                    level_offset)
    return live
