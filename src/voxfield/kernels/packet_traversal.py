"""Packet traversal: up to 64 rays walk the octree together, with the scalar loop's results.

Why: the samples of one pixel (and of its neighbours) visit almost the same nodes. The scalar
loop (``kernels.traversal``) pays a dependent load and a hard-to-predict branch per node and
per ray; a packet loads each node's descriptor once and decides for all eight children with
one pass of branch-free arithmetic over the packet's rays (which the compiler vectorises),
and one branch for the whole packet. Supersampled primary rays run about twice as fast this
way, and so do the sun bake's shadow rays, parallel rays from neighbouring voxels (any-hit
packets: a ray stops in the first solid node it enters, as ``occluded`` stops); a packet of
rays that diverge (one ray per pixel over fine voxels, cosine-weighted sky rays) gains
nothing, so those keep the scalar loop.

**Same answers.** Rays are grouped by direction signs (``flip``); within a group the children
of a node, taken in mirrored octant order, are front to back for every ray. A depth-first walk
in that order, with a bit mask of the rays whose clipped interval meets each node, enters for
each ray exactly the nodes the scalar loop enters, in the same order; a ray leaves the packet
at its first hit. Every plane time is ``face_time``'s formula, so hit node, ``t`` (bit for
bit), entry face and step count equal ``trace_ray``'s; the tests check this on adversarial
rays and real scenes. Packets stop at a fixed level only: cone-footprint LOD keeps the scalar
loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.node_descriptor import SOLID_BIT, child_index
from voxfield.kernels.scalar_ops import fmax, fmin
from voxfield.kernels.traversal import (
    MISS,
    NO_NORMAL,
    axis_setup,
    entry_normal,
    flush_uninvertible,
)

#: Most rays one packet holds (one bit each in an int64 mask).
PACKET_RAYS = 64

# Rows of the packet's ray table (``PacketScratch.rays``).
_OX, _OY, _OZ, _IX, _IY, _IZ, _TMIN, _TMAX = range(8)


@njit(cache=True, nogil=True)
def new_packet_scratch(depth: int):
    """Per-thread packet scratch: the walk's stack (node, level, corner, ray mask), the
    packet's ray table, its nine plane times per ray, child masks, the rays of one sign
    group with their results, and each ray's sign group."""
    cap = 8 * (depth + 1) + 1
    return (
        np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 3), np.int64),
        np.empty(cap, np.int64),
        np.empty((8, PACKET_RAYS)),
        np.empty((9, PACKET_RAYS)),
        np.empty(8, np.int64),
        np.empty(PACKET_RAYS, np.int64),
        np.empty(PACKET_RAYS, np.int64), np.empty(PACKET_RAYS, np.int64),
        np.empty(PACKET_RAYS), np.empty(PACKET_RAYS, np.int64), np.empty(PACKET_RAYS, np.int64),
        np.empty(PACKET_RAYS, np.int64),
    )


@njit(cache=True, nogil=True, inline="always")
def _ray_signs(dx: float, dy: float, dz: float) -> int:
    return (1 if dx < 0.0 else 0) | (2 if dy < 0.0 else 0) | (4 if dz < 0.0 else 0)


@njit(cache=True, nogil=True, inline="always")
def _traceable(origins, directions, tmins, tmaxs, k: int) -> bool:
    """Finite ray with non-NaN bounds (``traverse`` answers a miss in 0 steps otherwise)."""
    return (np.isfinite(origins[k, 0]) and np.isfinite(origins[k, 1])
            and np.isfinite(origins[k, 2]) and np.isfinite(directions[k, 0])
            and np.isfinite(directions[k, 1]) and np.isfinite(directions[k, 2])
            and tmins[k] == tmins[k] and tmaxs[k] == tmaxs[k])


