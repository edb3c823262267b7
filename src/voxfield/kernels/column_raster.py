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

The distance to a box's nearest point suits a ray that heads straight for it; a pixel's
rays head along their own directions. A unit ray whose largest component along an axis is
``m`` (over the pixel's rays, ``direction_limits``) covers at most ``m·t`` of that axis by
time ``t``, so it reaches a box ``g`` away along it (the gap between the eye and the box's
slab) no sooner than ``g / m``: each pixel keeps the larger of the two bounds. Seen from
above, rays towards the image's edges slant, and their start moves from a box's nearest
point down to their own crossing of its top.

Only a pinhole camera with every box in front of its eye plane is drawn: a box across that
plane has no bounded projection, and the caller falls back to the beam.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.camera_rays import PINHOLE, camera_ray, image_plane, pinhole_direction

#: Pixels a projected rectangle is widened by on each side, against rounding in the
#: projection: it only loosens bounds.
PIXEL_MARGIN = 1e-3


@njit(cache=True, nogil=True, inline="always")
def box_gaps(ex: float, ey: float, ez: float, x0: float, x1: float, y0: float, y1: float,
             z0: float, z1: float) -> tuple[float, float, float]:
    """How far the eye is from the box's slab along each axis (0 inside the slab): the
    components of the way to the box's nearest point."""
    return (max(max(x0 - ex, ex - x1), 0.0), max(max(y0 - ey, ey - y1), 0.0),
            max(max(z0 - ez, ez - z1), 0.0))


@njit(parallel=True, cache=True, nogil=True)
def direction_limits(cam: np.ndarray, width: int, height: int, reach: float) -> np.ndarray:
    """``(height, width, 3)``: per pixel and axis, 1 over the largest magnitude a unit
    direction of the pinhole camera ``cam`` has along the axis for an image point within
    ``reach`` pixels of the pixel's centre (along each image axis): 0 is the centre ray
    itself (``camera_ray``'s very direction), 0.5 every ray through the pixel. ``inf`` where
    no such ray moves along the axis."""
    limits = np.empty((height, width, 3))
    fx, fy, fz = cam[4], cam[5], cam[6]
    rx, ry, rz = cam[7], cam[8], cam[9]
    ux, uy, uz = cam[10], cam[11], cam[12]
    products = (fx * fx + fy * fy + fz * fz, fx * rx + fy * ry + fz * rz,
                fx * ux + fy * uy + fz * uz, rx * rx + ry * ry + rz * rz,
                rx * ux + ry * uy + rz * uz, ux * ux + uy * uy + uz * uz)
    for row in prange(height):
        if reach == 0.0:
            centre_ray_limits(cam, width, height, row, limits[row])
        else:
            pixel_area_limits(cam, width, height, row, reach, products, limits[row])
    return limits


@njit(cache=True, nogil=True, error_model="numpy")
def centre_ray_limits(cam: np.ndarray, width: int, height: int, row: int,
                      limits: np.ndarray) -> None:
    """``direction_limits`` of one row's centre rays: in IEEE arithmetic ``1 / 0`` is the
    ``inf`` a zero component needs, so the loop has no branch and vectorises."""
    if cam[0] != PINHOLE:
        for col in range(width):
            _, _, _, dx, dy, dz = camera_ray(cam, col + 0.5, row + 0.5, width, height)
            limits[col, 0] = 1.0 / abs(dx)
            limits[col, 1] = 1.0 / abs(dy)
            limits[col, 2] = 1.0 / abs(dz)
        return
    # The pinhole directions with the camera kind settled outside the loop, which then
    # runs on vectors.
    lx = np.empty(width)
    ly = np.empty(width)
    lz = np.empty(width)
    for col in range(width):
        a, b = image_plane(cam, col + 0.5, row + 0.5, width, height)
        dx, dy, dz = pinhole_direction(cam, a, b)
        lx[col] = 1.0 / abs(dx)
        ly[col] = 1.0 / abs(dy)
        lz[col] = 1.0 / abs(dz)
    for col in range(width):
        limits[col, 0] = lx[col]
        limits[col, 1] = ly[col]
        limits[col, 2] = lz[col]


@njit(cache=True, nogil=True)
def pixel_area_limits(cam: np.ndarray, width: int, height: int, row: int, reach: float,
                      products, limits: np.ndarray) -> None:
    """``direction_limits`` of one row for image points within ``reach`` of each centre."""
    fx, fy, fz = cam[4], cam[5], cam[6]
    rx, ry, rz = cam[7], cam[8], cam[9]
    ux, uy, uz = cam[10], cam[11], cam[12]
    for col in range(width):
        # The unnormalised direction f + a·r + b·u over the image rectangle: each
        # component is largest at a corner, the length smallest where the convex
        # |f + a·r + b·u|² is.
        a0 = (2.0 * (col + 0.5 - reach) / width - 1.0) * cam[13]
        a1 = (2.0 * (col + 0.5 + reach) / width - 1.0) * cam[13]
        b0 = (1.0 - 2.0 * (row + 0.5 + reach) / height) * cam[14]
        b1 = (1.0 - 2.0 * (row + 0.5 - reach) / height) * cam[14]
        mx = 0.0
        my = 0.0
        mz = 0.0
        for corner in range(4):
            a = a1 if corner & 1 else a0
            b = b1 if corner & 2 else b0
            mx = max(mx, abs(fx + a * rx + b * ux))
            my = max(my, abs(fy + a * ry + b * uy))
            mz = max(mz, abs(fz + a * rz + b * uz))
        shortest = math.sqrt(smallest_square_length(products, a0, a1, b0, b1))
        # Rounding only loosens the limits (the bound's own slack covers the rest).
        scale = (1.0 + 1e-12) / (shortest * (1.0 - 1e-12))
        limits[col, 0] = 1.0 / (mx * scale) if mx > 0.0 else math.inf
        limits[col, 1] = 1.0 / (my * scale) if my > 0.0 else math.inf
        limits[col, 2] = 1.0 / (mz * scale) if mz > 0.0 else math.inf


@njit(cache=True, nogil=True, inline="always")
def _square_length(products, a: float, b: float) -> float:
    ff, fr, fu, rr, ru, uu = products
    return ff + 2.0 * a * fr + 2.0 * b * fu + a * a * rr + 2.0 * a * b * ru + b * b * uu


@njit(cache=True, nogil=True, inline="always")
def smallest_square_length(products, a0: float, a1: float, b0: float, b1: float) -> float:
    """The least ``|f + a·r + b·u|²`` over ``a0 <= a <= a1``, ``b0 <= b <= b1`` for the
    camera's forward, right and up vectors, given their dot ``products`` (ff, fr, fu, rr,
    ru, uu): at the unconstrained minimum if it lies inside, else on an edge, where it is a
    parabola's clamped vertex."""
    ff, fr, fu, rr, ru, uu = products
    best = math.inf
    det = rr * uu - ru * ru
    if det > 0.0:
        a = (ru * fu - uu * fr) / det
        b = (ru * fr - rr * fu) / det
        if a0 <= a <= a1 and b0 <= b <= b1:
            best = _square_length(products, a, b)
    for edge in range(4):
        if edge < 2:  # a fixed, b free
            a = a0 if edge == 0 else a1
            b = min(max(-(fu + a * ru) / uu, b0), b1) if uu > 0.0 else b0
        else:  # b fixed, a free
            b = b0 if edge == 2 else b1
            a = min(max(-(fr + b * ru) / rr, a0), a1) if rr > 0.0 else a0
        best = min(best, _square_length(products, a, b))
    return max(best, 0.0)


@njit(parallel=True, cache=True, nogil=True)
def draw_cell_boxes(
    cam: np.ndarray, to_camera: np.ndarray, width: int, height: int, tops: np.ndarray,
    floors: np.ndarray, first: int, cells_x: int, cells_z: int, level: int, node_level: int,
    reach: float, limits: np.ndarray, parts: int, nearest: np.ndarray, drawn: np.ndarray,
) -> bool:
    """Draw the ``cells_x × cells_z`` cells of one pyramid level (``tops`` and ``floors``
    from ``first``, x-major, side ``2^level``) into ``nearest`` (``(parts, height, width)``,
    filled with ``inf``): part ``p`` draws the cell rows ``p, p + parts, ...`` into
    ``nearest[p]`` and counts them in ``drawn[p]`` (-1 where it met a box across the eye
    plane). A pixel is covered where a point within ``reach`` pixels of its centre (along
    each image axis) lies in a box's rectangle: 0 bounds the ray through the centre, 0.5
    every ray through the pixel (its sub-samples), whose ``direction_limits`` for that reach
    are ``limits``. Heights round out to nodes of side ``2^node_level``. ``to_camera`` maps
    ``point - eye`` to ``(s, s·a, s·b)``, a point on the ray through image-plane position
    ``(a, b)``. False when a box reaches the eye plane (no bound: the caller must not use
    ``nearest``)."""
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
                # s, a and b are linear in the corner offsets, so the corners nearest and
                # farthest along s tell a box behind the eye or across its plane without a
                # test per corner, and the rectangle's edges are among the corners' a/s and
                # b/s (the same bits as projecting each corner: the mapping to pixels is
                # monotonic).
                s_near = s0 + min(sx, 0.0) + min(sy, 0.0) + min(sz, 0.0)
                s_far = s0 + max(sx, 0.0) + max(sy, 0.0) + max(sz, 0.0)
                if not s_far > 0.0:
                    continue  # wholly behind the eye: no ray reaches it
                if not s_near > 0.0:
                    across = True
                    break
                lo_a = math.inf
                hi_a = -math.inf
                lo_b = math.inf
                hi_b = -math.inf
                for corner in range(8):
                    s = s0 + (sx if corner & 1 else 0.0) + (sy if corner & 2 else 0.0) + (
                        sz if corner & 4 else 0.0)
                    a = a0 + (ax if corner & 1 else 0.0) + (ay if corner & 2 else 0.0) + (
                        az if corner & 4 else 0.0)
                    b = b0 + (bx if corner & 1 else 0.0) + (by if corner & 2 else 0.0) + (
                        bz if corner & 4 else 0.0)
                    inv = 1.0 / s
                    lo_a = min(lo_a, a * inv)
                    hi_a = max(hi_a, a * inv)
                    lo_b = min(lo_b, b * inv)
                    hi_b = max(hi_b, b * inv)
                lo_x = (lo_a * x_scale + 1.0) * 0.5 * width
                hi_x = (hi_a * x_scale + 1.0) * 0.5 * width
                lo_y = (1.0 - hi_b * y_scale) * 0.5 * height
                hi_y = (1.0 - lo_b * y_scale) * 0.5 * height
                col0 = max(int(math.ceil(lo_x - 0.5 - widen)), 0)
                col1 = min(int(math.floor(hi_x - 0.5 + widen)), width - 1)
                row0 = max(int(math.ceil(lo_y - 0.5 - widen)), 0)
                row1 = min(int(math.floor(hi_y - 0.5 + widen)), height - 1)
                if col0 > col1 or row0 > row1:
                    continue
                gap_x, gap_y, gap_z = box_gaps(ex, ey, ez, x0, x1, y0, y1, z0, z1)
                d = math.sqrt(gap_x * gap_x + gap_y * gap_y + gap_z * gap_z)  # nearest point
                # Unsigned indices (no wrap-around test) and a minimum in place of a
                # branch: with the corners above, drawing took 0.65-0.76× the time
                # (2048² mountain, 512² image, top and 45° views).
                for row in range(row0, row1 + 1):
                    r = np.uint64(row)
                    for col in range(col0, col1 + 1):
                        c = np.uint64(col)
                        lx = gap_x * limits[r, c, 0] if gap_x > 0.0 else 0.0
                        ly = gap_y * limits[r, c, 1] if gap_y > 0.0 else 0.0
                        lz = gap_z * limits[r, c, 2] if gap_z > 0.0 else 0.0
                        out[r, c] = min(out[r, c], max(max(d, lx), max(ly, lz)))
            if across:
                break
        drawn[p] = -1 if across else count
    return drawn.min() >= 0
