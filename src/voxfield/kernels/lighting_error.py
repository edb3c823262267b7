"""Ray-cast colour error of child configurations with "bright" flags (EA thesis §6.1).

A configuration is a child mask plus the subset of present children flagged bright. In the
binary luminance model a bright child has luminance 1, any other child 0, and the parent
(the mean of its children) ``p = |bright| / |mask|``. A ray through the parent that meets a
child sees the first child along it, so its colour error is ``|b(first) − p|``; rays that
miss every child are the geometric error's business and add nothing here. The colour error
of a configuration and direction is the mean over the rays that hit the parent.

The image plane and rays are those of the geometric error raycast (``error_raycast``); per
direction, rays are binned by the front-to-back sequence of children they cross (at most 4
of the 8), and every configuration's error is summed from those few bins.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from voxfield.kernels.error_raycast import orthonormal_basis
from voxfield.kernels.traversal import axis_interval, safe_inverse

#: Sequence keys hold up to 4 octants front to back, 4 bits each (octant + 1, 0 = none).
_KEYS = 1 << 16


@njit(cache=True, nogil=True)
def child_sequence_key(ox, oy, oz, dx, dy, dz, ix, iy, iz) -> int:
    """The children of ``[-0.5, 0.5]^3`` a ray crosses, front to back, packed as a key."""
    lx0, lx1 = axis_interval(ox, dx, ix, -0.5, 0.0)
    hx0, hx1 = axis_interval(ox, dx, ix, 0.0, 0.5)
    ly0, ly1 = axis_interval(oy, dy, iy, -0.5, 0.0)
    hy0, hy1 = axis_interval(oy, dy, iy, 0.0, 0.5)
    lz0, lz1 = axis_interval(oz, dz, iz, -0.5, 0.0)
    hz0, hz1 = axis_interval(oz, dz, iz, 0.0, 0.5)
    octants = np.empty(8, np.int64)
    entries = np.empty(8, np.float64)
    n = 0
    for c in range(8):
        e0, e1 = (hx0, hx1) if c & 1 else (lx0, lx1)
        f0, f1 = (hy0, hy1) if c & 2 else (ly0, ly1)
        g0, g1 = (hz0, hz1) if c & 4 else (lz0, lz1)
        enter = max(e0, f0, g0)
        if enter < min(e1, f1, g1):
            # Insertion by entry time (children's open intervals are disjoint).
            j = n
            while j > 0 and entries[j - 1] > enter:
                entries[j] = entries[j - 1]
                octants[j] = octants[j - 1]
                j -= 1
            entries[j] = enter
            octants[j] = c
            n += 1
    key = 0
    for j in range(min(n, 4)):
        key |= (octants[j] + 1) << (4 * j)
    return key


@njit(cache=True, nogil=True)
def sequence_colour_error(key: int, mask: int, bright: int, parent: float) -> float:
    """``|b(first) − p|`` for the first child in ``mask`` along the sequence; 0 if none."""
    while key:
        octant = (key & 0xF) - 1
        if (mask >> octant) & 1:
            return abs(float((bright >> octant) & 1) - parent)
        key >>= 4
    return 0.0


@njit(cache=True, parallel=True)
def configuration_colour_errors(
    directions: np.ndarray, samples: np.ndarray, masks: np.ndarray, brights: np.ndarray
) -> np.ndarray:
    """(n_configurations, n_directions) colour errors of (mask, bright) configurations."""
    n_dirs = directions.shape[0]
    n_conf = masks.shape[0]
    out = np.zeros((n_conf, n_dirs))
    parents = np.empty(n_conf)
    for i in range(n_conf):
        count = 0
        lit = 0
        for c in range(8):
            count += (masks[i] >> c) & 1
            lit += (brights[i] >> c) & 1
        parents[i] = lit / max(count, 1)
    for k in prange(n_dirs):
        dx = directions[k, 0]
        dy = directions[k, 1]
        dz = directions[k, 2]
        rx, ry, rz, ux, uy, uz = orthonormal_basis(dx, dy, dz)
        ix = safe_inverse(dx)
        iy = safe_inverse(dy)
        iz = safe_inverse(dz)
        hist = np.zeros(_KEYS, np.int64)
        for s in range(samples.shape[0]):
            a = samples[s, 0] * 2.0 - 1.0
            b = samples[s, 1] * 2.0 - 1.0
            ox = -2.0 * dx + a * rx + b * ux
            oy = -2.0 * dy + a * ry + b * uy
            oz = -2.0 * dz + a * rz + b * uz
            hist[child_sequence_key(ox, oy, oz, dx, dy, dz, ix, iy, iz)] += 1
        keys = np.flatnonzero(hist[1:]) + 1
        parent_hits = 0
        for key in keys:
            parent_hits += hist[key]
        if parent_hits == 0:
            continue
        for i in range(n_conf):
            total = 0.0
            for key in keys:
                total += hist[key] * sequence_colour_error(key, masks[i], brights[i], parents[i])
            out[i, k] = total / parent_hits
    return out
