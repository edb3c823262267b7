"""Which faces of each voxel no other voxel covers, found in the octree itself.

A face is exposed when the voxel across it is absent. Faces toward a sibling are read from
the parent's child mask; the others by a lookup from the lowest ancestor the two voxels
share, which the depth-first walk keeps (most neighbours share a grandparent: two levels
down instead of the whole depth). Memory stays at one
byte per voxel, so this runs on streamed terrains far larger than their coordinate arrays.
Bits follow ``scene.surface.DIRECTIONS``: -x, +x, -y, +y, -z, +z.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from voxfield.kernels.node_descriptor import child_index, node_at, node_below
from voxfield.kernels.traversal import highest_bit


@njit(parallel=True, cache=True, nogil=True)
def leaf_exposure(descriptors, depth: int, start_level: int, start_first: int,
                  start_coords, out) -> None:
    """Exposed-face bits of every voxel into ``out`` (one byte per voxel, leaf order).

    The subtrees below the ``start_level`` nodes (flat indices from ``start_first``, corners
    ``start_coords`` in that level's node units) run in parallel, each depth first.
    """
    inner = descriptors.shape[0]
    for s in prange(start_coords.shape[0]):
        stack_node = np.empty(8 * (depth + 1), np.int64)
        stack_level = np.empty(8 * (depth + 1), np.int64)
        stack_pos = np.empty((8 * (depth + 1), 3), np.int64)
        path = np.empty(depth + 1, np.int64)  # the walk's current node per level
        side = 1 << depth
        top = 0
        stack_node[0] = start_first + s
        stack_level[0] = start_level
        stack_pos[0, 0] = start_coords[s, 0]
        stack_pos[0, 1] = start_coords[s, 1]
        stack_pos[0, 2] = start_coords[s, 2]
        top = 1
        while top > 0:
            top -= 1
            node = stack_node[top]
            level = stack_level[top]
            px = stack_pos[top, 0]
            py = stack_pos[top, 1]
            pz = stack_pos[top, 2]
            path[level] = node
            descriptor = descriptors[node]
            mask = descriptor & 0xFF
            if level + 1 < depth:
                for octant in range(8):
                    if (mask >> octant) & 1:
                        stack_node[top] = child_index(descriptor, octant)
                        stack_level[top] = level + 1
                        stack_pos[top, 0] = 2 * px + (octant & 1)
                        stack_pos[top, 1] = 2 * py + ((octant >> 1) & 1)
                        stack_pos[top, 2] = 2 * pz + ((octant >> 2) & 1)
                        top += 1
                continue
            # Children are voxels: their faces toward siblings from the mask, others by lookup.
            for octant in range(8):
                if not (mask >> octant) & 1:
                    continue
                x = 2 * px + (octant & 1)
                y = 2 * py + ((octant >> 1) & 1)
                z = 2 * pz + ((octant >> 2) & 1)
                bits = 0
                for axis in range(3):
                    bit = 1 << axis
                    high = (octant & bit) != 0
                    sibling_present = (mask >> (octant ^ bit)) & 1
                    # Toward the sibling: the high child's low face, the low child's high face.
                    inward_face = 2 * axis + (0 if high else 1)
                    outward_face = 2 * axis + (1 if high else 0)
                    if not sibling_present:
                        bits |= 1 << inward_face
                    step = 1 if high else -1
                    nx = x + (step if axis == 0 else 0)
                    ny = y + (step if axis == 1 else 0)
                    nz = z + (step if axis == 2 else 0)
                    if nx < 0 or ny < 0 or nz < 0 or nx >= side or ny >= side or nz >= side:
                        bits |= 1 << outward_face
                        continue
                    # The lowest common ancestor: above the highest bit where they differ.
                    shared = depth - 1 - highest_bit((x ^ nx) | (y ^ ny) | (z ^ nz))
                    if shared >= start_level:
                        found = node_below(descriptors, path[shared], shared, depth, nx, ny, nz)
                    else:
                        found = node_at(descriptors, depth, depth, nx, ny, nz)
                    if found < 0:
                        bits |= 1 << outward_face
                out[child_index(descriptor, octant) - inner] = bits
