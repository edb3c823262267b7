"""Polygons to triangles: a fan where the polygon is convex, ear clipping where it is not.

A fan from the first corner covers a concave polygon wrongly (an L-shaped floor plan fills
its notch); OBJ allows any simple planar polygon, and exporters write concave ones (floor
plans, lettering). Convex polygons, nearly all of them, keep the fan and its triangle order.
"""

from __future__ import annotations

import numpy as np


def triangulate(counts: np.ndarray, corners: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(sum(counts - 2), 3) indices into ``corners`` (each polygon's corner rows, polygons one
    after another), ``counts - 2`` triangles a polygon in polygon order."""
    counts = np.asarray(counts, np.int64)
    n_tri = counts - 2
    face_of_tri = np.repeat(np.arange(len(counts)), n_tri)
    first = np.cumsum(counts) - counts
    k = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    a = first[face_of_tri]
    triangles = np.stack([a, a + k + 1, a + k + 2], axis=1)
    tri_start = np.cumsum(n_tri) - n_tri
    vertices = unit_scaled(vertices)
    for face in np.flatnonzero(~_convex(counts, first, vertices[corners])):
        rows = np.arange(first[face], first[face] + counts[face])
        clipped = ear_clip(vertices[corners[rows]])
        triangles[tri_start[face] : tri_start[face] + n_tri[face]] = rows[clipped]
    return triangles


def unit_scaled(points: np.ndarray) -> np.ndarray:
    """``points`` times the power of two that brings their largest coordinate into [0.5, 1):
    the turns and normals below multiply coordinates, which overflowed to infinity (or
    underflowed to 0) for any finite coordinates far from 1 (a mesh in units of 1e300). A
    power of two scales exactly, so every sign, and the triangles, stay the same."""
    points = np.asarray(points, np.float64)
    largest = float(np.abs(points).max(initial=0.0))
    if largest == 0.0 or not np.isfinite(largest):
        return points
    return np.ldexp(points, -int(np.frexp(largest)[1]))


#: The two axes a polygon keeps in 2D, by the axis its normal leans on most.
_KEPT_AXES = np.array([(1, 2), (2, 0), (0, 1)])


def _convex(counts: np.ndarray, first: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per polygon, whether no corner turns right in its plane (all polygons at once; a
    triangle always is)."""
    polygon = np.repeat(np.arange(len(counts)), counts)
    offset = np.arange(len(points)) - first[polygon]
    following = first[polygon] + (offset + 1) % counts[polygon]
    preceding = first[polygon] + (offset - 1) % counts[polygon]
    normal = np.add.reduceat(np.cross(points, points[following]), first, axis=0)
    flat = _plane_coordinates(points, normal[polygon])
    into, out = flat - flat[preceding], flat[following] - flat
    turns = into[:, 0] * out[:, 1] - into[:, 1] * out[:, 0]
    # a straight corner's turn is rounding noise of either sign: relative to its edges
    slack = 1e-9 * np.hypot(*into.T) * np.hypot(*out.T)
    return (np.minimum.reduceat(turns + slack, first) >= 0.0) | (counts == 3)


def _plane_coordinates(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Points in 2D, counter-clockwise about ``normal`` (one a point, or one for all): the
    axis the normal leans on most dropped, mirrored where it points down that axis."""
    normal = np.broadcast_to(normal, points.shape)
    axis = np.argmax(np.abs(normal), axis=1)
    kept = _KEPT_AXES[axis]
    flat = np.take_along_axis(points, kept, axis=1).astype(np.float64)
    flat[:, 0] *= np.where(np.take_along_axis(normal, axis[:, None], 1)[:, 0] < 0, -1.0, 1.0)
    return flat


def ear_clip(points: np.ndarray) -> np.ndarray:
    """(n - 2, 3) corner indices covering a simple polygon of ``n`` corners (a polygon whose
    outline doubles back through the same corners to cut a hole, as exporters write holes,
    included); where no ear is left (a self-intersecting or degenerate rest), the rest is
    fanned. The scan goes on from the last ear, so a polygon of thousands of corners takes
    a fraction of a second."""
    points = unit_scaled(points)
    normal = np.sum(np.cross(points, np.roll(points, -1, axis=0)), axis=0)
    flat = _plane_coordinates(points, normal)
    left = list(range(len(flat)))
    triangles = []
    i, misses = 0, 0
    while len(left) > 3:
        i %= len(left)
        a, b, c = left[i - 1], left[i], left[(i + 1) % len(left)]
        if _is_ear(flat, left, a, b, c):
            triangles.append((a, b, c))
            del left[i]
            i, misses = max(i - 1, 0), 0  # the corner before may have become an ear
        elif misses >= len(left):  # a whole round without an ear: fan what is left
            triangles += [(left[0], left[j], left[j + 1]) for j in range(1, len(left) - 1)]
            left = []
        else:
            i, misses = i + 1, misses + 1
    if left:
        triangles.append(tuple(left))
    return np.asarray(triangles, np.int64).reshape(-1, 3)


def _cross(o: np.ndarray, p: np.ndarray, q: np.ndarray):
    """(p - o) × (q - o), for one ``q`` or an array of them."""
    return (p[0] - o[0]) * (q[..., 1] - o[1]) - (p[1] - o[1]) * (q[..., 0] - o[0])


def _is_ear(flat: np.ndarray, left: list[int], a: int, b: int, c: int) -> bool:
    """A convex corner ``b`` whose triangle holds no other remaining corner (a corner at
    the same place as one of the triangle's, where an outline doubles back, does not
    count)."""
    if _cross(flat[a], flat[b], flat[c]) <= 0.0:
        return False
    others = flat[left]
    inside = ((_cross(flat[a], flat[b], others) >= 0.0)
              & (_cross(flat[b], flat[c], others) >= 0.0)
              & (_cross(flat[c], flat[a], others) >= 0.0))
    for corner in (flat[a], flat[b], flat[c]):
        inside &= np.any(others != corner, axis=1)
    return not inside.any()
