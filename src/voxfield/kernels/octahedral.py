"""Octahedral direction mapping (Cigolle et al. 2014) and bordered bilinear lookup.

Convention (y-up world): the upper hemisphere (y >= 0) fills the inner diamond of the unit
square, the lower hemisphere folds over its four corners. ``u`` follows x and ``v`` follows z.
Maps of R×R texels are stored with a one-texel border, (R + 2)², filled so that a bilinear
fetch across any edge of the square reads the texel that is its neighbour on the sphere.

Unit normals are also stored in 32 bits as two snorm16 channels holding the octahedral point
in [-1, 1]² (``encode_normal_snorm16``); the encoder picks, among the four codes around the
point, the one whose decoded direction is closest to the input (Cigolle et al.'s "precise"
variant), which lowers the worst-case error of plain rounding by about a third.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from voxfield.errors import VoxfieldError


@njit(cache=True, nogil=True)
def sign_not_zero(v: float) -> float:
    """±1 with +1 for ±0: the fold needs a definite side for points on the axis planes."""
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


@njit(cache=True, nogil=True, inline="always")
def bilinear_footprint(resolution: int, u: float, v: float) -> tuple[int, int, float, float]:
    """The texel corner ``(x0, y0)`` and weights ``(fx, fy)`` of a bilinear lookup at
    (u, v) in [0, 1]² in a bordered (R + 2)² map, ``R = resolution``: the same for every
    map of that size, so several maps read at one direction share it."""
    # Bordered texel i holds interior texel i - 1, centred at u = (i - 0.5) / R: in these
    # coordinates texel centres sit on integers.
    x = u * resolution + 0.5
    y = v * resolution + 0.5
    x0 = min(max(int(math.floor(x)), 0), resolution)
    y0 = min(max(int(math.floor(y)), 0), resolution)
    fx = min(max(x - x0, 0.0), 1.0)
    fy = min(max(y - y0, 0.0), 1.0)
    return x0, y0, fx, fy


@njit(cache=True, nogil=True, inline="always")
def bilinear_at(bordered: np.ndarray, x0: int, y0: int, fx: float, fy: float) -> float:
    """One bordered map read at a ``bilinear_footprint``."""
    top = bordered[y0, x0] * (1.0 - fx) + bordered[y0, x0 + 1] * fx
    bottom = bordered[y0 + 1, x0] * (1.0 - fx) + bordered[y0 + 1, x0 + 1] * fx
    return top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True)
def oct_bilinear(bordered: np.ndarray, u: float, v: float) -> float:
    """Bilinear lookup in one bordered (R + 2)² map at (u, v) in [0, 1]²."""
    x0, y0, fx, fy = bilinear_footprint(bordered.shape[0] - 2, u, v)
    return bilinear_at(bordered, x0, y0, fx, fy)


#: Largest snorm16 magnitude: code ``c`` stands for ``c / SNORM16_MAX`` (-32768 reads as -1).
SNORM16_MAX = 32767


@njit(cache=True, nogil=True)
def texel_of_direction(x: float, y: float, z: float, resolution: int) -> tuple[int, int]:
    """(row, col) of the texel of an R×R map containing a direction (row follows v, col u).

    The square's far edges (u or v = 1) belong to the last texel, so every direction lands
    on a texel.
    """
    u, v = oct_encode(x, y, z)
    col = min(int(u * resolution), resolution - 1)
    row = min(int(v * resolution), resolution - 1)
    return row, col


@njit(cache=True, nogil=True)
def decode_normal_snorm16(a: int, b: int) -> tuple[float, float, float]:
    """Two snorm16 codes (the octahedral point in [-1, 1]², x then z) → unit direction."""
    px = max(a / SNORM16_MAX, -1.0)
    pz = max(b / SNORM16_MAX, -1.0)
    return oct_decode(px * 0.5 + 0.5, pz * 0.5 + 0.5)


@njit(cache=True, nogil=True)
def encode_normal_snorm16_naive(x: float, y: float, z: float) -> tuple[int, int]:
    """Nearest-code rounding of the octahedral point: the baseline the precise encoder beats.

    ``(x, y, z)`` must be non-zero and finite; it need not be unit length.
    """
    u, v = oct_encode(x, y, z)
    a = int(round((u * 2.0 - 1.0) * SNORM16_MAX))
    b = int(round((v * 2.0 - 1.0) * SNORM16_MAX))
    return a, b


@njit(cache=True, nogil=True)
def encode_normal_snorm16(x: float, y: float, z: float) -> tuple[int, int]:
    """Direction → two snorm16 codes, choosing the code whose decode is closest to the input.

    Rounding each coordinate to its nearest code is not the same as the nearest direction:
    the octahedral map stretches unevenly, so the floor/ceil neighbours on each axis are all
    tried and the best dot product with the input wins (ties keep the first tried, so the
    result is deterministic). ``(x, y, z)`` must be non-zero and finite; any length works.
    """
    u, v = oct_encode(x, y, z)
    scaled_a = (u * 2.0 - 1.0) * SNORM16_MAX
    scaled_b = (v * 2.0 - 1.0) * SNORM16_MAX
    floor_a = int(math.floor(scaled_a))
    floor_b = int(math.floor(scaled_b))
    best_a = floor_a
    best_b = floor_b
    best_dot = -math.inf
    for step_a in range(2):
        a = min(floor_a + step_a, SNORM16_MAX)
        for step_b in range(2):
            b = min(floor_b + step_b, SNORM16_MAX)
            dx, dy, dz = decode_normal_snorm16(a, b)
            dot = dx * x + dy * y + dz * z
            if dot > best_dot:
                best_dot = dot
                best_a = a
                best_b = b
    return best_a, best_b


def _checked_directions(directions) -> np.ndarray:
    """N×3 finite, non-zero float64 directions, or a VoxfieldError saying what is wrong."""
    d = np.ascontiguousarray(directions, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise VoxfieldError(f"directions must be an N×3 array, got shape {d.shape}")
    if not np.isfinite(d).all():
        raise VoxfieldError("directions hold NaN or infinity; cannot encode them")
    if d.size and not np.abs(d).sum(axis=1).all():
        raise VoxfieldError("a direction is the zero vector; it has no octahedral code")
    return d


@njit(cache=True, nogil=True)
def _encode_rows(directions: np.ndarray, out: np.ndarray, precise: bool) -> None:
    for i in range(directions.shape[0]):
        x, y, z = directions[i, 0], directions[i, 1], directions[i, 2]
        if precise:
            a, b = encode_normal_snorm16(x, y, z)
        else:
            a, b = encode_normal_snorm16_naive(x, y, z)
        out[i, 0] = a
        out[i, 1] = b


@njit(cache=True, nogil=True)
def _decode_rows(codes: np.ndarray, out: np.ndarray) -> None:
    for i in range(codes.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = decode_normal_snorm16(codes[i, 0], codes[i, 1])


def encode_normals_snorm16(directions, *, precise: bool = True) -> np.ndarray:
    """N×3 directions (any non-zero length) → N×2 int16 octahedral snorm16 codes."""
    d = _checked_directions(directions)
    out = np.empty((len(d), 2), np.int16)
    _encode_rows(d, out, precise)
    return out


def decode_normals_snorm16(codes) -> np.ndarray:
    """N×2 snorm16 codes → N×3 unit float64 directions."""
    c = np.asarray(codes)
    if c.ndim != 2 or c.shape[1] != 2:
        raise VoxfieldError(f"normal codes must be an N×2 array, got shape {c.shape}")
    if c.size and not np.issubdtype(c.dtype, np.integer):
        raise VoxfieldError(f"normal codes must be integers (int16), got {c.dtype}")
    if c.size and (c.min() < -32768 or c.max() > SNORM16_MAX):
        raise VoxfieldError("normal codes must fit in int16 (-32768..32767)")
    out = np.empty((len(c), 3))
    _decode_rows(np.ascontiguousarray(c, dtype=np.int64), out)
    return out
