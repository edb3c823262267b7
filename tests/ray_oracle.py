"""A slow, obviously-correct ray–box oracle: every box tested against every ray in NumPy.

It applies the same slab contract as the traversal kernel (crossing time ``(plane - o) / d``
computed as ``(plane - o) * (1 / d)`` in float64, half-open slabs for zero components) and
returns, per ray, the index of the box with the smallest clipped entry time.
"""

from __future__ import annotations

import numpy as np


def _axis_times(o, d, lo, hi):
    """Per-ray × per-box entry and exit times along one axis."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = np.where(np.isfinite(1.0 / d), d, 0.0)  # uninvertible components count as zero
        inv = np.where(d != 0.0, 1.0 / np.where(d != 0.0, d, 1.0), np.inf)
        t0 = (lo[None, :] - o[:, None]) * inv[:, None]
        t1 = (hi[None, :] - o[:, None]) * inv[:, None]
    neg = (inv < 0.0)[:, None]
    enter = np.where(neg, t1, t0)
    leave = np.where(neg, t0, t1)
    zero = (d == 0.0)[:, None]
    inside = (lo[None, :] <= o[:, None]) & (o[:, None] < hi[None, :])
    enter = np.where(zero, np.where(inside, -np.inf, np.inf), enter)
    leave = np.where(zero, np.where(inside, np.inf, -np.inf), leave)
    return enter, leave


def first_hits(origins, directions, box_min, box_size, tmin=0.0, chunk=64):
    """Index of the first box hit by each ray (-1 for a miss) and its clipped entry time."""
    origins = np.asarray(origins, np.float64)
    directions = np.asarray(directions, np.float64)
    lo = np.asarray(box_min, np.float64)
    hi = lo + float(box_size)
    n = len(origins)
    hit = np.full(n, -1, np.int64)
    t_hit = np.full(n, np.inf)
    for start in range(0, n, chunk):
        sl = slice(start, start + chunk)
        enter = np.full((len(origins[sl]), len(lo)), -np.inf)
        leave = np.full_like(enter, np.inf)
        for axis in range(3):
            e, l_ = _axis_times(origins[sl, axis], directions[sl, axis], lo[:, axis], hi[:, axis])
            enter = np.maximum(enter, e)
            leave = np.minimum(leave, l_)
        near = np.maximum(enter, tmin)
        valid = near < leave
        near = np.where(valid, near, np.inf)
        best = np.argmin(near, axis=1)
        best_t = near[np.arange(len(best)), best]
        found = np.isfinite(best_t)
        hit[sl] = np.where(found, best, -1)
        t_hit[sl] = best_t
    return hit, t_hit
