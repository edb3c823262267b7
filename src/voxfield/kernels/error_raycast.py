"""The EA thesis's error raycast (§3.1.2, Algorithm 1), all 256 child masks in one pass.

A unit parent cube ``[-0.5, 0.5]^3`` is viewed by an orthographic camera covering the unit
sphere (a 2×2 image plane) along direction ``d``. For every ray the kernel records the 8-bit
mask of child octants it passes through; a child mask ``m`` is hit by exactly the rays whose
bits intersect ``m``, so a 256-bin histogram per direction gives every mask's hit count.
Octant ``c = x | y << 1 | z << 2`` with a set bit meaning the high half along that axis.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from voxfield.kernels.sampling import cmj_sample
from voxfield.kernels.traversal import axis_interval, safe_inverse


def image_plane_samples(resolution: int, seed: int) -> np.ndarray:
    """R² CMJ sample positions over the unit square (one per pixel, stratified and jittered),
    shared by all directions: the jitter breaks alignment with cube edges (EA §3.2.1)."""
    return _cmj_grid(int(resolution), int(seed))


@njit(cache=True, parallel=True)
def _cmj_grid(resolution: int, seed: int) -> np.ndarray:
    n = resolution * resolution
    out = np.empty((n, 2))
    pattern = (seed * 0x9E3779B9 + 0x51ED27) & 0xFFFFFFFF
    for s in prange(n):
        x, y = cmj_sample(s, resolution, resolution, pattern)
        out[s, 0] = x
        out[s, 1] = y
    return out


@njit(cache=True, nogil=True)
def orthonormal_basis(dx: float, dy: float, dz: float):
    """Right and up vectors perpendicular to a unit direction (branch-free for all d)."""
    sign = 1.0 if dz >= 0.0 else -1.0
    a = -1.0 / (sign + dz)
    b = dx * dy * a
    rx, ry, rz = 1.0 + sign * dx * dx * a, sign * b, -sign * dx
    ux, uy, uz = b, sign + dy * dy * a, -dy
    return rx, ry, rz, ux, uy, uz


@njit(cache=True, nogil=True)
def plane_origin(samples, s, dx, dy, dz, rx, ry, rz, ux, uy, uz) -> tuple[float, float, float]:
    """Origin of image-plane sample ``s``: the 2×2 plane two units before the cube centre,
    spanned by the right and up vectors, covers the unit sphere's silhouette."""
    a = samples[s, 0] * 2.0 - 1.0
    b = samples[s, 1] * 2.0 - 1.0
    return -2.0 * dx + a * rx + b * ux, -2.0 * dy + a * ry + b * uy, -2.0 * dz + a * rz + b * uz


@njit(cache=True, nogil=True)
def child_entries(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries: np.ndarray) -> None:
    """``entries[c]``: when a ray enters child octant ``c`` of ``[-0.5, 0.5]^3`` (open
    intervals), ``inf`` when it misses it."""
    lx0, lx1 = axis_interval(ox, dx, ix, -0.5, 0.0)
    hx0, hx1 = axis_interval(ox, dx, ix, 0.0, 0.5)
    ly0, ly1 = axis_interval(oy, dy, iy, -0.5, 0.0)
    hy0, hy1 = axis_interval(oy, dy, iy, 0.0, 0.5)
    lz0, lz1 = axis_interval(oz, dz, iz, -0.5, 0.0)
    hz0, hz1 = axis_interval(oz, dz, iz, 0.0, 0.5)
    for c in range(8):
        e0, e1 = (hx0, hx1) if c & 1 else (lx0, lx1)
        f0, f1 = (hy0, hy1) if c & 2 else (ly0, ly1)
        g0, g1 = (hz0, hz1) if c & 4 else (lz0, lz1)
        enter = max(e0, f0, g0)
        entries[c] = enter if enter < min(e1, f1, g1) else np.inf


@njit(cache=True, nogil=True)
def child_hit_bits(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries: np.ndarray) -> int:
    """Mask of the child octants a ray passes through (``entries`` is scratch of 8)."""
    child_entries(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries)
    bits = 0
    for c in range(8):
        if entries[c] < np.inf:
            bits |= 1 << c
    return bits


@njit(cache=True, parallel=True)
def child_hit_histograms(directions: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """(n_directions, 256) counts of rays by the set of children they pass through."""
    n_dirs = directions.shape[0]
    hist = np.zeros((n_dirs, 256), np.int64)
    for k in prange(n_dirs):
        dx = directions[k, 0]
        dy = directions[k, 1]
        dz = directions[k, 2]
        rx, ry, rz, ux, uy, uz = orthonormal_basis(dx, dy, dz)
        ix = safe_inverse(dx)
        iy = safe_inverse(dy)
        iz = safe_inverse(dz)
        entries = np.empty(8)
        for s in range(samples.shape[0]):
            ox, oy, oz = plane_origin(samples, s, dx, dy, dz, rx, ry, rz, ux, uy, uz)
            hist[k, child_hit_bits(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries)] += 1
    return hist


def errors_from_histograms(hist: np.ndarray) -> np.ndarray:
    """(256, n_directions) error ``1 - hits(children in m) / hits(parent)``; 0 for mask 0.

    The parent cube is the union of all eight children, so a ray hits the parent exactly when
    its bits are non-zero; mask ``m`` is hit by the rays whose bits intersect ``m``.
    """
    bits = np.arange(256)
    hits_mask = (bits[:, None] & bits[None, :]) != 0  # [mask, bits]
    child_hits = hits_mask.astype(np.float64) @ hist.T.astype(np.float64)  # (256, n_dirs)
    parent_hits = hist[:, 1:].sum(axis=1).astype(np.float64)
    errors = 1.0 - child_hits / np.maximum(parent_hits, 1.0)[None, :]
    errors[0] = 0.0
    return errors

