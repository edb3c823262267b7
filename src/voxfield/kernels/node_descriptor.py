"""The packed inner-node descriptor every traversal reads: one int64 per inner node.

``first_child << 9 | solid << 8 | child_mask``:

- ``child_mask`` (bits 0-7): bit ``c`` set when child octant ``c = x | y << 1 | z << 2``
  exists;
- ``solid`` (bit 8): every voxel of the node's cube is present, so any ray that enters the
  cube hits a voxel at the moment it enters (any-hit queries stop there);
- ``first_child`` (bits 9-62): flat index of the first child; child ``c`` sits at
  ``first_child + popcount(child_mask & ((1 << c) - 1))``.

One 8-byte load per visited inner node, none per leaf.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SOLID_BIT = 1 << 8
FIRST_CHILD_SHIFT = 9


def pack_descriptors(child_mask: np.ndarray, first_child: np.ndarray,
                     solid: np.ndarray) -> np.ndarray:
    """Descriptors of inner nodes from their masks, first-child indices and solid flags."""
    packed = first_child.astype(np.int64) << FIRST_CHILD_SHIFT
    packed |= solid.astype(np.int64) << 8
    return packed | child_mask.astype(np.int64)


@njit(cache=True, nogil=True, inline="always")
def descriptor_mask(descriptor: int) -> int:
    return descriptor & 0xFF


@njit(cache=True, nogil=True, inline="always")
def descriptor_first_child(descriptor: int) -> int:
    return descriptor >> FIRST_CHILD_SHIFT


@njit(cache=True, nogil=True, inline="always")
def descriptor_solid(descriptor: int) -> bool:
    return (descriptor & SOLID_BIT) != 0


@njit(cache=True, nogil=True, inline="always")
def popcount8(x: int) -> int:
    """Set bits of an 8-bit mask (SWAR arithmetic: no table, no intrinsic, so the same code
    runs on CUDA and in its simulator)."""
    x = x - ((x >> 1) & 0x55)
    x = (x & 0x33) + ((x >> 2) & 0x33)
    return (x + (x >> 4)) & 0x0F


@njit(cache=True, nogil=True, inline="always")
def child_index(descriptor: int, octant: int) -> int:
    """Flat index of child ``octant`` (which must exist)."""
    below = descriptor & ((1 << octant) - 1) & 0xFF
    return (descriptor >> FIRST_CHILD_SHIFT) + popcount8(below)


@njit(cache=True, nogil=True)
def node_at(descriptors, depth: int, level: int, x: int, y: int, z: int) -> int:
    """Flat index of the inner node at ``level`` whose corner, in that level's node units,
    is ``(x, y, z)``; -1 where there is none."""
    side = 1 << level
    if x < 0 or y < 0 or z < 0 or x >= side or y >= side or z >= side:
        return -1
    return node_below(descriptors, 0, 0, level, x, y, z)


@njit(cache=True, nogil=True, inline="always")
def node_below(descriptors, node: int, level: int, target_level: int, x: int, y: int,
               z: int) -> int:
    """``node_at`` from an ancestor: the node at ``target_level`` with corner ``(x, y, z)``
    (that level's units) below ``node`` at ``level``, whose cube must hold it; -1 where
    there is none. A lookup next to a known node starts at their common ancestor."""
    for current in range(level, target_level):
        shift = target_level - current - 1
        octant = ((x >> shift) & 1) | (((y >> shift) & 1) << 1) | (((z >> shift) & 1) << 2)
        descriptor = descriptors[node]
        if not (descriptor >> octant) & 1:
            return -1
        node = child_index(descriptor, octant)
    return node
