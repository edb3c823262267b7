"""The bottom-up build's loops over flat arrays: Morton codes, their sort, and parents grouped
from their children level by level.

The NumPy versions (bit spreading in five whole-array passes, a comparison sort, ``reduceat``
per level) spent about 1.8 s of CPU on the 17M voxels of a 2048² terrain; these take a
fraction of it, and they release the GIL, so the streamed build's threads run side by side.
Every kernel is serial: the streamed build runs one per cube on each thread.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.octree_levels import child_mean

#: Bits sorted per pass of the radix sort: 4096 buckets, so the 24-bit codes of a 256³ cube
#: take two passes.
_RADIX_BITS = 12


@njit(cache=True, nogil=True, inline="always")
def _spread(v: int) -> np.uint64:
    """The low 21 bits of ``v`` with two zero bits inserted after each."""
    x = np.uint64(v) & np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x001F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x001F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    return (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)


@njit(cache=True, nogil=True)
def morton_codes(coords: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """63-bit Morton codes of ``(n, 3)`` corners relative to ``origin`` (at or below every
    corner): x in bit 0, y in bit 1, z in bit 2 of each octal digit."""
    out = np.empty(coords.shape[0], np.uint64)
    x0, y0, z0 = origin[0], origin[1], origin[2]
    for i in range(coords.shape[0]):
        out[i] = (_spread(coords[i, 0] - x0) | (_spread(coords[i, 1] - y0) << np.uint64(1))
                  | (_spread(coords[i, 2] - z0) << np.uint64(2)))
    return out


@njit(cache=True, nogil=True)
def sort_codes(codes: np.ndarray, code_bits: int):
    """``(sorted codes, order)`` with ``codes[order]`` ascending, for codes below
    ``2**code_bits``: a least-significant-digit radix sort, stable, so equal codes keep
    their input order as ``np.argsort(kind="stable")`` keeps them."""
    n = codes.shape[0]
    keys = codes.copy()
    order = np.arange(n)
    spare_keys = np.empty_like(keys)
    spare_order = np.empty_like(order)
    buckets = 1 << _RADIX_BITS
    count = np.empty(buckets, np.int64)
    digit_mask = np.uint64(buckets - 1)
    for shift in range(0, max(code_bits, 1), _RADIX_BITS):
        count[:] = 0
        s = np.uint64(shift)
        for i in range(n):
            count[(keys[i] >> s) & digit_mask] += 1
        if n == 0 or count[(keys[0] >> s) & digit_mask] == n:
            continue  # every key has this digit: the pass would not move anything
        total = 0
        for b in range(buckets):
            here = count[b]
            count[b] = total
            total += here
        for i in range(n):
            b = (keys[i] >> s) & digit_mask
            spare_keys[count[b]] = keys[i]
            spare_order[count[b]] = order[i]
            count[b] += 1
        keys, spare_keys = spare_keys, keys
        order, spare_order = spare_order, order
    return keys, order


@njit(cache=True, nogil=True)
def has_repeats(sorted_codes: np.ndarray) -> bool:
    """Whether two neighbours of a sorted array are equal."""
    for i in range(1, sorted_codes.shape[0]):
        if sorted_codes[i] == sorted_codes[i - 1]:
            return True
    return False


@njit(cache=True, nogil=True)
def group_parents(codes: np.ndarray, solid: np.ndarray):
    """The level above sorted Morton ``codes``: per parent (``code >> 3``, ascending), its
    code, first child, child mask and solid flag (all eight children present and solid)."""
    n = codes.shape[0]
    parents = 0
    for i in range(n):
        if i == 0 or (codes[i] >> np.uint64(3)) != (codes[i - 1] >> np.uint64(3)):
            parents += 1
    parent_codes = np.empty(parents, np.uint64)
    starts = np.empty(parents, np.int64)
    masks = np.zeros(parents, np.uint8)
    parent_solid = np.empty(parents, np.bool_)
    p = -1
    for i in range(n):
        code = codes[i] >> np.uint64(3)
        if i == 0 or code != parent_codes[p]:
            p += 1
            parent_codes[p] = code
            starts[p] = i
            parent_solid[p] = True
        masks[p] |= np.uint8(1 << (codes[i] & np.uint64(7)))
        parent_solid[p] = parent_solid[p] and solid[i]
    for p in range(parents):
        parent_solid[p] = parent_solid[p] and masks[p] == 255
    return parent_codes, starts, masks, parent_solid


@njit(cache=True, nogil=True)
def child_means(starts: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``(parents, columns)`` float32: per parent the mean of its children's rows of
    ``values`` (a run from ``starts[p]``, the last one ending at the last row), as
    ``np.add.reduceat`` with a float64 accumulator computes it, to the bit
    (``octree_levels.child_mean``), then rounded once."""
    parents = starts.shape[0]
    rows = values.shape[0]
    columns = values.shape[1]
    out = np.empty((parents, columns), np.float32)
    for p in range(parents):
        first = starts[p]
        last = starts[p + 1] if p + 1 < parents else rows
        for c in range(columns):
            out[p, c] = child_mean(values, first, last, c)
    return out
