"""The sparse voxel octree: per-level arrays in Morton order, flattened for kernels.

Level 0 is the root, level ``depth`` holds the voxels; ``lod = depth - level`` (EA thesis).
Node ``i`` of the flat arrays has ``child_mask[i]`` (bit ``c`` set when child octant ``c``
exists, ``c = x | y << 1 | z << 2``) and ``first_child[i]`` (flat index of its first child;
child ``c`` sits at ``first_child + popcount(mask & ((1 << c) - 1))``). A parent's colour is
the mean of its children's colours (EA §3.1).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from voxfield.kernels.node_descriptor import pack_descriptors


@dataclass(frozen=True)
class Octree:
    """An SVO over ``[0, 2**depth)^3`` in finest-voxel units."""

    depth: int
    child_mask: np.ndarray  # (nodes,) uint8
    first_child: np.ndarray  # (nodes,) uint32, flat index; 0 for leaves
    node_coord: np.ndarray  # (nodes, 3) int32, position in units of the node's own size
    level_offsets: np.ndarray  # (depth + 2,) int64: level l occupies [off[l], off[l+1])
    attributes: dict[str, np.ndarray]  # name -> (nodes, 3) float32 (albedo, emission, ...)
    scene_origin: np.ndarray = field(default_factory=lambda: np.zeros(3, np.int64))
    build_seconds: float = 0.0
    name: str = "scene"

    @property
    def node_count(self) -> int:
        return int(self.level_offsets[-1])

    @property
    def voxel_count(self) -> int:
        return int(self.level_offsets[-1] - self.level_offsets[-2])

    @property
    def size(self) -> int:
        """Side length of the root cube in voxels."""
        return 1 << self.depth

    @cached_property
    def inner_nodes(self) -> np.ndarray:
        """One packed descriptor per inner node (levels 0..depth-1), the layout the
        traversal kernels read (``kernels.node_descriptor``)."""
        inner = int(self.level_offsets[-2])
        return pack_descriptors(self.child_mask[:inner], self.first_child[:inner],
                                self.solid_nodes()[:inner])

    def solid_nodes(self) -> np.ndarray:
        """Per node: is every voxel of its cube present? Voxels are; an inner node is when
        all eight children are solid."""
        solid = np.ones(self.node_count, bool)
        for level in range(self.depth - 1, -1, -1):
            sl = self.level_slice(level)
            full = np.flatnonzero(self.child_mask[sl] == 0xFF)
            level_solid = np.zeros(sl.stop - sl.start, bool)
            if len(full):
                children = self.first_child[sl][full].astype(np.int64)[:, None] + np.arange(8)
                level_solid[full] = solid[children].all(axis=1)
            solid[sl] = level_solid
        return solid

    @property
    def voxel_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Inclusive min and exclusive max corner of the voxels, in octree space."""
        leaves = self.node_coord[self.level_slice(self.depth)]
        return leaves.min(axis=0).astype(np.int64), leaves.max(axis=0).astype(np.int64) + 1

    def level_slice(self, level: int) -> slice:
        return slice(int(self.level_offsets[level]), int(self.level_offsets[level + 1]))

    def nodes_per_level(self) -> list[int]:
        return [int(n) for n in np.diff(self.level_offsets)]

    def node_level(self, node: np.ndarray) -> np.ndarray:
        """Level of each flat node index."""
        return np.searchsorted(self.level_offsets, np.asarray(node), side="right") - 1

    @property
    def color(self) -> np.ndarray:
        return self.attributes["color"]

    def bytes_per_node(self) -> dict[str, float]:
        """Storage per node by array, for ``voxfield info``."""
        n = max(self.node_count, 1)
        sizes = {
            "child_mask": self.child_mask.nbytes,
            "first_child": self.first_child.nbytes,
            "node_coord": self.node_coord.nbytes,
        }
        for key, arr in self.attributes.items():
            sizes[f"attr:{key}"] = arr.nbytes
        per_node = {k: v / n for k, v in sizes.items()}
        per_node["total"] = sum(sizes.values()) / n
        return per_node

    def lod_voxels(self, lod: int) -> np.ndarray:
        """Integer corners (in voxels) of all nodes at a given LOD (node size ``2**lod``)."""
        level = self.depth - lod
        return self.node_coord[self.level_slice(level)].astype(np.int64) << lod

    def channel(self, name: str) -> np.ndarray:
        from voxfield.errors import VoxfieldError

        if name == "albedo":
            name = "color"
        if name not in self.attributes:
            known = ", ".join(sorted("albedo" if k == "color" else k for k in self.attributes))
            raise VoxfieldError(f"the octree has no channel {name!r}; it has: {known}")
        return self.attributes[name]
