"""How coarse levels get their colours: rules applied to a built octree, streamed or not.

A parent that averages all its children (``mean``, the EA thesis's rule) also averages what
no ray reaches at full resolution: buried earth, the inside of a hull, the underside of the
ground. The other rules keep coarse colours to what rays see:

- ``surface``: the mean over voxels weighted by their exposed faces, a face on the floor
  of the voxel box (the cut base of a terrain) not counted. One colour a node: a wall
  whose two sides differ shows their mix, and an object seen from below shows its
  interior where only floor faces were exposed;
- ``facing``: per inner node and travel direction along each axis, the colour a viewer
  looking that way sees (``kernels.facing_colour``), read by ray direction. 24 bytes per
  inner node on top of the albedo; the albedo itself keeps its ``mean``.

Only the albedo gets directional colours; baked channels keep their own weighting.
"""

from __future__ import annotations

import numba
import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.colour import decode_channel, encode_channel, storage_of
from voxfield.kernels.exposure import leaf_exposure
from voxfield.kernels.facing_colour import FACING_CHANNELS, facing_level
from voxfield.svo.channels import propagate_channel
from voxfield.svo.octree import Octree

#: The rules, the thesis's first. ``DEFAULT_LOD_COLOUR`` is what commands use unless told.
LOD_COLOURS = ("mean", "surface", "facing")
DEFAULT_LOD_COLOUR = "facing"
#: Face order of ``scene.surface.DIRECTIONS``: -y is the face turned to the floor.
_DOWN_FACE = 2


#: Inner nodes per call of the directional-colour kernel (about a second at most).
KERNEL_BAND_NODES = 1 << 20

def check_lod_colour(rule: str) -> str:
    if rule not in LOD_COLOURS:
        raise VoxfieldError(f"unknown LOD colour rule {rule!r}; choose one of "
                            f"{', '.join(LOD_COLOURS)}")
    return rule


def apply_lod_colour(octree: Octree, rule: str) -> Octree:
    """The octree with its coarse colours made by ``rule`` (built octrees carry ``mean``)."""
    check_lod_colour(rule)
    if rule == "surface":
        return surface_weighted(octree)
    if rule == "facing":
        return octree.recoloured(facing=facing_colours(octree))
    return octree


def exposed_face_weights(octree: Octree) -> np.ndarray:
    """Per voxel, the number of faces no voxel covers, less a down face on the box floor."""
    bits = exposed_faces(octree).copy()
    on_floor = octree.node_coords(octree.depth)[:, 1] == octree.voxel_box[0, 1]
    bits[on_floor] &= np.uint8(~(1 << _DOWN_FACE) & 0xFF)
    return np.unpackbits(bits[:, None], axis=1).sum(axis=1).astype(np.float64)


def surface_weighted(octree: Octree) -> Octree:
    """Every channel's inner levels re-averaged with ``exposed_face_weights``."""
    leaves = octree.level_slice(octree.depth)
    weights = exposed_face_weights(octree)
    attributes = {}
    for name, stored in octree.attributes.items():
        values = propagate_channel(octree, decode_channel(stored[leaves]), weights)
        attributes[name] = encode_channel(values, storage_of(stored))
    return octree.recoloured(attributes=attributes)


def facing_colours(octree: Octree) -> np.ndarray:
    """``(inner nodes, 6, 4)`` uint8 directional colours of the albedo, deepest level first."""
    exposure = exposed_faces(octree)
    facing = np.zeros((octree.inner_count, 6, FACING_CHANNELS), np.uint8)
    colors = octree.attributes["color"]
    for level in range(octree.depth - 1, -1, -1):
        sl = octree.level_slice(level)
        # Nodes of a level are independent: in bands, so Ctrl-C is heard between kernel calls.
        for first in range(sl.start, sl.stop, KERNEL_BAND_NODES):
            facing_level(octree.descriptors, first, min(sl.stop, first + KERNEL_BAND_NODES),
                         colors, exposure, facing)
    return facing


def exposed_faces(octree: Octree) -> np.ndarray:
    """Per voxel (leaf order), the bits of its faces no voxel covers (``kernels.exposure``);
    worked out once per structure (``Octree.derived``) and read-only, as it is shared."""
    return octree.derived(("exposed_faces",), lambda: _find_exposed_faces(octree))


def _find_exposed_faces(octree: Octree) -> np.ndarray:
    start_level = min(octree.depth - 1, 4)
    out = np.zeros(octree.voxel_count, np.uint8)
    first = int(octree.level_offsets[start_level])
    coords = octree.node_coords(start_level)
    # Subtrees are independent: a band per kernel call, so Ctrl-C is heard between calls,
    # each band wide enough to keep every thread busy.
    band = max(8 * numba.get_num_threads(), len(coords) // 64)
    for k in range(0, len(coords), band):
        leaf_exposure(octree.descriptors, octree.depth, start_level, first + k,
                      coords[k:k + band], out)
    out.setflags(write=False)
    return out
