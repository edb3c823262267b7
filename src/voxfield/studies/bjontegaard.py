"""Bjøntegaard deltas: how far apart two cost–quality curves are, as one number each way.

Two renderers swept over their own knobs give two curves of (cost, PSNR) points. One point
each cannot say which is better when neither is both cheaper and sharper; the curves can:

- ``bd_quality``: the mean PSNR difference (dB) of B over A across the cost range both
  cover, with cost on a log scale (BD-PSNR, Bjøntegaard 2001, VCEG-M33);
- ``bd_cost``: the mean relative cost change (percent) of B against A at equal PSNR across
  the PSNR range both cover (BD-rate; negative: B is cheaper).

Each curve is first reduced to its Pareto front (a point that another beats in both cost
and PSNR is a setting nobody would choose), then interpolated piecewise-cubic and monotone
(PCHIP, as later VCEG/JVET practice recommends over the original cubic fit, which
overshoots on few points).
"""

from __future__ import annotations

import numpy as np

from voxfield.errors import VoxfieldError

#: Narrowest common range worth a mean: 20 % in cost (log scale), 0.25 dB in PSNR.
MIN_COST_OVERLAP = float(np.log(1.2))
MIN_PSNR_OVERLAP = 0.25


def _curve(x, y, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Points sorted by x, duplicates in x averaged; at least two distinct finite points."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise VoxfieldError(f"{what}: costs and qualities must be equal-length lists")
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    xs, inverse = np.unique(x, return_inverse=True)
    if len(xs) < 2:
        raise VoxfieldError(f"{what}: a curve needs at least two distinct finite points")
    ys = np.bincount(inverse, weights=y) / np.bincount(inverse)
    return xs, ys


def pareto_front(cost, psnr) -> tuple[np.ndarray, np.ndarray]:
    """The points no other point beats in both: cheaper-or-equal and strictly sharper."""
    cost = np.asarray(cost, np.float64)
    psnr = np.asarray(psnr, np.float64)
    keep = np.isfinite(cost) & np.isfinite(psnr)
    cost, psnr = cost[keep], psnr[keep]
    order = np.lexsort((-psnr, cost))  # by cost, the sharpest first among equal costs
    best = -np.inf
    front = []
    for i in order:
        if psnr[i] > best:
            front.append(i)
            best = psnr[i]
    front = np.array(front, np.int64)
    return cost[front], psnr[front]


def _mean_gap(xa, ya, xb, yb, what: str, min_overlap: float) -> float:
    """Mean of ``fb(x) - fa(x)`` over the x range both curves cover (at least
    ``min_overlap`` wide: a mean over a sliver says nothing)."""
    lo = max(xa[0], xb[0])
    hi = min(xa[-1], xb[-1])
    if not hi > lo:
        raise VoxfieldError(f"{what}: the two curves do not overlap")
    if hi - lo < min_overlap:
        raise VoxfieldError(f"{what}: the two curves overlap too little to compare")
    # Imported here: scipy.interpolate takes a fifth of a second, which every command that
    # loads the CLI would pay.
    from scipy.interpolate import PchipInterpolator

    fa = PchipInterpolator(xa, ya)
    fb = PchipInterpolator(xb, yb)
    return float((fb.integrate(lo, hi) - fa.integrate(lo, hi)) / (hi - lo))


def bd_quality(cost_a, psnr_a, cost_b, psnr_b) -> float:
    """Mean PSNR gain (dB) of curve B over curve A at equal cost (log scale)."""
    if np.any(np.asarray(cost_a, float) <= 0) or np.any(np.asarray(cost_b, float) <= 0):
        raise VoxfieldError("BD-PSNR: costs must be positive")
    cost_a, psnr_a = pareto_front(cost_a, psnr_a)
    cost_b, psnr_b = pareto_front(cost_b, psnr_b)
    xa, ya = _curve(np.log(cost_a), psnr_a, "BD-PSNR")
    xb, yb = _curve(np.log(cost_b), psnr_b, "BD-PSNR")
    return _mean_gap(xa, ya, xb, yb, "BD-PSNR", MIN_COST_OVERLAP)


def bd_cost(cost_a, psnr_a, cost_b, psnr_b) -> float:
    """Mean cost change (percent) of curve B against curve A at equal PSNR."""
    if np.any(np.asarray(cost_a, float) <= 0) or np.any(np.asarray(cost_b, float) <= 0):
        raise VoxfieldError("BD-rate: costs must be positive")
    # Cost as a function of quality: the Pareto fronts rise with cost, so they invert.
    cost_a, psnr_a = pareto_front(cost_a, psnr_a)
    cost_b, psnr_b = pareto_front(cost_b, psnr_b)
    xa, ya = _curve(psnr_a, np.log(cost_a), "BD-rate")
    xb, yb = _curve(psnr_b, np.log(cost_b), "BD-rate")
    return float((np.exp(_mean_gap(xa, ya, xb, yb, "BD-rate", MIN_PSNR_OVERLAP)) - 1.0) * 100.0)
