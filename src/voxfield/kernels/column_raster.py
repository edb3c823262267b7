"""Per-pixel start bounds for primary rays, from the column-top pyramid drawn into the image.

Every voxel of a pyramid cell lies in the cell's box: its footprint, from the lowest voxel's
``y`` (``ColumnTops.floors``) to the cell's top. A pixel's ray that hits a voxel enters that
box first, so its hit distance is at least the distance from the eye to the box; and the
hit point projects onto the ray's image position (the pixel's centre, or a sub-sample's
point in the pixel), which therefore lies inside the box's projected corners. Drawing every
cell's box as its screen rectangle, each pixel keeping the nearest box distance among the
rectangles that hold its centre (or, for sub-samples, meet the pixel), gives every ray a
start no later than its hit, and ``inf`` to pixels no box covers (their rays miss). A
per-block beam bound (``kernels.beam``) is as far from a ray's hit as the highest ground in
the block; this one as far as the highest ground under the pixel's cell.

Only a pinhole camera with every box in front of its eye plane is drawn: a box across that
plane has no bounded projection, and the caller falls back to the beam.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: Pixels a projected rectangle is widened by on each side, against rounding in the
#: projection: it only loosens bounds.
PIXEL_MARGIN = 1e-3


@njit(cache=True, nogil=True, inline="always")
def box_distance(ex: float, ey: float, ez: float, x0: float, x1: float, y0: float, y1: float,
                 z0: float, z1: float) -> float:
    """Distance from the eye to the nearest point of the box."""
    dx = max(max(x0 - ex, ex - x1), 0.0)
    dy = max(max(y0 - ey, ey - y1), 0.0)
    dz = max(max(z0 - ez, ez - z1), 0.0)
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(parallel=True, cache=True, nogil=True)
def draw_cell_boxes(
    cam: np.ndarray, to_camera: np.ndarray, width: int, height: int, tops: np.ndarray,
    floors: np.ndarray, first: int, cells_x: int, cells_z: int, level: int, node_level: int,
    reach: float, parts: int, nearest: np.ndarray, drawn: np.ndarray,
) -> bool:
    """Draw the ``cells_x × cells_z`` cells of one pyramid level (``tops`` and ``floors``
    from ``first``, x-major, side ``2^level``) into ``nearest`` (``(parts, height, width)``,
    filled with ``inf``): part ``p`` draws the cell rows ``p, p + parts, ...`` into
    ``nearest[p]`` and counts them in ``drawn[p]`` (-1 where it met a box across the eye
    plane). A pixel is covered where a point within ``reach`` pixels of its centre (along
    each image axis) lies in a box's rectangle: 0 bounds the ray through the centre, 0.5
    every ray through the pixel (its sub-samples). Heights round out to nodes of side
    ``2^node_level``. ``to_camera`` maps ``point - eye`` to ``(s, s·a, s·b)``, a point on
    the ray through image-plane position ``(a, b)``. False when a box reaches the eye plane
    (no bound: the caller must not use ``nearest``)."""
    ex, ey, ez = cam[1], cam[2], cam[3]
    x_scale = 1.0 / cam[13]
    y_scale = 1.0 / cam[14]
    side = float(1 << level)
    node = 1 << node_level
    widen = reach + PIXEL_MARGIN
    # The corners' camera coordinates are one corner's plus the box's edges: those along x
    # and z are the same for every cell.
    sx, ax, bx = to_camera[0, 0] * side, to_camera[1, 0] * side, to_camera[2, 0] * side
    sz, az, bz = to_camera[0, 2] * side, to_camera[1, 2] * side, to_camera[2, 2] * side
    for p in prange(parts):
        out = nearest[p]
        count = 0
        across = False
        for cx in range(p, cells_x, parts):  # the rows dealt out in turn
            x0 = float(cx << level)
            x1 = float((cx + 1) << level)
            for cz in range(cells_z):
                top = tops[first + cx * cells_z + cz]
                if top == 0:
                    continue
                count += 1
                y1 = float((top + node - 1) & ~(node - 1))
                y0 = float(floors[first + cx * cells_z + cz] & ~(node - 1))
                z0 = float(cz << level)
                z1 = float((cz + 1) << level)
                vx = x0 - ex
                vy = y0 - ey
                vz = z0 - ez
                s0 = to_camera[0, 0] * vx + to_camera[0, 1] * vy + to_camera[0, 2] * vz
                a0 = to_camera[1, 0] * vx + to_camera[1, 1] * vy + to_camera[1, 2] * vz
                b0 = to_camera[2, 0] * vx + to_camera[2, 1] * vy + to_camera[2, 2] * vz
                rise = y1 - y0
                sy, ay, by = to_camera[0, 1] * rise, to_camera[1, 1] * rise, to_camera[2, 1] * rise
                lo_x = math.inf
                hi_x = -math.inf
                lo_y = math.inf
                hi_y = -math.inf
                behind = 0
                for corner in range(8):
                    s = s0
                    a = a0
                    b = b0
                    if corner & 1:
                        s += sx
                        a += ax
                        b += bx
                    if corner & 2:
                        s += sy
                        a += ay
                        b += by
                    if corner & 4:
                        s += sz
                        a += az
                        b += bz
                    if not s > 0.0:
                        behind += 1
                        continue
                    inv = 1.0 / s
                    px = (a * inv * x_scale + 1.0) * 0.5 * width
                    py = (1.0 - b * inv * y_scale) * 0.5 * height
                    lo_x = min(lo_x, px)
                    hi_x = max(hi_x, px)
                    lo_y = min(lo_y, py)
                    hi_y = max(hi_y, py)
                if behind == 8:
                    continue  # wholly behind the eye: no ray reaches it
                if behind > 0:
                    across = True
                    break
                col0 = max(int(math.ceil(lo_x - 0.5 - widen)), 0)
                col1 = min(int(math.floor(hi_x - 0.5 + widen)), width - 1)
                row0 = max(int(math.ceil(lo_y - 0.5 - widen)), 0)
                row1 = min(int(math.floor(hi_y - 0.5 + widen)), height - 1)
                if col0 > col1 or row0 > row1:
                    continue
                d = box_distance(ex, ey, ez, x0, x1, y0, y1, z0, z1)
                for row in range(row0, row1 + 1):
                    for col in range(col0, col1 + 1):
                        if d < out[row, col]:
                            out[row, col] = d
            if across:
                break
        drawn[p] = -1 if across else count
    return drawn.min() >= 0
