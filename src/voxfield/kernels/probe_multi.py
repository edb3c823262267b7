"""Multi-probe light-field tracing (probe thesis §5.4-5.5, Algorithms 4-6).

Each ray is answered by the 8 probes of the lattice cell around the point it has reached (the
cage; points outside the grid use the nearest border cell, as ``ProbeGrid.cell_of``): at
first its origin. The first probe is the one the ordering heuristic prefers; the others
follow in the thesis's ``i + 3 mod 8`` order over the cage corners (corner ``c`` has lattice
offset ``(c & 1, c >> 1 & 1, c >> 2 & 1)``: bits zyx). Each probe continues from the ``t``
where the previous one lost visibility (Algorithm 5), so no part of the ray is marched twice;
a probe that loses the ray further on re-forms the cage around that point, so the probes
near where the ray now is carry it on (the thesis keeps the origin's cage, whose probes may
all sit on one side of the ray). When every probe of a cage loses the ray at once, the probes
one lattice step outside it (the ring) try, nearest first, before the ray is given up (the
thesis stops at the cage; ``P_RING``). When no probe can carry the ray further, the nearest
probe answers as an environment map (§5.4): its radiance in direction ω.

A hit's colour is read at the hit point, bilinearly over the bordered map of a probe that
sees that point (its stored distance agrees): by default the one whose texels are smallest
there (``COLOUR_FOOTPRINT``), or the one that sees it most nearly along the ray
(``COLOUR_PARALLEL``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from voxfield.kernels.octahedral import oct_encode, texel_of_direction
from voxfield.kernels.probe_march import (
    FALLBACK,
    HIT,
    MISS,
    P_BILINEAR,
    P_COLOUR_PROBE,
    P_CONSENSUS,
    P_EPSILON,
    P_REFINE,
    P_RING,
    UNKNOWN,
    slope_thickness,
    steepest_slope_thickness,
    texel_angle,
    trace_probe,
)
from voxfield.kernels.scheduling import claim_items, new_run_queue

#: First-probe heuristics.
ORDER_SIGNED_DOT = 0  # max ω · S²(X - P) (thesis §4.3, §5.7)
ORDER_NEAREST = 1  # min |X - P| (McGuire et al. 2017)
ORDER_FIXED = 2  # corner 0 first, whatever the ray

#: Which of the probes that see a hit point answers its colour.
#: The smallest texel on the surface: distance over |cos| between the stored normal and the
#: probe's direction. Baked radiance is view-independent (albedo, diffuse light), so the
#: sharpest view of the point is the best one, and more probes can only make it sharper.
COLOUR_FOOTPRINT = 0
#: The probe most parallel to the ray (the view most like the camera's: for radiance that
#: varies with direction).
COLOUR_PARALLEL = 1
#: Grazing views count as this |cos| at most, so a probe exactly in the surface's plane
#: still has a finite footprint.
FOOTPRINT_MIN_COSINE = 0.05

#: Probes of the cage that must agree before a hit is moved: that see empty space at it
#: (``seen_through``, the consensus check) or that find a surface in front of it
#: (``hit_in_front``). One alone is often wrong beside an edge, where its texel spans two
#: surfaces (measured, built-in Cornell box, 8 probes, 48² maps, 6000 random rays: hits
#: more than two voxels short 35 → 50 with one witness in front, 35 → 43 with two, while
#: the far ones fall alike, 73 → 38 / 40; Cornell box room view at 256², 8 / 27 / 64
#: probes: the consensus check with one witness 36.21 / 38.64 / 39.56 dB, with two 36.29 /
#: 38.91 / 40.08).
WITNESSES = 2

#: Successive corners differ by this, mod 8 (Algorithm 6).
CORNER_STRIDE = 3
#: Most probe traces one ray makes across all the cages it passes through.
MAX_PROBE_TRACES = 32
#: Probes one lattice step outside a cage: the 4x4x4 block around its cell less its 8.
RING_SIZE = 56


@njit(cache=True, nogil=True)
def next_corner(corner: int) -> int:
    """Algorithm 6's ``nextProbe``: ``(i + 3) mod 8``; 3 is odd, so from any start the
    sequence visits all 8 corners once, each move a face reflection or a diagonal."""
    return (corner + CORNER_STRIDE) % 8


@njit(cache=True, nogil=True)
def cage_cell(grid_origin: np.ndarray, grid_spacing: np.ndarray, grid_counts: np.ndarray,
              x: float, y: float, z: float) -> tuple[int, int, int]:
    """The lattice cell around point (x, y, z): ``ProbeGrid.cell_of``'s, its lowest corner's
    lattice index per axis (the nearest border cell for points outside the grid)."""
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
    return cell0, cell1, cell2


@njit(cache=True, nogil=True)
def cage(grid_origin: np.ndarray, grid_spacing: np.ndarray, grid_counts: np.ndarray,
         x: float, y: float, z: float, out: np.ndarray) -> None:
    """The 8 probe indices around point (x, y, z) into ``out[0:8]`` (corner order, bits zyx).
    The cell is ``cage_cell``'s; on an axis with a single probe both corners are that
    probe, so ``out`` may repeat an index."""
    cell0, cell1, cell2 = cage_cell(grid_origin, grid_spacing, grid_counts, x, y, z)
    nx = grid_counts[0]
    ny = grid_counts[1]
    for corner in range(8):
        i = min(cell0 + (corner & 1), nx - 1)
        j = min(cell1 + ((corner >> 1) & 1), ny - 1)
        k = min(cell2 + ((corner >> 2) & 1), grid_counts[2] - 1)
        out[corner] = i + nx * (j + ny * k)


@njit(cache=True, nogil=True)
def probe_ring(grid_origin: np.ndarray, grid_spacing: np.ndarray, grid_counts: np.ndarray,
               positions: np.ndarray, enabled: np.ndarray, x: float, y: float, z: float,
               out: np.ndarray, out_d2: np.ndarray) -> int:
    """The enabled probes one lattice step outside the cage around (x, y, z) (the 4x4x4
    block around its cell, less the cage; fewer at the grid's border) into ``out``, nearest
    to the point first (ties by index); returns how many. ``out`` and ``out_d2`` hold
    ``RING_SIZE``."""
    cell0, cell1, cell2 = cage_cell(grid_origin, grid_spacing, grid_counts, x, y, z)
    nx = grid_counts[0]
    ny = grid_counts[1]
    nz = grid_counts[2]
    count = 0
    for k in range(max(cell2 - 1, 0), min(cell2 + 3, nz)):
        for j in range(max(cell1 - 1, 0), min(cell1 + 3, ny)):
            for i in range(max(cell0 - 1, 0), min(cell0 + 3, nx)):
                if (cell0 <= i <= cell0 + 1 and cell1 <= j <= cell1 + 1
                        and cell2 <= k <= cell2 + 1):
                    continue  # the cage's own corner
                p = i + nx * (j + ny * k)
                if not enabled[p]:
                    continue
                vx = x - positions[p, 0]
                vy = y - positions[p, 1]
                vz = z - positions[p, 2]
                d2 = vx * vx + vy * vy + vz * vz
                at = count
                while at > 0 and out_d2[at - 1] > d2:  # insertion: a stable nearest-first
                    out[at] = out[at - 1]
                    out_d2[at] = out_d2[at - 1]
                    at -= 1
                out[at] = p
                out_d2[at] = d2
                count += 1
    return count


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
    scale = _distance_scale(ox, oy, oz)
    best = -1
    best_d = math.inf
    for corner in range(8):
        best, best_d = _closer(corners[corner], best, best_d, positions, enabled, ox, oy, oz,
                               scale)
    if best >= 0:
        return best
    for p in range(len(positions)):
        best, best_d = _closer(p, best, best_d, positions, enabled, ox, oy, oz, scale)
    return best


@njit(cache=True, nogil=True)
def _distance_scale(ox: float, oy: float, oz: float) -> float:
    """A power of two that keeps the squared offsets from a point this far out finite: from
    an origin of 1e300 every one was inf, none was nearer than inf, and the fallback found
    no probe. 1 for any point a scene holds (the offsets are then exactly as before)."""
    far = max(abs(ox), abs(oy), abs(oz))
    return 2.0 ** -600 if far > 1e150 else 1.0


@njit(cache=True, nogil=True)
def _closer(p: int, best: int, best_d: float, positions: np.ndarray, enabled: np.ndarray,
            ox: float, oy: float, oz: float, scale: float) -> tuple[int, float]:
    """``(p, its squared distance · scale²)`` if probe ``p`` is enabled and nearer than
    ``best``."""
    if not enabled[p]:
        return best, best_d
    vx = (ox - positions[p, 0]) * scale
    vy = (oy - positions[p, 1]) * scale
    vz = (oz - positions[p, 2]) * scale
    d = vx * vx + vy * vy + vz * vz
    return (p, d) if d < best_d else (best, best_d)


@njit(cache=True, nogil=True)
def trace_light_field_ray(marcher: int, eps_mode: int, ordering: int, fallback: bool,
                          params: np.ndarray, positions: np.ndarray, enabled: np.ndarray,
                          mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
                          normals: np.ndarray, resolution: int, grid_origin: np.ndarray,
                          grid_spacing: np.ndarray, grid_counts: np.ndarray,
                          ox: float, oy: float, oz: float, dx: float, dy: float, dz: float,
                          tmin: float, tmax: float, corners: np.ndarray,
                          tried_probe: np.ndarray, tried_t: np.ndarray,
                          corners2: np.ndarray, ring: np.ndarray, ring_d2: np.ndarray):
    """One ray through its probe cages. Returns ``(kind, t, probe, row, col, tried, fetches,
    steps)``; ``kind`` is ``HIT``, ``MISS``, ``FALLBACK`` (probe = the environment map used,
    t = its stored distance in direction ω) or ``UNKNOWN`` (every probe lost the ray and
    fallback is off; t = how far they got).

    The cage is formed around the point the ray has reached: at first its origin, then,
    each time a probe loses the ray further on, the point where it was lost, so the probes
    around that point (not those around the camera) continue it; with ``params[P_RING]``,
    when all of them lose it there, the ring around the cage tries next (``probe_ring``,
    nearest first). A probe is never traced twice from the same point. With
    ``params[P_CONSENSUS]`` a hit that other probes of the cage around it see through
    (``seen_through``) is not taken: the ray marches on past it, and comes back to it only
    if every probe loses the ray behind it.
    ``corners`` and ``corners2`` are 8-int scratch, ``ring`` / ``ring_d2`` ``RING_SIZE``;
    ``tried_probe`` / ``tried_t`` (``MAX_PROBE_TRACES`` each) log the traces made."""
    t = tmin
    tried = 0
    fetches = 0
    steps = 0
    # The first hit the consensus check passed over: the answer if no probe can tell what
    # lies behind it (a proven miss still wins: the witnesses saw empty space there too).
    kept_t = math.inf
    kept_probe = -1
    kept_row = -1
    kept_col = -1
    ring_on = params[P_RING] != 0.0
    while tried < MAX_PROBE_TRACES and t < tmax:
        qx = ox + t * dx
        qy = oy + t * dy
        qz = oz + t * dz
        cage(grid_origin, grid_spacing, grid_counts, qx, qy, qz, corners)
        start = first_corner(ordering, corners, positions, enabled, qx, qy, qz, dx, dy, dz)
        if start < 0:
            if not ring_on:
                break
            start = 0  # no probe of the cage is enabled: the ring alone
        advanced = False
        ring_count = 0
        for m in range(8 + RING_SIZE):
            if tried >= MAX_PROBE_TRACES:
                break  # the budget is spent: no ring to list, no probe to try
            if m < 8:
                p = corners[(start + CORNER_STRIDE * m) % 8]
            else:
                if m == 8:
                    if not ring_on:
                        break
                    ring_count = probe_ring(grid_origin, grid_spacing, grid_counts,
                                            positions, enabled, qx, qy, qz, ring, ring_d2)
                if m - 8 >= ring_count:
                    break
                p = ring[m - 8]
            if not enabled[p]:
                continue
            again = False
            for j in range(tried):
                if tried_probe[j] == p and tried_t[j] == t:
                    again = True  # from this very point (a one-probe axis repeats corners)
            if again:
                continue
            tried_probe[tried] = p
            tried_t[tried] = t
            tried += 1
            kind, t_out, row, col, f, s = trace_probe(
                marcher, eps_mode, params, positions, mips, mip_offsets, mip_sizes,
                normals, resolution, p, ox, oy, oz, dx, dy, dz, t, tmax)
            fetches += f
            steps += s
            if kind == HIT and params[P_CONSENSUS] != 0.0:
                fetches += 8
                if seen_through(positions, enabled, normals, mips, resolution, grid_origin,
                                grid_spacing, grid_counts, p, ox + t_out * dx,
                                oy + t_out * dy, oz + t_out * dz, hit_tolerance(params),
                                corners2):
                    # Other probes see empty space at the hit point: march on past it.
                    if kept_probe < 0:
                        kept_t = t_out
                        kept_probe = p
                        kept_row = row
                        kept_col = col
                    kind = UNKNOWN
                    t_out = t_out + hit_tolerance(params)
            if kind == HIT or kind == MISS:
                return kind, t_out, p, row, col, tried, fetches, steps
            if t_out > t:
                t = t_out
                advanced = True
                break  # re-form the cage where this probe lost the ray
        if not advanced:
            break
    if kept_probe >= 0:
        return HIT, kept_t, kept_probe, kept_row, kept_col, tried, fetches, steps
    if not fallback:
        return UNKNOWN, t, -1, -1, -1, tried, fetches, steps
    cage(grid_origin, grid_spacing, grid_counts, ox, oy, oz, corners)
    p = nearest_enabled(corners, positions, enabled, ox, oy, oz)
    if p < 0:
        return UNKNOWN, t, -1, -1, -1, tried, fetches, steps
    row, col = texel_of_direction(dx, dy, dz, resolution)
    return (FALLBACK, float(mips[p, row * resolution + col]), p, row, col, tried,
            fetches + 1, steps)


@njit(cache=True, nogil=True)
def point_from_probe(positions: np.ndarray, normals: np.ndarray, mips: np.ndarray,
                     resolution: int, probe: int, yx: float, yy: float, yz: float,
                     tolerance: float):
    """Point ``Y`` as probe ``probe`` sees it: ``(length, cx, cy, cz, row, col, stored,
    slack)`` — its distance and unit direction from the probe, the nearest texel, the
    distance stored there, and how far they may differ while the probe still sees ``Y``
    (``view_slack``). ``length`` 0: ``Y`` is the probe's centre (the rest undefined)."""
    length, cx, cy, cz, row, col, stored = probe_view(positions, mips, resolution, probe, yx,
                                                      yy, yz)
    if length == 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0, 0, 0.0, 0.0
    slack = view_slack(normals, resolution, probe, length, cx, cy, cz, row, col, tolerance)
    return length, cx, cy, cz, row, col, stored, slack


@njit(cache=True, nogil=True, inline="always")
def probe_view(positions: np.ndarray, mips: np.ndarray, resolution: int, probe: int,
               yx: float, yy: float, yz: float):
    """``point_from_probe`` without the slack: ``(length, cx, cy, cz, row, col, stored)``.
    The slack is at least the tolerance, so a check that the stored distance passes ``Y`` by
    more than the slack can first test it against the tolerance and leave most probes'
    normals unread (each is another cache miss)."""
    vx = yx - positions[probe, 0]
    vy = yy - positions[probe, 1]
    vz = yz - positions[probe, 2]
    length = math.sqrt(vx * vx + vy * vy + vz * vz)
    if length == 0.0:
        return 0.0, 0.0, 0.0, 1.0, 0, 0, 0.0
    cx = vx / length
    cy = vy / length
    cz = vz / length
    row, col = texel_of_direction(cx, cy, cz, resolution)
    return length, cx, cy, cz, row, col, np.float64(mips[probe, row * resolution + col])


@njit(cache=True, nogil=True, inline="always")
def view_slack(normals: np.ndarray, resolution: int, probe: int, length: float, cx: float,
               cy: float, cz: float, row: int, col: int, tolerance: float) -> float:
    """How far a probe's stored distance may differ from ``length`` while it still sees the
    point: ``tolerance`` plus half the depth the texel's surface spans (never less than
    ``tolerance``)."""
    return tolerance + slope_thickness(
        length, cx, cy, cz, np.float64(normals[probe, row, col, 0]),
        np.float64(normals[probe, row, col, 1]), np.float64(normals[probe, row, col, 2]),
        resolution)


@njit(cache=True, nogil=True)
def seen_through(positions: np.ndarray, enabled: np.ndarray, normals: np.ndarray,
                 mips: np.ndarray, resolution: int, grid_origin: np.ndarray,
                 grid_spacing: np.ndarray, grid_counts: np.ndarray, hit_probe: int, yx: float,
                 yy: float, yz: float, tolerance: float, corners: np.ndarray) -> bool:
    """Whether ``WITNESSES`` probes of the cage around ``Y`` (other than the one that found
    it) store a surface farther than ``Y`` in ``Y``'s direction, by more than ``tolerance``
    plus the texel's slope: they see empty space where the hit claims a surface."""
    cage(grid_origin, grid_spacing, grid_counts, yx, yy, yz, corners)
    seen = 0
    for corner in range(8):
        q = corners[corner]
        if q == hit_probe or not enabled[q]:
            continue
        length, cx, cy, cz, row, col, stored = probe_view(positions, mips, resolution, q, yx,
                                                          yy, yz)
        if not (length > 0.0 and stored > length + tolerance):
            continue  # not past Y by the tolerance, so not by the slack either
        if stored > length + view_slack(normals, resolution, q, length, cx, cy, cz, row, col,
                                        tolerance):
            seen += 1
            if seen >= WITNESSES:
                return True
    return False


@njit(cache=True, nogil=True, inline="always")
def colour_score(rule: int, length: float, cx: float, cy: float, cz: float, dx: float,
                 dy: float, dz: float, nx: float, ny: float, nz: float) -> float:
    """How well a probe that sees a point from ``length`` away in direction ``c`` (stored
    normal ``n`` there) answers the colour of a ray ``d`` hitting it: larger is better."""
    if rule == COLOUR_PARALLEL:
        return cx * dx + cy * dy + cz * dz
    cosine = max(abs(nx * cx + ny * cy + nz * cz), FOOTPRINT_MIN_COSINE)
    return -length / cosine


@njit(cache=True, nogil=True, inline="always")
def sees_front(length: float, stored: float, slack: float, nx: float, ny: float, nz: float,
               dx: float, dy: float, dz: float) -> bool:
    """Whether a probe ``length`` from a point sees it on a surface a ray ``d`` hits from the
    front: its stored distance agrees (within ``slack``) and its stored normal faces the ray
    (not the back of a thin wall, whose other side the ray hit)."""
    return (length > 0.0 and abs(stored - length) <= slack
            and nx * dx + ny * dy + nz * dz < 0.0)


@njit(cache=True, nogil=True)
def hit_colour_probe(positions: np.ndarray, enabled: np.ndarray, normals: np.ndarray,
                     mips: np.ndarray, resolution: int, grid_origin: np.ndarray,
                     grid_spacing: np.ndarray, grid_counts: np.ndarray, hit_probe: int,
                     yx: float, yy: float, yz: float, dx: float, dy: float, dz: float,
                     tolerance: float, corners: np.ndarray, rule: int) -> int:
    """The probe whose radiance answers a hit at ``Y``: of the cage around ``Y`` (and the
    probe that found the hit), the best by ``rule`` (``colour_score``) of those that see ``Y``
    itself (``sees_front``). The probe that found the hit may have seen it through a texel
    that spans an edge; each candidate is judged by its own texel, so near a corner the
    sharpest view decides which wall the point is on."""
    cage(grid_origin, grid_spacing, grid_counts, yx, yy, yz, corners)
    best = hit_probe
    best_score = -math.inf
    for corner in range(9):
        q = hit_probe if corner == 8 else corners[corner]
        if not enabled[q]:
            continue
        length, cx, cy, cz, row, col, stored = probe_view(positions, mips, resolution, q, yx,
                                                          yy, yz)
        if not abs(stored - length) <= tolerance + steepest_slope_thickness(length,
                                                                            resolution):
            continue  # off by more than any slack: the normal need not be read
        nx = np.float64(normals[q, row, col, 0])
        ny = np.float64(normals[q, row, col, 1])
        nz = np.float64(normals[q, row, col, 2])
        slack = tolerance + slope_thickness(length, cx, cy, cz, nx, ny, nz, resolution)
        if not sees_front(length, stored, slack, nx, ny, nz, dx, dy, dz):
            continue
        score = colour_score(rule, length, cx, cy, cz, dx, dy, dz, nx, ny, nz)
        if score > best_score:
            best_score = score
            best = q
    return best


@njit(cache=True, nogil=True)
def radiance_at(radiance_bordered: np.ndarray, distance_bordered: np.ndarray, probe: int,
                cx: float, cy: float, cz: float, length: float, slack: float,
                resolution: int) -> tuple[float, float, float]:
    """Bilinear radiance of ``probe`` in direction ``c`` over its bordered map, leaving out
    texels whose stored distance disagrees with ``length`` by more than ``slack`` (they show
    another surface); the nearest texel when all four do."""
    u, v = oct_encode(cx, cy, cz)
    x = u * resolution + 0.5
    y = v * resolution + 0.5
    x0 = min(max(int(math.floor(x)), 0), resolution)
    y0 = min(max(int(math.floor(y)), 0), resolution)
    fx = min(max(x - x0, 0.0), 1.0)
    fy = min(max(y - y0, 0.0), 1.0)
    r = 0.0
    g = 0.0
    b = 0.0
    total = 0.0
    for k in range(4):
        ix = x0 + (k & 1)
        iy = y0 + (k >> 1)
        w = (fx if k & 1 else 1.0 - fx) * (fy if k >> 1 else 1.0 - fy)
        if w <= 0.0:
            continue
        stored = np.float64(distance_bordered[probe, iy, ix])
        if not abs(stored - length) <= slack:
            continue
        r += w * radiance_bordered[probe, iy, ix, 0]
        g += w * radiance_bordered[probe, iy, ix, 1]
        b += w * radiance_bordered[probe, iy, ix, 2]
        total += w
    if total > 1e-9:
        return r / total, g / total, b / total
    row, col = texel_of_direction(cx, cy, cz, resolution)
    return (np.float64(radiance_bordered[probe, row + 1, col + 1, 0]),
            np.float64(radiance_bordered[probe, row + 1, col + 1, 1]),
            np.float64(radiance_bordered[probe, row + 1, col + 1, 2]))


class TraceModes(NamedTuple):
    """How rays are traced (``lightfield.LightFieldOptions`` as numbers): marcher, epsilon
    mode, cage ordering, whether to fall back, and the float parameters (``P_*``)."""

    marcher: int
    eps_mode: int
    ordering: int
    fallback: bool
    params: np.ndarray


class ProbeField(NamedTuple):
    """What a trace reads of a packed probe set, named as ``lightfield.PackedProbes``'s
    attributes: positions, enabled flags, distance mips, normals, radiance (plain and
    bordered for bilinear reads), map resolution and the grid."""

    positions: np.ndarray
    enabled: np.ndarray
    mips: np.ndarray
    mip_offsets: np.ndarray
    mip_sizes: np.ndarray
    normals: np.ndarray
    radiance: np.ndarray
    radiance_bordered: np.ndarray
    distance_bordered: np.ndarray
    resolution: int
    grid_origin: np.ndarray
    grid_spacing: np.ndarray
    grid_counts: np.ndarray


class RayBatch(NamedTuple):
    """Rays ``o + t·d`` with ``tmin[i] <= t < tmax[i]``."""

    origins: np.ndarray
    dirs: np.ndarray
    tmin: np.ndarray
    tmax: np.ndarray


class LightFieldOutputs(NamedTuple):
    """Per-ray answers, named as ``lightfield.LightFieldHits``'s arrays: kind, t, radiance,
    normal, stored distance, answering probe, probes tried, texel fetches and march steps."""

    kind: np.ndarray
    t: np.ndarray
    radiance: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    probe: np.ndarray
    probes_tried: np.ndarray
    fetches: np.ndarray
    steps: np.ndarray


#: Rays a thread claims at a time in ``trace_light_field_rays``.
RAY_BLOCK = 256


@njit(cache=True, nogil=True, parallel=True)
def trace_light_field_rays(modes: TraceModes, field: ProbeField, rays: RayBatch,
                           out: LightFieldOutputs, threads: int = 1) -> None:
    """Every ray, in blocks of ``RAY_BLOCK`` that ``threads`` workers claim as they are free
    (``kernels.scheduling.claim_items``; pass ``numba.get_num_threads()``); each ray's results
    depend only on that ray. A hit's colour comes from ``hit_colour_probe``, read bilinearly
    at the hit point."""
    queue = new_run_queue()
    tolerance = hit_tolerance(modes.params)
    for _ in prange(threads):
        trace_blocks(queue, modes, field, rays, out, tolerance)


@njit(cache=True, nogil=True)
def trace_blocks(queue: np.ndarray, modes: TraceModes, field: ProbeField, rays: RayBatch,
                 out: LightFieldOutputs, tolerance: float) -> None:
    """One worker's share of ``trace_light_field_rays``: blocks claimed from ``queue`` until
    none is left, traced in the worker's own scratch."""
    scratch = new_ray_scratch()
    n = len(rays.origins)
    while True:
        first, last = claim_items(queue, n, RAY_BLOCK)
        if first == last:
            return
        for i in range(first, last):
            answer_ray(i, modes, field, rays, out, tolerance, scratch)


@njit(cache=True, nogil=True)
def hit_tolerance(params: np.ndarray) -> float:
    """How far a probe's stored distance may differ from a hit point's for the probe to see
    it (plus the texel's slope): ε and half a voxel."""
    return params[P_EPSILON] + 0.5


@njit(cache=True, nogil=True)
def new_ray_scratch():
    """One thread's scratch for ``answer_ray``: two cage buffers, the log of the probe
    traces of one ray and the ring's two buffers. (The CUDA kernel builds the same tuple
    from local arrays.)"""
    return (np.empty(8, np.int64), np.empty(8, np.int64),
            np.empty(MAX_PROBE_TRACES, np.int64), np.empty(MAX_PROBE_TRACES, np.float64),
            np.empty(RING_SIZE, np.int64), np.empty(RING_SIZE, np.float64))


@njit(cache=True, nogil=True)
def hit_in_front(marcher: int, eps_mode: int, params: np.ndarray, positions: np.ndarray,
                 enabled: np.ndarray, mips: np.ndarray, mip_offsets: np.ndarray,
                 mip_sizes: np.ndarray, normals: np.ndarray, resolution: int,
                 grid_origin: np.ndarray, grid_spacing: np.ndarray, grid_counts: np.ndarray,
                 hit_probe: int, row: int, col: int, ox: float, oy: float, oz: float,
                 dx: float, dy: float, dz: float, t: float, tmin: float, tolerance: float,
                 corners: np.ndarray):
    """A hit at ``t`` checked against the other probes of the cage around it: one that
    stores a surface in front of the hit point (nearer by more than its slack), within ``w``
    of the stretch of the ray before the hit, re-traces that stretch (``w``:
    ``params[P_REFINE]`` of its texel widths, at least as many voxels). When
    ``WITNESSES`` of them find the ray crossing a surface there, the nearest such hit
    replaces this one. Returns ``(t, probe, row, col, fetches, steps)``.

    Why: where two walls meet, the texel through which the finding probe saw the first wall
    may store the second, so the ray passes the first wall unseen and stops on the second's
    plane behind it; probes that see the corner from elsewhere have the first wall in front
    of that point. One probe alone is not trusted: beside a silhouette it may take a surface
    the ray only passes."""
    fetches = 0
    steps = 0
    found = 0
    nearest = t
    nearest_probe = hit_probe
    nearest_row = row
    nearest_col = col
    yx = ox + t * dx
    yy = oy + t * dy
    yz = oz + t * dz
    cage(grid_origin, grid_spacing, grid_counts, yx, yy, yz, corners)
    for corner in range(8):
        q = corners[corner]
        if q == hit_probe or not enabled[q]:
            continue
        length, cx, cy, cz, view_row, view_col, stored = probe_view(positions, mips,
                                                                    resolution, q, yx, yy, yz)
        fetches += 1
        if not (length > 0.0 and stored < length - tolerance):
            continue  # not in front of Y by the tolerance, so not by the slack either
        if not stored < length - view_slack(normals, resolution, q, length, cx, cy, cz,
                                            view_row, view_col, tolerance):
            continue
        # The surface it sees in front must lie by the stretch of the ray before the hit.
        w = params[P_REFINE] * max(1.0, length * texel_angle(resolution))
        vx = positions[q, 0] + stored * cx - ox
        vy = positions[q, 1] + stored * cy - oy
        vz = positions[q, 2] + stored * cz - oz
        along = vx * dx + vy * dy + vz * dz
        if not (t - w <= along <= t and vx * vx + vy * vy + vz * vz - along * along <= w * w):
            continue
        kind, t_front, q_row, q_col, f, s = trace_probe(
            marcher, eps_mode, params, positions, mips, mip_offsets, mip_sizes, normals,
            resolution, q, ox, oy, oz, dx, dy, dz, max(tmin, t - w), t)
        fetches += f
        steps += s
        if kind == HIT and t_front < t:
            found += 1
            if t_front < nearest:
                nearest = t_front
                nearest_probe = q
                nearest_row = q_row
                nearest_col = q_col
    if found >= WITNESSES:
        return nearest, nearest_probe, nearest_row, nearest_col, fetches, steps
    return t, hit_probe, row, col, fetches, steps


@njit(cache=True, nogil=True)
def refine_hit(marcher: int, eps_mode: int, params: np.ndarray, positions: np.ndarray,
               mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
               normals: np.ndarray, resolution: int, probe: int, ox: float, oy: float,
               oz: float, dx: float, dy: float, dz: float, t: float, length: float,
               tmin: float) -> tuple[float, int, int]:
    """A hit at ``t`` re-traced against ``probe``, the view that answers its colour, over
    ``t ± w`` (``w``: ``params[P_REFINE]`` texel widths of that probe at the hit, at least
    that many voxels); returns the refined ``t`` (``t`` itself where that probe finds no
    hit there), the texels fetched and the march steps.

    Why: the probe that found the hit may see the surface at a grazing angle, through a
    texel spanning several voxels of a staircase, so the hit can be voxels off along the
    ray; the colour probe sees the point most sharply, and its depth places it best."""
    w = params[P_REFINE] * max(1.0, length * texel_angle(resolution))
    kind, t_refined, _, _, fetches, steps = trace_probe(
        marcher, eps_mode, params, positions, mips, mip_offsets, mip_sizes, normals,
        resolution, probe, ox, oy, oz, dx, dy, dz, max(tmin, t - w), t + w)
    return (t_refined if kind == HIT else t), fetches, steps


@njit(cache=True, nogil=True)
def answer_ray(i: int, modes: TraceModes, field: ProbeField, rays: RayBatch,
               out: LightFieldOutputs, tolerance: float, scratch) -> None:
    """Ray ``i``: its trace; then its hit checked against the probes that may see a surface
    in front of it (``hit_in_front``), refined against (``refine_hit``) and coloured by the
    probe ``hit_colour_probe`` picks; into the outputs. The body both the CPU loop and the
    CUDA kernel run."""
    marcher, eps_mode, ordering, fallback, params = modes
    (positions, enabled, mips, mip_offsets, mip_sizes, normals, radiance, radiance_bordered,
     distance_bordered, resolution, grid_origin, grid_spacing, grid_counts) = field
    origins, dirs, tmin, tmax = rays
    (out_kind, out_t, out_radiance, out_normal, out_distance, out_probe, out_tried,
     out_fetches, out_steps) = out
    corners, corners2, tried_probe, tried_t, ring, ring_d2 = scratch
    ox = origins[i, 0]
    oy = origins[i, 1]
    oz = origins[i, 2]
    dx = dirs[i, 0]
    dy = dirs[i, 1]
    dz = dirs[i, 2]
    kind, t, p, row, col, tried, fetches, steps = trace_light_field_ray(
        marcher, eps_mode, ordering, fallback, params, positions, enabled, mips,
        mip_offsets, mip_sizes, normals, resolution, grid_origin, grid_spacing,
        grid_counts, ox, oy, oz, dx, dy, dz, tmin[i], tmax[i], corners, tried_probe,
        tried_t, corners2, ring, ring_d2)
    if kind == HIT and row >= 0 and params[P_REFINE] > 0.0:
        t, p, row, col, f, s = hit_in_front(
            marcher, eps_mode, params, positions, enabled, mips, mip_offsets, mip_sizes,
            normals, resolution, grid_origin, grid_spacing, grid_counts, p, row, col, ox, oy,
            oz, dx, dy, dz, t, tmin[i], tolerance, corners2)
        fetches += f
        steps += s
    out_probe[i] = p
    if kind == HIT and row >= 0:
        yx = ox + t * dx
        yy = oy + t * dy
        yz = oz + t * dz
        q = hit_colour_probe(positions, enabled, normals, mips, resolution, grid_origin,
                             grid_spacing, grid_counts, p, yx, yy, yz, dx, dy, dz,
                             tolerance, corners, int(params[P_COLOUR_PROBE]))
        length, cx, cy, cz, qr, qc, _, slack = point_from_probe(
            positions, normals, mips, resolution, q, yx, yy, yz, tolerance)
        if params[P_REFINE] > 0.0 and length > 0.0:
            t_refined, f, s = refine_hit(marcher, eps_mode, params, positions, mips,
                                         mip_offsets, mip_sizes, normals, resolution, q, ox,
                                         oy, oz, dx, dy, dz, t, length, tmin[i])
            fetches += f
            steps += s
            if t_refined != t:
                t = t_refined
                yx = ox + t * dx
                yy = oy + t * dy
                yz = oz + t * dz
                length, cx, cy, cz, qr, qc, _, slack = point_from_probe(
                    positions, normals, mips, resolution, q, yx, yy, yz, tolerance)
        if length > 0.0:
            if params[P_BILINEAR] != 0.0:
                cr, cg, cb = radiance_at(radiance_bordered, distance_bordered, q, cx, cy,
                                         cz, length, slack, resolution)
            else:
                cr = np.float64(radiance[q, qr, qc, 0])
                cg = np.float64(radiance[q, qr, qc, 1])
                cb = np.float64(radiance[q, qr, qc, 2])
            p, row, col = q, qr, qc
        else:
            cr = np.float64(radiance[p, row, col, 0])
            cg = np.float64(radiance[p, row, col, 1])
            cb = np.float64(radiance[p, row, col, 2])
        out_probe[i] = p
        out_radiance[i, 0] = cr
        out_radiance[i, 1] = cg
        out_radiance[i, 2] = cb
        for c in range(3):
            out_normal[i, c] = normals[p, row, col, c]
        out_distance[i] = mips[p, row * resolution + col]
    elif kind == FALLBACK and row >= 0:
        for c in range(3):
            out_radiance[i, c] = radiance[p, row, col, c]
            out_normal[i, c] = normals[p, row, col, c]
        out_distance[i] = mips[p, row * resolution + col]
    else:
        for c in range(3):
            out_radiance[i, c] = 0.0
            out_normal[i, c] = 0.0
        out_distance[i] = math.inf
    out_kind[i] = kind
    out_t[i] = t
    out_tried[i] = tried
    out_fetches[i] = fetches
    out_steps[i] = steps


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


@njit(cache=True, nogil=True, parallel=True)
def perfect_trace_rays(positions: np.ndarray, enabled: np.ndarray, normals: np.ndarray,
                       mips: np.ndarray, radiance_bordered: np.ndarray,
                       distance_bordered: np.ndarray,
                       resolution: int, points: np.ndarray, dirs: np.ndarray,
                       tolerance: float, bilinear: bool, rule: int,
                       out_radiance: np.ndarray, out_probe: np.ndarray) -> None:
    """The perfect-trace bound's colours: each ray is given its true hit point and reads the
    enabled probe best by ``rule`` (``colour_score``) among those that see the point from the
    ray's side (``sees_front``, ``tolerance`` plus the texel's slope; the best of all when none
    does), bilinear (as ``radiance_at``) or at the nearest texel."""
    for i in prange(len(points)):
        yx = points[i, 0]
        yy = points[i, 1]
        yz = points[i, 2]
        best = -1
        best_score = -math.inf
        any_best = -1
        any_score = -math.inf
        for q in range(len(positions)):
            if not enabled[q]:
                continue
            length, cx, cy, cz, row, col, stored, slack = point_from_probe(
                positions, normals, mips, resolution, q, yx, yy, yz, tolerance)
            if length == 0.0:
                continue
            nx = np.float64(normals[q, row, col, 0])
            ny = np.float64(normals[q, row, col, 1])
            nz = np.float64(normals[q, row, col, 2])
            dx = dirs[i, 0]
            dy = dirs[i, 1]
            dz = dirs[i, 2]
            score = colour_score(rule, length, cx, cy, cz, dx, dy, dz, nx, ny, nz)
            if score > any_score:
                any_score = score
                any_best = q
            if sees_front(length, stored, slack, nx, ny, nz, dx, dy, dz) and score > best_score:
                best_score = score
                best = q
        q = best if best >= 0 else any_best
        out_probe[i] = q
        if q < 0:
            for c in range(3):
                out_radiance[i, c] = 0.0
            continue
        length, cx, cy, cz, row, col, _, slack = point_from_probe(
            positions, normals, mips, resolution, q, yx, yy, yz, tolerance)
        if bilinear:
            r, g, b = radiance_at(radiance_bordered, distance_bordered, q, cx, cy, cz, length,
                                  slack, resolution)
        else:
            r = np.float64(radiance_bordered[q, row + 1, col + 1, 0])
            g = np.float64(radiance_bordered[q, row + 1, col + 1, 1])
            b = np.float64(radiance_bordered[q, row + 1, col + 1, 2])
        out_radiance[i, 0] = r
        out_radiance[i, 1] = g
        out_radiance[i, 2] = b