@borrowing
def trace_packet(
    count: int, origins: np.ndarray, directions: np.ndarray, tmins: np.ndarray, tmaxs: np.ndarray,
    inner_nodes: np.ndarray, depth: int, stop_level: int, scratch,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, any_hit: bool = False,
) -> None:
    """Trace ``count`` ≤ 64 rays (``origins[k] + t·directions[k]`` over ``[tmins[k],
    tmaxs[k])``) to ``stop_level``; results as ``trace_ray`` with no cone, entry ``k``.
    With ``any_hit`` (``stop_level`` the leaves) they are ``occluded``'s instead: a ray stops
    in the first solid node it enters, and only ``out_node`` (``MISS`` or not) and
    ``out_steps`` mean anything."""
    table = scratch[4]
    members = scratch[7]
    g_node, g_level, g_t, g_normal, g_steps = scratch[8:13]
    group = scratch[13]
    # Each ray's sign group once (-1: not traceable, a miss in 0 steps), then one walk per
    # group present.
    signs = 0
    _clear_results(count, out_node, out_level, out_t, out_normal, out_steps)
    for k in range(count):
        group[k] = -1
        if _traceable(origins, directions, tmins, tmaxs, k):
            group[k] = _ray_signs(flush_uninvertible(directions[k, 0]),
                                  flush_uninvertible(directions[k, 1]),
                                  flush_uninvertible(directions[k, 2]))
            signs |= 1 << group[k]
    for flip in range(8):
        if not (signs >> flip) & 1:
            continue
        n = 0
        for k in range(count):
            if group[k] != flip:
                continue
            table[_OX, n], _, table[_IX, n] = axis_setup(origins[k, 0], directions[k, 0])
            table[_OY, n], _, table[_IY, n] = axis_setup(origins[k, 1], directions[k, 1])
            table[_OZ, n], _, table[_IZ, n] = axis_setup(origins[k, 2], directions[k, 2])
            table[_TMIN, n] = tmins[k]
            table[_TMAX, n] = tmaxs[k]
            members[n] = k
            n += 1
        if n == 0:
            continue
        walk_sign_group(n, flip, inner_nodes, depth, stop_level, scratch,
                        g_node, g_level, g_t, g_normal, g_steps, any_hit)
        for j in range(n):
            k = members[j]
            out_node[k] = g_node[j]
            out_level[k] = g_level[j]
            out_t[k] = g_t[j]
            out_normal[k] = g_normal[j]
            out_steps[k] = g_steps[j]


@njit(cache=True, nogil=True, inline="always")
def _clear_results(n: int, out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
                   out_normal: np.ndarray, out_steps: np.ndarray) -> None:
    """The first ``n`` results as misses in 0 steps, as ``traverse`` answers them."""
    for k in range(n):
        out_node[k] = MISS
        out_level[k] = 0
        out_t[k] = math.inf
        out_normal[k] = NO_NORMAL
        out_steps[k] = 0


@njit(cache=True, nogil=True, inline="always")
def _node_planes(x0: int, y0: int, z0: int, size: int, exit_x: int, exit_y: int,
                 exit_z: int):
    """The planes a ray enters, halves and leaves a node by, per axis in the mirrored frame
    (near, middle, far), as floats for ``face_time``'s formula. (``_child_masks``, the hot
    pass, spells them out: there the tuple measured up to 8 % slower.)"""
    half = size >> 1
    return (float(x0 + (size & ~exit_x)), float(x0 + half), float(x0 + (size & exit_x)),
            float(y0 + (size & ~exit_y)), float(y0 + half), float(y0 + (size & exit_y)),
            float(z0 + (size & ~exit_z)), float(z0 + half), float(z0 + (size & exit_z)))


@njit(cache=True, nogil=True, inline="always")
def _plane_times(n: int, times: np.ndarray, x0: int, y0: int, z0: int, size: int,
                 exit_x: int, exit_y: int, exit_z: int, ox: np.ndarray, oy: np.ndarray,
                 oz: np.ndarray, ix: np.ndarray, iy: np.ndarray, iz: np.ndarray) -> None:
    """Crossing times of a node's nine planes per ray: entry, middle and exit of each axis in
    rows ``3a, 3a + 1, 3a + 2`` (``face_time``'s formula), so a child's entry planes are rows
    ``3a + bit`` and its exit planes the next rows."""
    near_x, mid_x, far_x, near_y, mid_y, far_y, near_z, mid_z, far_z = _node_planes(
        x0, y0, z0, size, exit_x, exit_y, exit_z)
    for k in range(n):
        times[0, k] = (near_x - ox[k]) * ix[k]
        times[1, k] = (mid_x - ox[k]) * ix[k]
        times[2, k] = (far_x - ox[k]) * ix[k]
        times[3, k] = (near_y - oy[k]) * iy[k]
        times[4, k] = (mid_y - oy[k]) * iy[k]
        times[5, k] = (far_y - oy[k]) * iy[k]
        times[6, k] = (near_z - oz[k]) * iz[k]
        times[7, k] = (mid_z - oz[k]) * iz[k]
        times[8, k] = (far_z - oz[k]) * iz[k]


@njit(cache=True, nogil=True, inline="always")
def _interval_mask(n: int, times: np.ndarray, ex: int, ey: int, ez: int, span: int,
                   tmn: np.ndarray, tmx: np.ndarray) -> int:
    """Bit ``k`` set where ray ``k``'s interval between the entry planes (rows ``ex, ey,
    ez`` of ``times``) and the exit planes (``span`` rows further: 1 for a child, 2 for the
    node itself), clipped to its own range, is non-empty. The loop runs over the whole
    packet, active or not: a fixed trip count from 0 is what the compiler vectorises
    (skipping inactive rays measured slower)."""
    mask = 0
    for k in range(n):
        enter = fmax(fmax(fmax(times[ex, k], times[ey, k]), times[ez, k]), tmn[k])
        leave = fmin(fmin(fmin(times[ex + span, k], times[ey + span, k]),
                          times[ez + span, k]), tmx[k])
        mask |= np.int64(enter < leave) << k
    return mask


