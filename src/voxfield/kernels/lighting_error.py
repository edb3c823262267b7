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

from voxfield.kernels.error_raycast import child_entries, orthonormal_basis, plane_origin
from voxfield.kernels.traversal import safe_inverse

#: Sequence keys hold up to 4 octants front to back, 4 bits each (octant + 1, 0 = none).
_KEYS = 1 << 16


@njit(cache=True, nogil=True)
def child_sequence_key(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries: np.ndarray) -> int:
    """The children of ``[-0.5, 0.5]^3`` a ray crosses, front to back, packed as a key
    (``entries`` is scratch of 8)."""
    child_entries(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries)
    key = 0
    for slot in range(4):  # a line crosses at most 4 of the 8 octants
        first = -1
        for c in range(8):
            if entries[c] < np.inf and (first < 0 or entries[c] < entries[first]):
                first = c
        if first < 0:
            break
        key |= (first + 1) << (4 * slot)
        entries[first] = np.inf
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
        entries = np.empty(8)
        for s in range(samples.shape[0]):
            ox, oy, oz = plane_origin(samples, s, dx, dy, dz, rx, ry, rz, ux, uy, uz)
            hist[child_sequence_key(ox, oy, oz, dx, dy, dz, ix, iy, iz, entries)] += 1
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
