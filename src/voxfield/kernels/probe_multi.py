"""Multi-probe light-field tracing (probe thesis §5.4-5.5, Algorithms 4-6).

Each ray is answered by the 8 probes of the lattice cell around its origin (the cage; points
outside the grid use the nearest border cell, as ``ProbeGrid.cell_of``). The first probe is
the one the ordering heuristic prefers; the others follow in the thesis's ``i + 3 mod 8``
order over the cage corners (corner ``c`` has lattice offset ``(c & 1, c >> 1 & 1,
c >> 2 & 1)``: bits zyx). Each probe continues from the ``t`` where the previous one lost
visibility (Algorithm 5), so no part of the ray is marched twice. When every probe of the cage
has lost the ray, the nearest probe answers as an environment map (§5.4): its radiance in
direction ω.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.octahedral import texel_of_direction
from voxfield.kernels.probe_march import FALLBACK, HIT, MISS, UNKNOWN, trace_probe

#: First-probe heuristics.
ORDER_SIGNED_DOT = 0  # max ω · S²(X - P) (thesis §4.3, §5.7)
ORDER_NEAREST = 1  # min |X - P| (McGuire et al. 2017)
ORDER_FIXED = 2  # corner 0 first, whatever the ray

#: Successive corners differ by this, mod 8 (Algorithm 6).
CORNER_STRIDE = 3


@njit(cache=True, nogil=True)
def next_corner(corner: int) -> int:
    """Algorithm 6's ``nextProbe``: ``(i + 3) mod 8``; 3 is odd, so from any start the
    sequence visits all 8 corners once, each move a face reflection or a diagonal."""
    return (corner + CORNER_STRIDE) % 8


@njit(cache=True, nogil=True)
def cage(grid_origin: np.ndarray, grid_spacing: np.ndarray, grid_counts: np.ndarray,
         x: float, y: float, z: float, out: np.ndarray) -> None:
    """The 8 probe indices around point (x, y, z) into ``out[0:8]`` (corner order, bits zyx).
    The cell is ``ProbeGrid.cell_of``'s; on an axis with a single probe both corners are that
    probe, so ``out`` may repeat an index."""
    cell0 = 0
    cell1 = 0
    cell2 = 0
    for axis in range(3):
        p = x if axis == 0 else (y if axis == 1 else z)
        c = math.floor((p - grid_origin[axis]) / grid_spacing[axis])
        top = max(grid_counts[axis] - 2, 0)
        c = int(min(max(c, 0.0), float(top)))
        if axis == 0:
            cell0 = c
        elif axis == 1:
            cell1 = c
        else:
            cell2 = c
    nx = grid_counts[0]
    ny = grid_counts[1]
    for corner in range(8):
        i = min(cell0 + (corner & 1), nx - 1)
        j = min(cell1 + ((corner >> 1) & 1), ny - 1)
        k = min(cell2 + ((corner >> 2) & 1), grid_counts[2] - 1)
        out[corner] = i + nx * (j + ny * k)


@njit(cache=True, nogil=True)
def first_corner(ordering: int, corners: np.ndarray, positions: np.ndarray,
                 enabled: np.ndarray, ox: float, oy: float, oz: float, dx: float, dy: float,
                 dz: float) -> int:
    """The cage corner tried first (-1 when no probe of the cage is enabled). Signed dot:
    largest ``ω · S²(X - P)`` (a probe at ``X`` counts as 1); nearest: smallest ``|X - P|``;
    fixed: the first enabled corner from 0. Ties keep the lower corner."""
    best = -1
    best_score = -math.inf
    for corner in range(8):
        p = corners[corner]
        if not enabled[p]:
            continue
        if ordering == ORDER_FIXED:
            return corner
        vx = ox - positions[p, 0]
        vy = oy - positions[p, 1]
        vz = oz - positions[p, 2]
        length = math.sqrt(vx * vx + vy * vy + vz * vz)
        if ordering == ORDER_NEAREST:
            score = -length
        elif length > 0.0:
            score = (vx * dx + vy * dy + vz * dz) / length
        else:
            score = 1.0
        if score > best_score:
            best_score = score
            best = corner
    return best


@njit(cache=True, nogil=True)
def nearest_enabled(corners: np.ndarray, positions: np.ndarray, enabled: np.ndarray,
                    ox: float, oy: float, oz: float) -> int:
    """The nearest enabled probe of the cage, else of the whole set (-1: none enabled)."""
    best = -1
    best_d = math.inf
    for corner in range(8):
        best, best_d = _closer(corners[corner], best, best_d, positions, enabled, ox, oy, oz)
    if best >= 0:
        return best
    for p in range(len(positions)):
        best, best_d = _closer(p, best, best_d, positions, enabled, ox, oy, oz)
    return best


@njit(cache=True, nogil=True)
def _closer(p: int, best: int, best_d: float, positions: np.ndarray, enabled: np.ndarray,
            ox: float, oy: float, oz: float) -> tuple[int, float]:
    """``(p, its squared distance)`` if probe ``p`` is enabled and nearer than ``best``."""
    if not enabled[p]:
        return best, best_d
    vx = ox - positions[p, 0]
    vy = oy - positions[p, 1]
    vz = oz - positions[p, 2]
    d = vx * vx + vy * vy + vz * vz
    return (p, d) if d < best_d else (best, best_d)


@njit(cache=True, nogil=True)
def trace_light_field_ray(marcher: int, eps_mode: int, ordering: int, fallback: bool,
                          params: np.ndarray, positions: np.ndarray, enabled: np.ndarray,
                          mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
                          normals: np.ndarray, resolution: int, grid_origin: np.ndarray,
                          grid_spacing: np.ndarray, grid_counts: np.ndarray,
                          ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
                          tmin: float, tmax: float, corners: np.ndarray):
    """One ray through its probe cage. Returns ``(kind, t, probe, row, col, tried, fetches,
    steps)``; ``kind`` is ``HIT``, ``MISS``, ``FALLBACK`` (probe = the environment map used,
    t = its stored distance in direction ω) or ``UNKNOWN`` (every probe lost the ray and
    fallback is off; t = how far they got). ``corners`` is 8-int scratch."""
    cage(grid_origin, grid_spacing, grid_counts, ox, oy, oz, corners)
    corner = first_corner(ordering, corners, positions, enabled, ox, oy, oz, dx, dy, dz)
    t = tmin
    tried = 0
    fetches = 0
    steps = 0
    start = corner
    if start >= 0:
        for m in range(8):
            corner = (start + CORNER_STRIDE * m) % 8
            p = corners[corner]
            seen = False
            for earlier in range(m):  # a cage on a one-probe axis repeats probes
                if corners[(start + CORNER_STRIDE * earlier) % 8] == p:
                    seen = True
            if enabled[p] and not seen:
                tried += 1
                kind, t_out, row, col, f, s = trace_probe(
                    marcher, eps_mode, params, positions, mips, mip_offsets, mip_sizes,
                    normals, resolution, p, ox, oy, oz, dx, dy, dz, t, tmax)
                fetches += f
                steps += s
                if kind == HIT or kind == MISS:
                    return kind, t_out, p, row, col, tried, fetches, steps
                t = max(t, t_out)
    if not fallback:
        return UNKNOWN, t, -1, -1, -1, tried, fetches, steps
    p = nearest_enabled(corners, positions, enabled, ox, oy, oz)
    if p < 0:
        return UNKNOWN, t, -1, -1, -1, tried, fetches, steps
    row, col = texel_of_direction(dx, dy, dz, resolution)
    return (FALLBACK, float(mips[p, row * resolution + col]), p, row, col, tried,
            fetches + 1, steps)


@njit(cache=True, nogil=True, parallel=True)
def trace_light_field_rays(marcher: int, eps_mode: int, ordering: int, fallback: bool,
                           params: np.ndarray, positions: np.ndarray, enabled: np.ndarray,
                           mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
                           normals: np.ndarray, radiance: np.ndarray, resolution: int,
                           grid_origin: np.ndarray, grid_spacing: np.ndarray,
                           grid_counts: np.ndarray, origins: np.ndarray, dirs: np.ndarray,
                           tmin: np.ndarray, tmax: np.ndarray, out_kind: np.ndarray,
                           out_t: np.ndarray, out_radiance: np.ndarray,
                           out_normal: np.ndarray, out_distance: np.ndarray,
                           out_probe: np.ndarray, out_tried: np.ndarray,
                           out_fetches: np.ndarray, out_steps: np.ndarray) -> None:
    """Every ray, in parallel blocks; each ray's results depend only on that ray."""
    n = len(origins)
    block = 256
    for b in prange((n + block - 1) // block):
        corners = np.empty(8, np.int64)
        for i in range(b * block, min(n, (b + 1) * block)):
            kind, t, p, row, col, tried, fetches, steps = trace_light_field_ray(
                marcher, eps_mode, ordering, fallback, params, positions, enabled, mips,
                mip_offsets, mip_sizes, normals, resolution, grid_origin, grid_spacing,
                grid_counts, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0],
                dirs[i, 1], dirs[i, 2], tmin[i], tmax[i], corners)
            out_kind[i] = kind
            out_t[i] = t
            out_probe[i] = p
            out_tried[i] = tried
            out_fetches[i] = fetches
            out_steps[i] = steps
            if (kind == HIT or kind == FALLBACK) and row >= 0:
                for c in range(3):
                    out_radiance[i, c] = radiance[p, row, col, c]
                    out_normal[i, c] = normals[p, row, col, c]
                out_distance[i] = mips[p, row * resolution + col]
            else:
                for c in range(3):
                    out_radiance[i, c] = 0.0
                    out_normal[i, c] = 0.0
                out_distance[i] = math.inf


@njit(cache=True, nogil=True, parallel=True)
def trace_single_rays(marcher: int, eps_mode: int, params: np.ndarray, positions: np.ndarray,
                      mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
                      normals: np.ndarray, resolution: int, probe: int, origins: np.ndarray,
                      dirs: np.ndarray, tmin: np.ndarray, tmax: np.ndarray,
                      out_kind: np.ndarray, out_t: np.ndarray, out_row: np.ndarray,
                      out_col: np.ndarray, out_fetches: np.ndarray,
                      out_steps: np.ndarray) -> None:
    """``trace_probe`` for every ray against one probe."""
    n = len(origins)
    for i in prange(n):
        kind, t, row, col, fetches, steps = trace_probe(
            marcher, eps_mode, params, positions, mips, mip_offsets, mip_sizes, normals,
            resolution, probe, origins[i, 0], origins[i, 1], origins[i, 2], dirs[i, 0],
            dirs[i, 1], dirs[i, 2], tmin[i], tmax[i])
        out_kind[i] = kind
        out_t[i] = t
        out_row[i] = row
        out_col[i] = col
        out_fetches[i] = fetches
        out_steps[i] = steps