@njit(cache=True, nogil=True, inline="always")
def _child_masks(n: int, x0: int, y0: int, z0: int, size: int, exit_x: int, exit_y: int,
                 exit_z: int, ox: np.ndarray, oy: np.ndarray, oz: np.ndarray, ix: np.ndarray,
                 iy: np.ndarray, iz: np.ndarray, tmn: np.ndarray, tmx: np.ndarray,
                 masks: np.ndarray) -> None:
    """``masks[i]``: bit ``k`` set where ray ``k``'s clipped interval in child ``i`` (octant
    bits in the mirrored frame) of the node at ``(x0, y0, z0)`` is non-empty, the eight in
    one pass over the packet. Each ray's nine plane times stay in registers, and the
    children share their partial maxima and minima: an axis's entry is clipped by ``tmin``
    and its exit by ``tmax`` once, the x and y pairs once for the four z children. Max and
    min are exact, so every mask equals ``_interval_mask``'s."""
    half = size >> 1
    near_x = float(x0 + (size & ~exit_x))
    mid_x = float(x0 + half)
    far_x = float(x0 + (size & exit_x))
    near_y = float(y0 + (size & ~exit_y))
    mid_y = float(y0 + half)
    far_y = float(y0 + (size & exit_y))
    near_z = float(z0 + (size & ~exit_z))
    mid_z = float(z0 + half)
    far_z = float(z0 + (size & exit_z))
    m0 = m1 = m2 = m3 = m4 = m5 = m6 = m7 = 0
    for k in range(n):
        lo = tmn[k]
        hi = tmx[k]
        x_in0 = fmax((near_x - ox[k]) * ix[k], lo)
        x_mid = (mid_x - ox[k]) * ix[k]
        x_in1 = fmax(x_mid, lo)
        x_out0 = fmin(x_mid, hi)
        x_out1 = fmin((far_x - ox[k]) * ix[k], hi)
        y_in0 = (near_y - oy[k]) * iy[k]
        y_mid = (mid_y - oy[k]) * iy[k]
        y_out1 = (far_y - oy[k]) * iy[k]
        z_in0 = (near_z - oz[k]) * iz[k]
        z_mid = (mid_z - oz[k]) * iz[k]
        z_out1 = (far_z - oz[k]) * iz[k]
        # Entry and exit of the four (x, y) columns, then of each z half.
        in00 = fmax(x_in0, y_in0)
        in10 = fmax(x_in1, y_in0)
        in01 = fmax(x_in0, y_mid)
        in11 = fmax(x_in1, y_mid)
        out00 = fmin(x_out0, y_mid)
        out10 = fmin(x_out1, y_mid)
        out01 = fmin(x_out0, y_out1)
        out11 = fmin(x_out1, y_out1)
        m0 |= np.int64(fmax(in00, z_in0) < fmin(out00, z_mid)) << k
        m1 |= np.int64(fmax(in10, z_in0) < fmin(out10, z_mid)) << k
        m2 |= np.int64(fmax(in01, z_in0) < fmin(out01, z_mid)) << k
        m3 |= np.int64(fmax(in11, z_in0) < fmin(out11, z_mid)) << k
        m4 |= np.int64(fmax(in00, z_mid) < fmin(out00, z_out1)) << k
        m5 |= np.int64(fmax(in10, z_mid) < fmin(out10, z_out1)) << k
        m6 |= np.int64(fmax(in01, z_mid) < fmin(out01, z_out1)) << k
        m7 |= np.int64(fmax(in11, z_mid) < fmin(out11, z_out1)) << k
    masks[0] = m0
    masks[1] = m1
    masks[2] = m2
    masks[3] = m3
    masks[4] = m4
    masks[5] = m5
    masks[6] = m6
    masks[7] = m7


@njit(cache=True, nogil=True, inline="always")
def _child_entry(k: int, i: int, x0: int, y0: int, z0: int, size: int, exit_x: int,
                 exit_y: int, exit_z: int, ox: np.ndarray, oy: np.ndarray, oz: np.ndarray,
                 ix: np.ndarray, iy: np.ndarray, iz: np.ndarray) -> tuple[float, float, float]:
    """Ray ``k``'s entry-plane times of child ``i`` (mirrored octant bits), each by
    ``face_time``'s formula as ``_plane_times`` computes it."""
    half = size >> 1
    px = float(x0 + half) if i & 1 else float(x0 + (size & ~exit_x))
    py = float(y0 + half) if i & 2 else float(y0 + (size & ~exit_y))
    pz = float(z0 + half) if i & 4 else float(z0 + (size & ~exit_z))
    return (px - ox[k]) * ix[k], (py - oy[k]) * iy[k], (pz - oz[k]) * iz[k]


