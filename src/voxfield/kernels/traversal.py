"""Front-to-back SVO traversal with exact, shared slab arithmetic (the watertightness contract).

**Contract.** A ray ``o + t·d`` hits an axis-aligned box when its clipped interval is
non-empty: ``max(t_enter, tmin) < min(t_exit, tmax)``. Every plane's crossing time is computed
by one formula, ``face_time``: ``(plane - o) * (1 / d)`` in float64 with ``plane`` an integer,
so neighbouring boxes see bit-identical times at their shared face; a zero direction component
uses the half-open test ``lo <= o < hi``; a component whose inverse overflows counts as zero.
Under that contract boxes along a ray have disjoint intervals, the first hit is unique, and
the brute-force oracle in the tests (same formula, every voxel) agrees exactly: hit node,
``t`` bit for bit, and entry face.

**Loop** (after Laine & Karras 2010, in integer coordinates). The current node is one child
of a parent whose descriptor sits in a register; the ray's sign bits (``flip``) turn "next
octant along the ray" into an XOR. Each iteration computes the child's three exit times:

- child present and interval non-empty: stop (leaf level, stop level or cone footprint) or
  descend, picking the child the ray is in from the centre-plane crossing times;
- otherwise advance: step every axis whose exit is first; if a step leaves the parent, the
  highest bit in which the old and new integer positions differ names the ancestor to pop
  to (the stack holds one descriptor per level, written only on descent).

A child's exit never comes after its parent's (same planes or nearer ones, and rounding is
monotonic), so only the ray's own ``tmax`` clips intervals.

**Steps** (the EA thesis's traversal steps, the cost measure every renderer reports): the
number of existing nodes with a non-empty interval the traversal enters, the root included,
up to and including the node it stops at. Empty octants it skips are not counted. The count
equals that of the textbook stack traversal that visits children front to back. Rays that
first walk the column-top pyramid (``kernels.surface_approach``, ``kernels.upward_rays``) add
one step per pyramid cell they visit, and a node the pyramid settles without the octree
counts as one step; the GPU kernel and ``columns=False`` renders walk the octree alone.

**Restart.** Consecutive rays of one thread are usually close. Each hit leaves its path (the
ancestors' descriptors on the stack, the hit node's position) in the per-thread scratch, and
each ray the path of the node it starts in (recorded at its first advance); the next ray
starts at the deepest ancestor on either path whose interval holds its start time, which
is exactly where a traversal from the root would arrive after entering every ancestor above.
Primary rays that a beam bound starts near the surface share their start nodes with their
neighbours far deeper than the last hit's path reaches.
Results and step counts are therefore identical to a traversal from the root whatever the ray
order or thread count; only the dependent loads of the descent are saved.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from voxfield.kernels.node_descriptor import SOLID_BIT, child_index
from voxfield.kernels.scalar_ops import face_time, fmin

MISS = -1
#: Face-normal codes: 0..5 = -x, +x, -y, +y, -z, +z; -1 = none (origin inside the hit node).
NO_NORMAL = -1


@njit(cache=True, nogil=True, inline="always")
def floor_float(x: float) -> float:
    """``floor`` of a finite float as a float, exact for any magnitude (no integer overflow):
    ``math.floor``, which the CUDA target compiles as well (it has no ``np.floor``), below
    2⁵², where every float is an integer already."""
    if abs(x) >= 4503599627370496.0:
        return x
    return float(math.floor(x))


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


@njit(cache=True, nogil=True, inline="always")
def flush_uninvertible(d: float) -> float:
    """``d``, or 0 when ``1 / d`` overflows (|d| below ~5.6e-309), so no crossing is NaN."""
    if d != 0.0 and abs(d) < 1e-300 and not math.isfinite(1.0 / d):
        return 0.0
    return d


@njit(cache=True, nogil=True, inline="always")
def axis_setup(o: float, d: float) -> tuple[float, float, float]:
    """Origin, direction and inverse of one axis as ``traverse`` prepares them: ``d``
    flushed (``flush_uninvertible``), and a zero component mid-cell with an infinite
    inverse, for walks that must cross planes exactly as the traversal does."""
    d = flush_uninvertible(d)
    if d == 0.0:
        return floor_float(o) + 0.5, d, math.inf
    return o, d, 1.0 / d


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


@njit(cache=True, nogil=True, inline="always")
def highest_bit(x: int) -> int:
    """Index of the highest set bit of ``0 < x < 2**32`` (branch-free: smear, then count)."""
    x |= x >> 1
    x |= x >> 2
    x |= x >> 4
    x |= x >> 8
    x |= x >> 16
    return popcount32(x) - 1


@njit(cache=True, nogil=True, inline="always")
def popcount32(x: int) -> int:
    x = x - ((x >> 1) & 0x55555555)
    x = (x & 0x33333333) + ((x >> 2) & 0x33333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F
    return ((x * 0x01010101) & 0xFFFFFFFF) >> 24


@njit(cache=True, nogil=True, inline="always")
def child_at(x0: int, y0: int, z0: int, size: int, ox: float, oy: float, oz: float,
             ix: float, iy: float, iz: float, t_min: float, flip: int):
    """The child (octant bits, corner) of a node at ``(x0, y0, z0)`` whose children have
    side ``size`` that the ray is in at ``t_min``: past a centre plane once its crossing time
    is reached, in the mirrored frame (``flip``) the traversal walks in."""
    idx = (
        (1 if face_time(x0 + size, ox, ix) <= t_min else 0)
        | (2 if face_time(y0 + size, oy, iy) <= t_min else 0)
        | (4 if face_time(z0 + size, oz, iz) <= t_min else 0)
    ) ^ flip
    if idx & 1:
        x0 += size
    if idx & 2:
        y0 += size
    if idx & 4:
        z0 += size
    return idx, x0, y0, z0


@njit(cache=True, nogil=True, inline="always")
def entry_normal(tex: float, tey: float, tez: float, tmin: float, dx: float, dy: float,
                 dz: float) -> int:
    """Face code of the axis whose slab is entered last (first maximum wins), or NO_NORMAL
    when the ray starts inside the node (entry not after ``tmin``)."""
    axis = 0
    enter = tex
    if tey > enter:
        enter = tey
        axis = 1
    if tez > enter:
        enter = tez
        axis = 2
    if not enter > tmin:
        return NO_NORMAL
    d_axis = dx if axis == 0 else (dy if axis == 1 else dz)
    return 2 * axis + (0 if d_axis > 0.0 else 1)


#: Scratch ``path`` slots, four per restart path: the level of the recorded node's parent
#: (-1: none) and the node's position. The last hit's path, the last any-hit ray's start node
#: and the last closest-hit ray's start node.
_PATH_LEVEL = 0
_START_LEVEL = 4
_CLOSEST_START_LEVEL = 8
#: Rows of the start-path descriptors: any-hit rays (whose start paths hold no solid node)
#: and closest-hit rays keep separate ones.
_ANY_HIT_ROW = 0
_CLOSEST_ROW = 1


@njit(cache=True, nogil=True)
def new_scratch(depth: int):
    """Per-thread traversal scratch: one descriptor per level (the stack), the restart paths
    (``path``) and the descriptors of the last start paths (one row per query kind).

    Closest-hit rays restart from the last hit or the last one's start node: the next primary
    ray usually hits near the last hit, and starts (at its beam bound) near the last start.
    Any-hit rays (shadow and sky rays) restart from the last one's start node: they leave
    from neighbouring surface points and mostly hit nothing.
    """
    path = np.empty(12, np.int64)
    path[_PATH_LEVEL] = -1
    path[_START_LEVEL] = -1
    path[_CLOSEST_START_LEVEL] = -1
    return np.empty(depth + 1, np.int64), path, np.empty((2, depth + 1), np.int64)


@njit(cache=True, nogil=True, inline="always")
def restart_level(
    path: np.ndarray, base: int, qx: int, qy: int, qz: int, t_min: float,
    ox: float, oy: float, oz: float, ix: float, iy: float, iz: float,
    exit_x: int, exit_y: int, exit_z: int, depth: int, stop_level: int,
    use_cone: bool, cone: float,
) -> int:
    """Deepest level (0: none below the root) of the ancestor on the recorded path at
    ``base`` that a ray may restart at: above the stop level and the cone's stopping size,
    holding the voxel ``q`` of the ray's start point, and with an interval that holds
    ``t_min``."""
    last = path[base]
    if last <= 0:
        return 0
    hx = path[base + 1]
    hy = path[base + 2]
    hz = path[base + 3]
    root = 1 << depth
    diff = (qx ^ hx) | (qy ^ hy) | (qz ^ hz)
    a = min(last, stop_level - 1)
    while a > 0 and diff >> (depth - a) != 0:
        a -= 1
    while a > 0 and use_cone and float(root >> a) <= cone:
        a -= 1
    while a > 0:
        s = root >> a
        ax0 = hx & -s
        ay0 = hy & -s
        az0 = hz & -s
        enter = max(max(face_time(ax0 + (s & ~exit_x), ox, ix),
                        face_time(ay0 + (s & ~exit_y), oy, iy)),
                    face_time(az0 + (s & ~exit_z), oz, iz))
        leave = min(min(face_time(ax0 + (s & exit_x), ox, ix),
                        face_time(ay0 + (s & exit_y), oy, iy)),
                    face_time(az0 + (s & exit_z), oz, iz))
        if enter <= t_min and t_min < leave:
            break
        a -= 1
    return a


@njit(cache=True, nogil=True, inline="always")
def node_at_level(inner_nodes: np.ndarray, depth: int, level: int, x: int, y: int, z: int,
            scratch) -> int:
    """Flat index of the node at ``level`` (1..depth) with corner ``(x, y, z)`` (voxel units),
    which must exist, recorded as the last hit (so the next ray restarts near it, as after
    ``trace_ray``). The lookup starts at the deepest ancestor it shares with the last hit."""
    stack, path, _ = scratch
    start = 0
    if path[_PATH_LEVEL] == level - 1:
        diff = (x ^ path[1]) | (y ^ path[2]) | (z ^ path[3])
        start = level - 1 if diff == 0 else min(max(depth - 1 - highest_bit(diff), 0), level - 1)
    else:
        stack[0] = inner_nodes[0]
    node = 0
    for current in range(start, level):
        shift = depth - current - 1
        octant = ((x >> shift) & 1) | (((y >> shift) & 1) << 1) | (((z >> shift) & 1) << 2)
        node = child_index(stack[current], octant)
        if current + 1 < level:
            stack[current + 1] = inner_nodes[node]
    path[_PATH_LEVEL] = level - 1
    path[1] = x
    path[2] = y
    path[3] = z
    return node


@njit(cache=True, nogil=True, inline="always")
def cone_width(radius: float, spread: float, t: float) -> float:
    """How wide a ray's cone is at time ``t`` (its radius behind the eye): a node no wider
    is sampled whole. One expression for the traversal and the walks that must judge
    nodes exactly as it does (``kernels.cone_walk``)."""
    return radius + spread * max(t, 0.0)


@njit(cache=True, nogil=True, inline="always")
def trace_ray(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_radius: float, cone_spread: float,
    scratch,
) -> tuple[int, int, float, int, int]:
    """First node hit by a ray, descending until ``stop_level`` or the cone footprint.

    Returns ``(node, level, t_hit, normal_code, steps)``; ``node == MISS`` when nothing is hit.
    A node of side ``s`` entered at time ``t`` is sampled as a leaf when
    ``s <= cone_radius + cone_spread * max(t, 0)`` (set both to 0 for a fixed level).
    ``scratch`` comes from ``new_scratch``, one per thread. Non-finite inputs miss.
    """
    return traverse(ox, oy, oz, dx, dy, dz, tmin, tmax, inner_nodes, depth, stop_level,
                    cone_radius, cone_spread, scratch, False, tmin)


@njit(cache=True, nogil=True, inline="always")
def trace_ray_from(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, t_from: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, stop_level: int, scratch,
) -> tuple[int, int, float, int, int]:
    """``trace_ray`` of the ray over ``[tmin, tmax)``, at a fixed level, searched from
    ``t_from >= tmin`` on: for a caller that knows nothing is hit before ``t_from``
    (``kernels.surface_approach``). Hit, time and normal are those of the whole ray (a node
    entered at ``t_from`` still has its entry face); the steps are those taken from
    ``t_from``."""
    return traverse(ox, oy, oz, dx, dy, dz, tmin, tmax, inner_nodes, depth, stop_level,
                    0.0, 0.0, scratch, False, max(t_from, tmin))


@njit(cache=True, nogil=True, inline="always")
def occluded(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int, scratch,
) -> tuple[bool, int]:
    """Any-hit query at LOD 0: whether a voxel blocks ``[tmin, tmax)``, and the steps taken.

    Stops at the first occupied node met, not the nearest: a solid node (every voxel of its
    cube present) counts as a hit the moment the ray enters it, so rays into terrain or
    walls stop levels above the voxels, and no hit time or normal is worked out.
    """
    node, _, _, _, steps = traverse(ox, oy, oz, dx, dy, dz, tmin, tmax, inner_nodes, depth,
                                    depth, 0.0, 0.0, scratch, True, tmin)
    return node != MISS, steps


@njit(cache=True, nogil=True, inline="always")
def traverse(
    ox: float, oy: float, oz: float,
    dx: float, dy: float, dz: float,
    tmin: float, tmax: float,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_radius: float, cone_spread: float,
    scratch, any_hit: bool, t_from: float,
) -> tuple[int, int, float, int, int]:
    """The loop behind ``trace_ray``, ``trace_ray_from`` and ``occluded`` (``any_hit`` is a
    constant at each call site, so each gets its own specialised copy). Any-hit results carry
    no time or normal. The search starts at ``t_from >= tmin``; entry faces are judged
    against ``tmin``."""
    if not (
        math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)
        and math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz)
        and tmin == tmin and tmax == tmax and t_from == t_from
    ):
        return MISS, 0, math.inf, NO_NORMAL, 0
    stack, path, start_stacks = scratch
    if any_hit:
        path[_PATH_LEVEL] = -1  # any-hit rays do not keep the stack a closest hit left
    dx = flush_uninvertible(dx)
    dy = flush_uninvertible(dy)
    dz = flush_uninvertible(dz)
    # A zero component never crosses a plane: its origin moves to the middle of its unit
    # cell (the same side of every integer plane as before, on none), so its crossing times
    # are +-inf, never NaN, and the half-open slab test holds.
    if dx == 0.0:
        ox = floor_float(ox) + 0.5
        ix = math.inf
    else:
        ix = 1.0 / dx
    if dy == 0.0:
        oy = floor_float(oy) + 0.5
        iy = math.inf
    else:
        iy = 1.0 / dy
    if dz == 0.0:
        oz = floor_float(oz) + 0.5
        iz = math.inf
    else:
        iz = 1.0 / dz
    # ``flip`` has a bit per axis the ray runs down; ``exit_*`` is -1 (all bits) where a node
    # is left through its high face and 0 where through its low face: a node at ``x0`` of
    # side ``s`` is left at plane ``x0 + (s & exit_x)`` and entered at ``x0 + (s & ~exit_x)``.
    flip = (1 if dx < 0.0 else 0) | (2 if dy < 0.0 else 0) | (4 if dz < 0.0 else 0)
    exit_x = 0 if dx < 0.0 else -1
    exit_y = 0 if dy < 0.0 else -1
    exit_z = 0 if dz < 0.0 else -1
    root = 1 << depth
    tex = face_time(root & ~exit_x, ox, ix)
    tey = face_time(root & ~exit_y, oy, iy)
    tez = face_time(root & ~exit_z, oz, iz)
    t_min = max(max(max(tex, tey), tez), t_from)
    t_leave = min(min(face_time(root & exit_x, ox, ix), face_time(root & exit_y, oy, iy)),
                  face_time(root & exit_z, oz, iz))
    if not t_min < min(t_leave, tmax):
        path[_PATH_LEVEL] = -1
        return MISS, 0, math.inf, NO_NORMAL, 0
    stop_level = min(stop_level, depth)
    use_cone = cone_radius > 0.0 or cone_spread > 0.0
    cone = cone_width(cone_radius, cone_spread, t_min)
    parent = inner_nodes[0] if depth > 0 else 0
    if (stop_level <= 0 or (use_cone and float(root) <= cone)
            or (any_hit and (parent & SOLID_BIT) != 0)):
        path[_PATH_LEVEL] = -1
        return 0, 0, t_min, entry_normal(tex, tey, tez, tmin, dx, dy, dz), 1
    # Restart below the root where a recorded path allows (see the module docstring).
    level = 0
    x0 = 0
    y0 = 0
    z0 = 0
    size = root
    start_base = _START_LEVEL if any_hit else _CLOSEST_START_LEVEL
    start_row = _ANY_HIT_ROW if any_hit else _CLOSEST_ROW
    if path[start_base] > 0 or path[_PATH_LEVEL] > 0:
        qx = int(min(max(floor_float(ox + t_min * dx), 0.0), root - 1.0))
        qy = int(min(max(floor_float(oy + t_min * dy), 0.0), root - 1.0))
        qz = int(min(max(floor_float(oz + t_min * dz), 0.0), root - 1.0))
        # Any-hit rays skip the last hit's path: it may hold solid nodes they must stop at.
        a = 0 if any_hit else restart_level(
            path, _PATH_LEVEL, qx, qy, qz, t_min, ox, oy, oz, ix, iy, iz, exit_x, exit_y,
            exit_z, depth, stop_level, use_cone, cone)
        b = restart_level(path, start_base, qx, qy, qz, t_min, ox, oy, oz, ix, iy, iz,
                          exit_x, exit_y, exit_z, depth, stop_level, use_cone, cone)
        base = _PATH_LEVEL
        if b > a:
            a = b
            base = start_base
            for j in range(a + 1):
                stack[j] = start_stacks[start_row, j]
        if a > 0:
            level = a
            size = root >> a
            x0 = path[base + 1] & -size
            y0 = path[base + 2] & -size
            z0 = path[base + 3] & -size
            parent = stack[a]
    started = False  # every ray records its start path at its first advance
    steps = level + 1
    # The current node is child ``idx`` (octant bits) at ``(x0, y0, z0)`` of side ``size`` of
    # the inner node ``parent`` at ``level``; the ray enters it at ``t_min``.
    size >>= 1
    idx, x0, y0, z0 = child_at(x0, y0, z0, size, ox, oy, oz, ix, iy, iz, t_min, flip)
    while True:
        tx = face_time(x0 + (size & exit_x), ox, ix)
        ty = face_time(y0 + (size & exit_y), oy, iy)
        tz = face_time(z0 + (size & exit_z), oz, iz)
        t_exit = min(min(tx, ty), tz)
        if (parent >> idx) & 1 and t_min < min(t_exit, tmax):
            steps += 1
            node = child_index(parent, idx)
            if level + 1 >= stop_level or (
                use_cone and float(size) <= cone_width(cone_radius, cone_spread, t_min)
            ):
                if any_hit:
                    return node, level + 1, t_min, NO_NORMAL, steps
                stack[level] = parent
                path[_PATH_LEVEL] = level
                path[1] = x0
                path[2] = y0
                path[3] = z0
                tex = face_time(x0 + (size & ~exit_x), ox, ix)
                tey = face_time(y0 + (size & ~exit_y), oy, iy)
                tez = face_time(z0 + (size & ~exit_z), oz, iz)
                normal = entry_normal(tex, tey, tez, tmin, dx, dy, dz)
                return node, level + 1, t_min, normal, steps
            # Descend: remember the parent for the pop, then pick the child the ray is in.
            stack[level] = parent
            parent = inner_nodes[node]
            level += 1
            if any_hit and (parent & SOLID_BIT) != 0:
                return node, level, t_min, NO_NORMAL, steps
            size >>= 1
            idx, x0, y0, z0 = child_at(x0, y0, z0, size, ox, oy, oz, ix, iy, iz, t_min, flip)
            continue
        # Advance to the next node along the ray: step every axis whose exit comes first.
        if not started:
            started = True
            for j in range(level):
                start_stacks[start_row, j] = stack[j]
            start_stacks[start_row, level] = parent
            path[start_base] = level
            path[start_base + 1] = x0
            path[start_base + 2] = y0
            path[start_base + 3] = z0
        step = ((1 if tx <= t_exit else 0) | (2 if ty <= t_exit else 0)
                | (4 if tz <= t_exit else 0))
        t_min = t_exit
        if not t_min < tmax:
            break
        # Branch-free: the stepped axes move by ±size (``~exit_*`` is -1 on axes run down,
        # so ``(size ^ m) - m`` is -size there and size elsewhere).
        nx = x0 + (((size ^ ~exit_x) + exit_x + 1) & -(step & 1))
        ny = y0 + (((size ^ ~exit_y) + exit_y + 1) & -((step >> 1) & 1))
        nz = z0 + (((size ^ ~exit_z) + exit_z + 1) & -(step >> 2))
        if (idx ^ flip) & step:
            # Left the parent: the highest bit in which the positions differ names the
            # level of the first ancestor that holds the new position.
            diff = (x0 ^ nx) | (y0 ^ ny) | (z0 ^ nz)
            if diff >> depth:  # left the root (a negative position sets every high bit)
                break
            h = highest_bit(diff)
            level = depth - h - 1
            parent = stack[level]
            size = 1 << h
            x0 = nx & -size
            y0 = ny & -size
            z0 = nz & -size
            idx = ((x0 >> h) & 1) | (((y0 >> h) & 1) << 1) | (((z0 >> h) & 1) << 2)
        else:
            idx ^= step
            x0 = nx
            y0 = ny
            z0 = nz
    path[_PATH_LEVEL] = -1
    return MISS, 0, math.inf, NO_NORMAL, steps
