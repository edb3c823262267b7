"""Kensler's correlated multi-jittered sampling (Pixar memo 13-01), as Numba device functions.

All arithmetic is on 32-bit unsigned values emulated with int64 and masking, so the same
functions give identical results in plain Python, under Numba, and on CUDA.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.borrowing import borrowing

_U32 = 0xFFFFFFFF


@njit(cache=True, nogil=True)
def hash_u32(x: int) -> int:
    """A 32-bit integer mix (lowbias32); used to derive per-pixel pattern seeds."""
    x &= _U32
    x ^= x >> 16
    x = (x * 0x7FEB352D) & _U32
    x ^= x >> 15
    x = (x * 0x846CA68B) & _U32
    x ^= x >> 16
    return x


@njit(cache=True, nogil=True)
def permute(i: int, length: int, p: int) -> int:
    """Kensler's hashed permutation of ``i`` within ``[0, length)`` for pattern ``p``."""
    w = length - 1
    w |= w >> 1
    w |= w >> 2
    w |= w >> 4
    w |= w >> 8
    w |= w >> 16
    p &= _U32
    while True:
        i ^= p
        i = (i * 0xE170893D) & _U32
        i ^= p >> 16
        i ^= (i & w) >> 4
        i ^= p >> 8
        i = (i * 0x0929EB3F) & _U32
        i ^= p >> 23
        i ^= (i & w) >> 1
        i = (i * (1 | (p >> 27))) & _U32
        i = (i * 0x6935FA69) & _U32
        i ^= (i & w) >> 11
        i = (i * 0x74DCB303) & _U32
        i ^= (i & w) >> 2
        i = (i * 0x9E501CC3) & _U32
        i ^= (i & w) >> 2
        i = (i * 0xC860A3DF) & _U32
        i &= w
        i ^= i >> 5
        if i < length:
            break
    return (i + p) % length


@njit(cache=True, nogil=True)
def rand_float(i: int, p: int) -> float:
    """Kensler's hashed uniform float in [0, 1) for index ``i`` and pattern ``p``."""
    p &= _U32
    i = (i ^ p) & _U32
    i ^= i >> 17
    i ^= i >> 10
    i = (i * 0xB36534E5) & _U32
    i ^= i >> 12
    i ^= i >> 21
    i = (i * 0x93FC4795) & _U32
    i ^= 0xDF6E307F
    i ^= i >> 17
    i = (i * (1 | (p >> 18))) & _U32
    return i * (1.0 / 4294967808.0)


@njit(cache=True, nogil=True, inline="always")
def divide(v: float, n: int) -> float:
    """``v / n``, as a multiply by ``1 / n`` where ``n`` is a power of two: that reciprocal
    is exact, so the bits are the same, without a division's cost (a sample's position and
    direction, from 18 to 11 ns a 16-ray pixel's sample on the 512² benchmark images)."""
    if n > 0 and n & (n - 1) == 0:
        return v * (1.0 / n)
    return v / n


@njit(cache=True, nogil=True)
def cmj_sample(s: int, m: int, n: int, p: int) -> tuple[float, float]:
    """Sample ``s`` of an m×n correlated multi-jittered pattern ``p``, in [0, 1)^2."""
    sx = permute(s % m, m, (p * 0xA511E9B3) & _U32)
    sy = permute(s // m, n, (p * 0x63D83595) & _U32)
    jx = rand_float(s, (p * 0xA399D265) & _U32)
    jy = rand_float(s, (p * 0x711AD6A5) & _U32)
    x = divide((s % m) + divide(sy + jx, n), m)
    y = divide((s // m) + divide(sx + jy, m), n)
    return x, y


@borrowing
def cmj_strata(m: int, n: int, p: int, column: np.ndarray, row: np.ndarray) -> None:
    """The two stratum permutations of the m×n pattern ``p``, once for all its samples:
    ``cmj_sample`` permutes again for every sample, which is most of its cost when a caller
    draws the whole pattern (``column`` needs ``m`` slots, ``row`` ``n``)."""
    for i in range(m):
        column[i] = permute(i, m, (p * 0xA511E9B3) & _U32)
    for j in range(n):
        row[j] = permute(j, n, (p * 0x63D83595) & _U32)


@njit(cache=True, nogil=True)
def new_cmj_strata(slots: int):
    """``cmj_strata``'s two tables (columns, rows), room for ``slots`` of each."""
    return np.empty(slots, np.int64), np.empty(slots, np.int64)


@njit(cache=True, nogil=True, inline="always")
def cmj_sample_in(s: int, i: int, j: int, m: int, n: int, p: int, column: np.ndarray,
                  row: np.ndarray) -> tuple[float, float]:
    """``cmj_sample(s, m, n, p)`` for ``s = j·m + i`` from ``cmj_strata``'s tables: the same
    arithmetic, so the same bits."""
    jx = rand_float(s, (p * 0xA399D265) & _U32)
    jy = rand_float(s, (p * 0x711AD6A5) & _U32)
    x = divide(i + divide(row[j] + jx, n), m)
    y = divide(j + divide(column[i] + jy, m), n)
    return x, y


@njit(cache=True, nogil=True)
def pixel_pattern(pixel: int, seed: int) -> int:
    """The CMJ pattern index of a pixel: a hash of its index and the user's seed."""
    return hash_u32(hash_u32(pixel) ^ hash_u32(seed * 0x9E3779B9 + 0x632BE5AB))


@njit(cache=True, nogil=True)
def subpixel(pixel: int, s: int, side: int, seed: int) -> tuple[float, float]:
    """Offset in the pixel of sample ``s`` of a side×side pattern; one sample is the centre."""
    if side == 1:
        return 0.5, 0.5
    return cmj_sample(s, side, side, pixel_pattern(pixel, seed))