@borrowing
def walk_sign_group(
    n: int, flip: int, inner_nodes: np.ndarray, depth: int, stop_level: int, scratch,
    out_node: np.ndarray, out_level: np.ndarray, out_t: np.ndarray,
    out_normal: np.ndarray, out_steps: np.ndarray, any_hit: bool,
) -> None:
    """The depth-first packet walk over the first ``n`` rays of the ray table, which share
    the direction signs ``flip``."""
    s_node, s_level, s_corner, s_mask, table, times, masks = scratch[:7]
    ox = table[_OX]
    oy = table[_OY]
    oz = table[_OZ]
    ix = table[_IX]
    iy = table[_IY]
    iz = table[_IZ]
    tmn = table[_TMIN]
    tmx = table[_TMAX]
    stop_level = min(stop_level, depth)
    root = 1 << depth
    # ``exit_*``: -1 on axes left through their high face, 0 on axes run down (as traverse).
    exit_x = 0 if flip & 1 else -1
    exit_y = 0 if flip & 2 else -1
    exit_z = 0 if flip & 4 else -1
    sx = -1.0 if flip & 1 else 1.0
    sy = -1.0 if flip & 2 else 1.0
    sz = -1.0 if flip & 4 else 1.0
    _clear_results(n, out_node, out_level, out_t, out_normal, out_steps)
    _plane_times(n, times, 0, 0, 0, root, exit_x, exit_y, exit_z, ox, oy, oz, ix, iy, iz)
    full = _interval_mask(n, times, 0, 3, 6, 2, tmn, tmx)
    if full == 0:
        return
    if stop_level <= 0:
        for k in range(n):
            if (full >> k) & 1:
                out_steps[k] = 1
                out_node[k] = 0
                out_t[k] = fmax(fmax(fmax(times[0, k], times[3, k]), times[6, k]), tmn[k])
                out_normal[k] = entry_normal(times[0, k], times[3, k], times[6, k], tmn[k],
                                             sx, sy, sz)
        return
    done = 0
    s_node[0] = 0
    s_level[0] = 0
    s_corner[0, 0] = 0
    s_corner[0, 1] = 0
    s_corner[0, 2] = 0
    s_mask[0] = full
    sp = 1
    while sp > 0:
        sp -= 1
        active = s_mask[sp] & ~done
        if active == 0:
            continue
        for k in range(n):
            out_steps[k] += (active >> k) & 1
        node = s_node[sp]
        level = s_level[sp]
        x0 = s_corner[sp, 0]
        y0 = s_corner[sp, 1]
        z0 = s_corner[sp, 2]
        size = root >> level
        half = size >> 1
        descriptor = inner_nodes[node]
        if any_hit and (descriptor & SOLID_BIT) != 0:
            # Every ray that enters a solid node is blocked there, as ``occluded`` stops.
            for k in range(n):
                if (active >> k) & 1:
                    out_node[k] = node
                    out_level[k] = level
            done |= active
            if done == full:
                return
            continue
        _child_masks(n, x0, y0, z0, size, exit_x, exit_y, exit_z, ox, oy, oz, ix, iy, iz,
                     tmn, tmx, masks)
        for i in range(8):
            masks[i] = active & masks[i] if (descriptor >> (i ^ flip)) & 1 else 0
        if level + 1 >= stop_level:
            # The children are leaves for this query: each ray stops at the first it meets.
            for i in range(8):
                hits = masks[i] & ~done
                if hits == 0:
                    continue
                child = child_index(descriptor, i ^ flip)
                for k in range(n):
                    if (hits >> k) & 1:
                        out_steps[k] += 1
                        out_node[k] = child
                        out_level[k] = level + 1
                        if any_hit:
                            continue  # an any-hit answer has no time or normal
                        tx, ty, tz = _child_entry(k, i, x0, y0, z0, size, exit_x, exit_y,
                                                  exit_z, ox, oy, oz, ix, iy, iz)
                        out_t[k] = fmax(fmax(fmax(tx, ty), tz), tmn[k])
                        out_normal[k] = entry_normal(tx, ty, tz, tmn[k], sx, sy, sz)
                done |= hits
            if done == full:
                return
            continue
        # Push the children back to front so the nearest is walked first.
        for i in range(7, -1, -1):
            if masks[i] == 0:
                continue
            octant = i ^ flip
            s_node[sp] = child_index(descriptor, octant)
            s_level[sp] = level + 1
            s_corner[sp, 0] = x0 + (half if octant & 1 else 0)
            s_corner[sp, 1] = y0 + (half if octant & 2 else 0)
            s_corner[sp, 2] = z0 + (half if octant & 4 else 0)
            s_mask[sp] = masks[i]
            sp += 1
