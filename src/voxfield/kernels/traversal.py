"""Front-to-back SVO traversal with exact, shared slab arithmetic (the watertightness contract).

A ray ``o + t·d`` hits an axis-aligned box when its clipped interval is non-empty:
``max(t_enter, tmin) < min(t_exit, tmax)``. Each plane's crossing time is computed by one
formula, ``(plane - o) * inv_d`` in float64, so neighbouring boxes see bit-identical times at
their shared face; a zero direction component uses the half-open test ``lo <= o < hi``.
Under that contract boxes along a ray have disjoint intervals, the first hit is unique, and
the brute-force oracle in the tests (same formula, every voxel) must agree exactly.

Stack entries are nodes whose interval is already known to be non-empty; children of a node
are pushed in reverse order of entry time, so they pop front to back; the nearest child is
descended into directly. Direction components whose inverse overflows count as zero.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MISS = -1
#: Face-normal codes: 0..5 = -x, +x, -y, +y, -z, +z; -1 = none (origin inside the hit node).
NO_NORMAL = -1


@njit(cache=True, nogil=True)
def fmax(a: float, b: float) -> float:
    """max for non-NaN floats without the NaN handling of the builtin."""
    return a if a > b else b


@njit(cache=True, nogil=True)
def fmin(a: float, b: float) -> float:
    return a if a < b else b


@njit(cache=True, nogil=True)
def axis_interval(o: float, d: float, inv: float, lo: float, hi: float) -> tuple[float, float]:
    """Times at which the ray is inside the slab ``[lo, hi)`` of one axis."""
    if d == 0.0:
        if lo <= o and o < hi:
            return -math.inf, math.inf
        return math.inf, -math.inf
    t0 = (lo - o) * inv
    t1 = (hi - o) * inv
    if inv < 0.0:
        return t1, t0
    return t0, t1


@njit(cache=True, nogil=True)
def safe_inverse(d: float) -> float:
    return 1.0 / d if d != 0.0 else math.inf


@njit(cache=True, nogil=True)
def flush_uninvertible(d: float) -> float:
    """``d``, or 0 when ``1 / d`` overflows (|d| below ~5.6e-309), so no crossing is NaN."""
    return d if d == 0.0 or math.isfinite(1.0 / d) else 0.0


@njit(cache=True, nogil=True)
def box_interval(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    ix: float, iy: float, iz: float,
    x0: float, y0: float, z0: float, size: float,
) -> tuple[float, float, int]:
    """Entry time, exit time and entry axis (0, 1, 2; first maximum wins) of a cube."""
    ax0, ax1 = axis_interval(ox, dx, ix, x0, x0 + size)
    ay0, ay1 = axis_interval(oy, dy, iy, y0, y0 + size)
    az0, az1 = axis_interval(oz, dz, iz, z0, z0 + size)
    enter = ax0
    axis = 0
    if ay0 > enter:
        enter = ay0
        axis = 1
    if az0 > enter:
        enter = az0
        axis = 2
    leave = fmin(fmin(ax1, ay1), az1)
    return enter, leave, axis


@njit(cache=True, nogil=True)
def child_slot(mask: int, octant: int) -> int:
    """Offset of child ``octant`` among the present children (popcount of lower bits)."""
    below = mask & ((1 << octant) - 1)
    count = 0
    while below:
        below &= below - 1
        count += 1
    return count


@njit(cache=True, nogil=True)
def split_axis(
    o: float, d: float, inv: float, lo: float, mid: float, hi: float
) -> tuple[float, float, float, float, float, int]:
    """``axis_interval`` of the low and high half of a slab, plus the order key of the split.

    Returns ``(low_enter, low_exit, high_enter, high_exit, t_mid, first)``: ``t_mid`` is the
    time the ray crosses ``mid`` (infinite when ``d == 0``: never) and ``first`` the half
    (0 low, 1 high) the ray is in before that.
    """
    if d == 0.0:
        if lo <= o and o < mid:
            return -math.inf, math.inf, math.inf, -math.inf, math.inf, 0
        if mid <= o and o < hi:
            return math.inf, -math.inf, -math.inf, math.inf, math.inf, 1
        return math.inf, -math.inf, math.inf, -math.inf, math.inf, 0
    ta = (lo - o) * inv
    tm = (mid - o) * inv
    tb = (hi - o) * inv
    if inv < 0.0:
        return tm, ta, tb, tm, tm, 1
    return ta, tm, tm, tb, tm, 0


@njit(cache=True, nogil=True)
def child_interval(
    octant: int,
    lex: float, llx: float, hex_: float, hlx: float,
    ley: float, lly: float, hey: float, hly: float,
    lez: float, llz: float, hez: float, hlz: float,
    tmin: float,
) -> tuple[float, float]:
    """Clipped entry and exit of child ``octant`` from its axes' half intervals."""
    if octant & 1:
        c_enter, c_leave = hex_, hlx
    else:
        c_enter, c_leave = lex, llx
    if octant & 2:
        c_enter, c_leave = fmax(c_enter, hey), fmin(c_leave, hly)
    else:
        c_enter, c_leave = fmax(c_enter, ley), fmin(c_leave, lly)
    if octant & 4:
        c_enter, c_leave = fmax(c_enter, hez), fmin(c_leave, hlz)
    else:
        c_enter, c_leave = fmax(c_enter, lez), fmin(c_leave, llz)
    return fmax(c_enter, tmin), c_leave


