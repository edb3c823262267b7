"""Which faces of each inner node border a same-level neighbour shaped like itself.

The EA error of a node is the silhouette its children do not fill, seen alone. Inside flat
ground or a terrace every neighbour on the same level has the same child mask, so sampling
them all coarse shifts the surface without changing its silhouette. One byte per inner
node, bit ``k`` (face order -x, +x, -y, +y, -z, +z) set where the neighbour across face
``k`` exists on the same level with the same child mask.
"""

from __future__ import annotations

from numba import njit, prange

from voxfield.kernels.node_descriptor import node_at


@njit(parallel=True, cache=True, nogil=True)
def same_shape_neighbours(descriptors, depth: int, level: int, first: int, coords,
                          out) -> None:
    """Fill ``out[node]`` for the inner nodes of one level (flat indices from ``first``,
    corners ``coords`` in that level's node units)."""
    for i in prange(coords.shape[0]):
        node = first + i
        mask = descriptors[node] & 0xFF
        bits = 0
        for axis in range(3):
            for up in range(2):
                step = 1 if up else -1
                nx = coords[i, 0] + (step if axis == 0 else 0)
                ny = coords[i, 1] + (step if axis == 1 else 0)
                nz = coords[i, 2] + (step if axis == 2 else 0)
                other = node_at(descriptors, depth, level, nx, ny, nz)
                if other >= 0 and (descriptors[other] & 0xFF) == mask:
                    bits |= 1 << (2 * axis + up)
        out[node] = bits
