"""The moves of a walk through the column-top pyramid (``svo.column_tops``), shared by the
rising any-hit rays (``kernels.upward_rays``) and the closest-hit rays
(``kernels.surface_approach``). A walk is in cell ``(cx, cz)`` of ``level`` (side
``2^level`` columns); every time is the traversal's ``face_time`` of an integer plane."""

from __future__ import annotations

from numba import njit

from voxfield.kernels.scalar_ops import face_time
from voxfield.kernels.traversal import floor_float

#: Nodes the pyramid keeps per column (``ColumnTops.top_nodes``): those of its top run's
#: highest voxels, top down, one 16-byte record. A primary ray the pyramid lands on a
#: column's side hits one of them without an octree lookup: on the 2048² mountain terrain
#: 98 % of such hits are within 4 voxels of the top (73 % the voxel under the top one), and
#: a lookup from the octree's root costs those rays a chain of cache misses.
TOP_RUN_NODES = 4
#: Bits of each signed field of a pyramid's cell record (``svo.column_tops.cell_records``:
#: top, gap floor, gap ceiling in one int64, for the walks in SIMD lanes).
RECORD_FIELD_BITS = 21


@njit(cache=True, nogil=True, inline="always")
def upper_half(mid_plane: int, o: float, d: float, inv: float, t: float) -> int:
    """1 if the ray is past the mid plane of a cell at time ``t`` (in the cell's upper half
    along this axis), else 0."""
    if d > 0.0:
        return 1 if face_time(mid_plane, o, inv) <= t else 0
    if d < 0.0:
        return 1 if t < face_time(mid_plane, o, inv) else 0
    return 1 if o >= mid_plane else 0


@njit(cache=True, nogil=True, inline="always")
def step_across(cx: int, cz: int, level: int, tx: float, tz: float, t_exit: float,
                step_x: int, step_z: int, top_level: int) -> tuple[int, int, int]:
    """The cell the ray enters at ``t_exit`` when it leaves a cell it skipped (through every
    face it crosses then), a level up when that cell lies in another parent: coarse where
    it can be."""
    px = cx
    pz = cz
    if tx <= t_exit:
        cx += step_x
    if tz <= t_exit:
        cz += step_z
    if level < top_level and ((cx >> 1) != (px >> 1) or (cz >> 1) != (pz >> 1)):
        return cx >> 1, cz >> 1, level + 1
    return cx, cz, level


@njit(cache=True, nogil=True, inline="always")
def step_down(cx: int, cz: int, level: int, ox: float, dx: float, ix: float, oz: float,
              dz: float, iz: float, t: float) -> tuple[int, int, int]:
    """The child cell that holds the ray at time ``t``."""
    level -= 1
    return (2 * cx + upper_half((2 * cx + 1) << level, ox, dx, ix, t),
            2 * cz + upper_half((2 * cz + 1) << level, oz, dz, iz, t), level)


@njit(cache=True, nogil=True, inline="always")
def clear_of_cell(oy: float, dy: float, iy: float, t: float, t_exit: float, t_leave: float,
                  top: int, gap_floor, gap_ceiling, cell, round_up: int) -> bool:
    """Whether a ray in a pyramid cell over ``[t, t_exit)`` meets none of its nodes of side
    ``round_up + 1``: above the cell's ``top`` (rounded up to them) all along (falling rays
    until they cross the top plane, rising ones from the time they are above it, level ones
    throughout), or in the gap all its columns leave under their top runs, rounded in to
    them, until ``t_leave``. The gap is read only where the top does not settle it."""
    t_top = face_time(top, oy, iy)
    if dy < 0.0:
        above = t_exit <= t_top
    elif dy > 0.0:
        above = t >= t_top
    else:
        above = oy >= top
    if not above and top != 0:
        above = in_the_gap(oy, dy, iy, t, t_leave, (gap_floor[cell] + round_up) & ~round_up,
                           gap_ceiling[cell] & ~round_up)
    return above


@njit(cache=True, nogil=True, inline="always")
def in_the_gap(oy: float, dy: float, iy: float, t: float, t_leave: float, floor: int,
               ceiling: int) -> bool:
    """Whether the ray stays in the gap ``[floor, ceiling)`` (under every top run of a cell,
    above everything under them: under a canopy or an overhang, inside a hollow shell) for
    all of ``[t, t_leave)``."""
    if dy < 0.0:
        return t >= face_time(ceiling, oy, iy) and t_leave <= face_time(floor, oy, iy)
    if dy > 0.0:
        return t >= face_time(floor, oy, iy) and t_leave <= face_time(ceiling, oy, iy)
    return floor <= oy and oy < ceiling


@njit(cache=True, nogil=True, inline="always")
def cell_holding(o: float, d: float, inv: float, t: float, level: int, lo: int,
                 hi: int) -> int:
    """The cell ``[k, k + 1) << level`` of one axis that holds the ray at time ``t``, clamped
    to ``lo..hi``: a guess from the position, settled by the contract's crossing times."""
    guess = min(max(floor_float(o + t * d), float(lo << level)), float(((hi + 1) << level) - 1))
    k = int(guess) >> level
    if d > 0.0:
        while k > lo and t < face_time(k << level, o, inv):
            k -= 1
        while k < hi and face_time((k + 1) << level, o, inv) <= t:
            k += 1
    elif d < 0.0:
        while k < hi and t < face_time((k + 1) << level, o, inv):
            k += 1
        while k > lo and face_time(k << level, o, inv) <= t:
            k -= 1
    return k