@njit(cache=True, nogil=True, inline='always')
def trace_ray(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_radius: float, cone_spread: float,
    stack_node: np.ndarray, stack_level: np.ndarray, stack_pos: np.ndarray,
    stack_t: np.ndarray,
) -> tuple[int, int, float, int, int]:
    """First node hit by a ray, descending until ``stop_level`` or the cone footprint.

    ``inner_nodes`` holds one packed descriptor per inner node, ``first_child << 8 | mask``
    (``Octree.inner_nodes``): one memory access per visited inner node, none per leaf.

    Returns ``(node, level, t_hit, normal_code, steps)``; ``node == MISS`` when nothing is hit.
    ``steps`` counts every node visited (popped), the EA thesis's traversal steps.
    The stacks (node, level, position, entry time) are per-thread scratch from
    ``new_scratch``, allocated once per tile.
    A node of side ``s`` met at distance ``t`` is sampled as a leaf when
    ``s <= cone_radius + cone_spread * t`` (set both to 0 for a fixed level).

    Child order without sorting: along each axis the two halves' intervals are
    ``[t(lo), t_mid)`` and ``[t_mid, t(hi))`` (mirrored for a negative direction) with one
    shared ``t_mid``, so the child containing time ``t`` flips its bit on an axis exactly
    when ``t`` passes that axis's ``t_mid``. Every child with a non-empty interval is
    therefore on the path that starts in the child the ray is in before any split
    (``first`` bits) and flips the axes in increasing ``t_mid`` order: 4 candidates, front
    to back (ties only add empty intermediate children). Candidates get the exact interval
    test of ``child_interval``; non-empty child intervals are disjoint, so the visiting
    order, the hit and the step count are those of testing all eight children and sorting
    them by entry time. The nearest hit child is descended into directly and the others are
    pushed (at most 3 per level).
    Non-finite inputs (NaN or infinite origin, direction or clip times) miss.

    ``inline='always'`` inlines the traversal into the calling kernels: a call costs more
    than a short ray (seven array reference-count updates each way).
    """
    if not (
        math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)
        and math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz)
        and tmin == tmin and tmax == tmax
    ):
        return MISS, 0, math.inf, NO_NORMAL, 0
    # A component too small to invert (denormal) moves the ray by nothing measurable: zero.
    dx = flush_uninvertible(dx)
    dy = flush_uninvertible(dy)
    dz = flush_uninvertible(dz)
    ix = safe_inverse(dx)
    iy = safe_inverse(dy)
    iz = safe_inverse(dz)
    steps = 0
    root = float(1 << depth)
    enter, leave, axis = box_interval(ox, oy, oz, dx, dy, dz, ix, iy, iz, 0.0, 0.0, 0.0, root)
    if not (max(enter, tmin) < min(leave, tmax)):
        return MISS, 0, math.inf, NO_NORMAL, steps
    use_cone = cone_radius > 0.0 or cone_spread > 0.0
    stop_level = min(stop_level, depth)
    # The current node lives in registers; the stack holds the later siblings only.
    node = 0
    level = 0
    px = 0
    py = 0
    pz = 0
    t_near = max(enter, tmin)
    sp = 0
    while True:
        steps += 1
        size = float(1 << (depth - level))
        x0 = px * size
        y0 = py * size
        z0 = pz * size
        # Levels at or below the stop level are never read: leaves cost no memory access.
        is_leaf = level >= stop_level
        if not is_leaf and use_cone:
            is_leaf = size <= cone_radius + cone_spread * max(t_near, 0.0)
        if is_leaf:
            enter, leave, axis = box_interval(
                ox, oy, oz, dx, dy, dz, ix, iy, iz, x0, y0, z0, size
            )
            normal = NO_NORMAL
            if enter > tmin:
                d_axis = dx if axis == 0 else (dy if axis == 1 else dz)
                normal = 2 * axis + (0 if d_axis > 0.0 else 1)
            return node, level, t_near, normal, steps
        descriptor = inner_nodes[node]
        mask = descriptor & 0xFF
        base = descriptor >> 8
        half = size * 0.5
        lex, llx, hex_, hlx, mx, bx = split_axis(ox, dx, ix, x0, x0 + half, x0 + size)
        ley, lly, hey, hly, my, by = split_axis(oy, dy, iy, y0, y0 + half, y0 + size)
        lez, llz, hez, hlz, mz, bz = split_axis(oz, dz, iz, z0, z0 + half, z0 + size)
        # Flip order: the axes sorted by split time (ties in axis order).
        if mx <= my:
            if my <= mz:
                f0, f1 = 1, 2
            elif mx <= mz:
                f0, f1 = 1, 4
            else:
                f0, f1 = 4, 1
        else:
            if mx <= mz:
                f0, f1 = 2, 1
            elif my <= mz:
                f0, f1 = 2, 4
            else:
                f0, f1 = 4, 2
        c0 = bx | (by << 1) | (bz << 2)
        level += 1
        px *= 2
        py *= 2
        pz *= 2
        # Candidates back to front; every hit one but the nearest goes on the stack.
        pending = -1
        pending_t = 0.0
        for k in range(4):
            if k == 0:
                octant = c0 ^ 7
            elif k == 1:
                octant = c0 ^ f0 ^ f1
            elif k == 2:
                octant = c0 ^ f0
            else:
                octant = c0
            if not (mask >> octant) & 1:
                continue
            c_near, c_leave = child_interval(
                octant, lex, llx, hex_, hlx, ley, lly, hey, hly, lez, llz, hez, hlz, tmin
            )
            if not (c_near < fmin(c_leave, tmax)):
                continue
            if pending >= 0:
                stack_node[sp] = base + child_slot(mask, pending)
                stack_level[sp] = level
                stack_pos[sp, 0] = px + (pending & 1)
                stack_pos[sp, 1] = py + ((pending >> 1) & 1)
                stack_pos[sp, 2] = pz + ((pending >> 2) & 1)
                stack_t[sp] = pending_t
                sp += 1
            pending = octant
            pending_t = c_near
        if pending >= 0:
            node = base + child_slot(mask, pending)
            px += pending & 1
            py += (pending >> 1) & 1
            pz += (pending >> 2) & 1
            t_near = pending_t
            continue
        if sp == 0:
            break
        sp -= 1
        node = stack_node[sp]
        level = stack_level[sp]
        px = stack_pos[sp, 0]
        py = stack_pos[sp, 1]
        pz = stack_pos[sp, 2]
        t_near = stack_t[sp]
    return MISS, 0, math.inf, NO_NORMAL, steps


@njit(cache=True, nogil=True)
def new_scratch(depth: int):
    """Per-thread traversal stacks (node, level, position, entry time): at most 3 siblings
    wait per level, so 4 entries per level is ample."""
    cap = 4 * (depth + 1) + 1
    return (
        np.empty(cap, np.int64),
        np.empty(cap, np.int64),
        np.empty((cap, 3), np.int64),
        np.empty(cap, np.float64),
    )
