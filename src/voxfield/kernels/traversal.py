"""Front-to-back SVO traversal with exact, shared slab arithmetic (the watertightness contract).

A ray ``o + t·d`` hits an axis-aligned box when its clipped interval is non-empty:
``max(t_enter, tmin) < min(t_exit, tmax)``. Each plane's crossing time is computed by one
formula, ``(plane - o) * inv_d`` in float64, so neighbouring boxes see bit-identical times at
their shared face; a zero direction component uses the half-open test ``lo <= o < hi``.
Under that contract boxes along a ray have disjoint intervals, the first hit is unique, and
the brute-force oracle in the tests (same formula, every voxel) must agree exactly.

Stack entries are nodes whose interval is already known to be non-empty; children of a node
are pushed in reverse order of entry time, so they pop front to back.
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
def trace_ray(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_radius: float, cone_spread: float,
    stack_node: np.ndarray, stack_level: np.ndarray, stack_pos: np.ndarray,
    stack_t: np.ndarray, order_t: np.ndarray, order_c: np.ndarray,
) -> tuple[int, int, float, int, int]:
    """First node hit by a ray, descending until ``stop_level`` or the cone footprint.

    ``inner_nodes`` holds one packed descriptor per inner node, ``first_child << 8 | mask``
    (``Octree.inner_nodes``): one memory access per visited inner node, none per leaf.

    Returns ``(node, level, t_hit, normal_code, steps)``; ``node == MISS`` when nothing is hit.
    ``steps`` counts every node visited (popped), the EA thesis's traversal steps.
    The stacks (node, level, position, entry time) and ``order_*`` arrays (8 entries) are
    per-thread scratch from ``new_scratch``, allocated once per tile.
    A node of side ``s`` met at distance ``t`` is sampled as a leaf when
    ``s <= cone_radius + cone_spread * t`` (set both to 0 for a fixed level).
    """
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
    sp = 0
    stack_node[0] = 0
    stack_level[0] = 0
    stack_pos[0, 0] = 0
    stack_pos[0, 1] = 0
    stack_pos[0, 2] = 0
    stack_t[0] = max(enter, tmin)
    sp = 1
    while sp > 0:
        sp -= 1
        node = stack_node[sp]
        level = stack_level[sp]
        px = stack_pos[sp, 0]
        py = stack_pos[sp, 1]
        pz = stack_pos[sp, 2]
        t_near = stack_t[sp]
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
        half = size * 0.5
        # Entry/exit times of the low and high half along each axis, from three planes per
        # axis; identical to box_interval on each child, at a third of the cost.
        lx0, lx1 = axis_interval(ox, dx, ix, x0, x0 + half)
        hx0, hx1 = axis_interval(ox, dx, ix, x0 + half, x0 + size)
        ly0, ly1 = axis_interval(oy, dy, iy, y0, y0 + half)
        hy0, hy1 = axis_interval(oy, dy, iy, y0 + half, y0 + size)
        lz0, lz1 = axis_interval(oz, dz, iz, z0, z0 + half)
        hz0, hz1 = axis_interval(oz, dz, iz, z0 + half, z0 + size)
        count = 0
        for octant in range(8):
            if not (mask >> octant) & 1:
                continue
            if octant & 1:
                c_enter, c_leave = hx0, hx1
            else:
                c_enter, c_leave = lx0, lx1
            if octant & 2:
                c_enter, c_leave = fmax(c_enter, hy0), fmin(c_leave, hy1)
            else:
                c_enter, c_leave = fmax(c_enter, ly0), fmin(c_leave, ly1)
            if octant & 4:
                c_enter, c_leave = fmax(c_enter, hz0), fmin(c_leave, hz1)
            else:
                c_enter, c_leave = fmax(c_enter, lz0), fmin(c_leave, lz1)
            c_near = fmax(c_enter, tmin)
            if not (c_near < fmin(c_leave, tmax)):
                continue
            # Insertion sort, latest entry first, so the nearest child ends on top of the stack.
            k = count
            while k > 0 and order_t[k - 1] < c_near:
                order_t[k] = order_t[k - 1]
                order_c[k] = order_c[k - 1]
                k -= 1
            order_t[k] = c_near
            order_c[k] = octant
            count += 1
        base = descriptor >> 8
        for k in range(count):
            octant = order_c[k]
            stack_node[sp] = base + child_slot(mask, octant)
            stack_level[sp] = level + 1
            stack_pos[sp, 0] = 2 * px + (octant & 1)
            stack_pos[sp, 1] = 2 * py + ((octant >> 1) & 1)
            stack_pos[sp, 2] = 2 * pz + ((octant >> 2) & 1)
            stack_t[sp] = order_t[k]
            sp += 1
    return MISS, 0, math.inf, NO_NORMAL, steps


def stack_capacity(depth: int) -> int:
    """Stack entries one ray can need: at most 4 pushed children per level, plus the root."""
    return 4 * (depth + 1) + 1


@njit(cache=True, nogil=True)
def new_scratch(depth: int):
    """Per-thread traversal scratch: node, level and position stacks plus child ordering."""
    cap = 4 * (depth + 1) + 1
    return (
        np.empty(cap, np.int64),
        np.empty(cap, np.int64),
        np.empty((cap, 3), np.int64),
        np.empty(cap, np.float64),
        np.empty(8, np.float64),
        np.empty(8, np.int64),
    )
