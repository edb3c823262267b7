"""Octahedral direction mapping (Cigolle et al. 2014) and bordered bilinear lookup.

Convention (y-up world): the upper hemisphere (y >= 0) fills the inner diamond of the unit
square, the lower hemisphere folds over its four corners. ``u`` follows x and ``v`` follows z.
Maps of R×R texels are stored with a one-texel border, (R + 2)², filled so that a bilinear
fetch across any edge of the square reads the texel that is its neighbour on the sphere.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def sign_not_zero(v: float) -> float:
    return 1.0 if v >= 0.0 else -1.0


@njit(cache=True, nogil=True)
def oct_encode(x: float, y: float, z: float) -> tuple[float, float]:
    """Unit direction → (u, v) in [0, 1]²."""
    s = abs(x) + abs(y) + abs(z)
    px = x / s
    pz = z / s
    if y < 0.0:
        qx = (1.0 - abs(pz)) * sign_not_zero(px)
        qz = (1.0 - abs(px)) * sign_not_zero(pz)
        px = qx
        pz = qz
    return px * 0.5 + 0.5, pz * 0.5 + 0.5


@njit(cache=True, nogil=True)
def oct_decode(u: float, v: float) -> tuple[float, float, float]:
    """(u, v) in [0, 1]² → unit direction."""
    px = u * 2.0 - 1.0
    pz = v * 2.0 - 1.0
    y = 1.0 - abs(px) - abs(pz)
    if y < 0.0:
        qx = (1.0 - abs(pz)) * sign_not_zero(px)
        qz = (1.0 - abs(px)) * sign_not_zero(pz)
        px = qx
        pz = qz
    length = math.sqrt(px * px + y * y + pz * pz)
    return px / length, y / length, pz / length


def texel_directions(resolution: int) -> np.ndarray:
    """Unit directions of the texel centres of an R×R octahedral map, row-major (v, u)."""
    centres = (np.arange(resolution) + 0.5) / resolution
    out = np.empty((resolution, resolution, 3))
    for row, v in enumerate(centres):
        for col, u in enumerate(centres):
            out[row, col] = oct_decode(u, v)
    return out.reshape(-1, 3)


def add_border(maps: np.ndarray) -> np.ndarray:
    """(..., R, R) interior texels → (..., R + 2, R + 2) with the octahedral wrap border.

    Crossing an edge of the square lands on the same edge mirrored about its midpoint, and
    crossing a corner lands on the opposite corner.
    """
    r = maps.shape[-1]
    out = np.empty(maps.shape[:-2] + (r + 2, r + 2), maps.dtype)
    out[..., 1:-1, 1:-1] = maps
    out[..., 0, 1:-1] = maps[..., 0, ::-1]
    out[..., -1, 1:-1] = maps[..., -1, ::-1]
    out[..., 1:-1, 0] = maps[..., ::-1, 0]
    out[..., 1:-1, -1] = maps[..., ::-1, -1]
    out[..., 0, 0] = maps[..., -1, -1]
    out[..., 0, -1] = maps[..., -1, 0]
    out[..., -1, 0] = maps[..., 0, -1]
    out[..., -1, -1] = maps[..., 0, 0]
    return out


@njit(cache=True, nogil=True)
def oct_bilinear(bordered: np.ndarray, u: float, v: float) -> float:
    """Bilinear lookup in one bordered (R + 2)² map at (u, v) in [0, 1]²."""
    r = bordered.shape[0] - 2
    # Bordered texel i holds interior texel i - 1, centred at u = (i - 0.5) / r: in these
    # coordinates texel centres sit on integers.
    x = u * r + 0.5
    y = v * r + 0.5
    x0 = min(max(int(math.floor(x)), 0), r)
    y0 = min(max(int(math.floor(y)), 0), r)
    fx = min(max(x - x0, 0.0), 1.0)
    fy = min(max(y - y0, 0.0), 1.0)
    top = bordered[y0, x0] * (1.0 - fx) + bordered[y0, x0 + 1] * fx
    bottom = bordered[y0 + 1, x0] * (1.0 - fx) + bordered[y0 + 1, x0 + 1] * fx
    return top * (1.0 - fy) + bottom * fy
