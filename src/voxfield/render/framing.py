"""What a view should frame: a scene's content, not a ground plane that dominates its box.

A room or a model imported with a large floor (a glTF stage, a terrain tile under a house)
has a voxel box set by the floor, and a view of that box shows mostly floor with the content
a speck in its middle. ``content_box`` finds such a floor on a coarse level of the octree
(thin, lowest, and much wider than what stands on it) and returns the box of what stands on
it, widened by a margin of floor, so a three-quarter view shows the content at a useful size.
Scenes without such a floor (terrains, objects, rooms with walls) keep their voxel box.
"""

from __future__ import annotations

import numpy as np

from voxfield.svo.octree import Octree

#: Coarse cells across the octree's cube in which the floor is looked for.
CELLS = 64
#: A floor is at most this many coarse cells thick.
FLOOR_CELLS = 2
#: The content covers at most this share of the floor's footprint (else it is the scene).
CONTENT_SHARE = 0.25
#: Floor kept around the content, as a share of the content's horizontal extent.
MARGIN = 0.35


def content_box(octree: Octree) -> tuple[np.ndarray, np.ndarray]:
    """The box a view should frame: the voxel box, or what stands on a dominant floor."""
    lo, hi = octree.voxel_bounds
    level = min(octree.depth, int(np.log2(CELLS)))
    cell = 1 << (octree.depth - level)
    coords = octree.node_coords(level)
    if len(coords) == 0:
        return lo, hi
    floor_top = int(coords[:, 1].min()) + FLOOR_CELLS
    above = coords[coords[:, 1] >= floor_top]
    if len(above) == 0:
        return lo, hi
    floor_area = len(np.unique(coords[:, [0, 2]], axis=0))
    content_area = len(np.unique(above[:, [0, 2]], axis=0))
    if content_area > CONTENT_SHARE * floor_area:
        return lo, hi
    c_lo = above.min(axis=0) * cell
    c_hi = (above.max(axis=0) + 1) * cell
    margin = MARGIN * float(max(c_hi[0] - c_lo[0], c_hi[2] - c_lo[2]))
    box_lo = np.array([c_lo[0] - margin, lo[1], c_lo[2] - margin])
    box_hi = np.array([c_hi[0] + margin, c_hi[1], c_hi[2] + margin])
    return np.maximum(box_lo, lo).astype(np.float64), np.minimum(box_hi, hi).astype(np.float64)
