"""The sparse voxel octree: per-level node runs in Morton order, flattened for kernels.

Level 0 is the root, level ``depth`` holds the voxels; ``lod = depth - level`` (EA thesis).
Nodes are numbered level after level; the children of a node are contiguous in the next
level. What is stored is what traversal needs and nothing it can derive:

- one packed descriptor per inner node (``kernels.node_descriptor``: child mask, solid bit,
  first child), 8 bytes; voxels need none;
- per node and channel one RGB value (``attributes``), a parent's being the mean of its
  children's (EA §3.1);
- the level offsets and the voxels' bounding box.

Node positions are not stored: a node's position is its path from the root, so
``node_coords`` rebuilds them level by level when something outside the kernels needs them
(the kernels know the position of every node they visit).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.fingerprint import array_fingerprint
from voxfield.kernels.colour import decode_channel
from voxfield.kernels.facing_colour import NO_FACING
from voxfield.kernels.node_descriptor import FIRST_CHILD_SHIFT, SOLID_BIT
from voxfield.kernels.octree_levels import child_corners

#: Fields ``Octree.recoloured`` may change: everything but the structure.
_COLOUR_FIELDS = frozenset({"attributes", "facing", "name"})
#: ``Octree.derived`` keys (first item) of tables that depend on the structure alone: the
#: column-top pyramid (``svo.column_tops``), the exposed faces (``svo.lod_colours``), the
#: context-aware error's repeating-surface flags and the children's mean SH error
#: coefficients for an error table (``render.error_aware``).
STRUCTURAL_TABLES = frozenset({"column_tops", "exposed_faces", "inside_repeating_surface",
                               "children_sh_means", "voxel_occupancy"})


class Channels(dict):
    """An octree's colour channels, read-only as its arrays are: a channel added in place
    (``octree.attributes["half"] = …``) would skip the checks an octree makes of its
    arrays. ``Octree.recoloured`` makes a copy with other channels."""

    def _refuse(self, *args, **kwargs):
        raise TypeError("an octree's channels are read-only; make a copy with other ones: "
                        "octree.recoloured(attributes={...})")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse
    __ior__ = _refuse

    def __reduce__(self):  # pickling rebuilds it whole (unpickling a dict sets items)
        return type(self), (dict(self),)


@dataclass(frozen=True)
class Octree:
    """An SVO over ``[0, 2**depth)^3`` in finest-voxel units."""

    depth: int
    descriptors: np.ndarray  # (inner nodes,) int64, kernels.node_descriptor layout
    level_offsets: np.ndarray  # (depth + 2,) int64: level l occupies [off[l], off[l+1])
    attributes: dict[str, np.ndarray]  # name -> (nodes, 3) colours (albedo, emission, ...)
    voxel_box: np.ndarray  # (2, 3) int64: voxels' min corner and exclusive max corner
    scene_origin: np.ndarray = field(default_factory=lambda: np.zeros(3, np.int64))
    build_seconds: float = 0.0
    name: str = "scene"
    #: ``(inner nodes, 6, 4)`` uint8 directional albedo (``svo.lod_colours``), or None.
    facing: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Arrays that disagree in shape or type are refused, and every array is made
        read-only: the kernels index one array by another's values, so an octree changed in
        place (``octree.descriptors[:] = …``) or assembled with a short colour array read
        past their ends and crashed the interpreter. Whether the child pointers describe a
        tree is checked where octrees come from outside (``svo.io.validate_octree``, run by
        ``load_octree``); run it on an octree assembled from arrays of unknown origin."""
        problem = shape_problem(self)
        if problem is not None:
            raise VoxfieldError(f"octree {self.name!r}: {problem}")
        object.__setattr__(self, "attributes", Channels(self.attributes))
        arrays = [self.descriptors, self.level_offsets, self.voxel_box, self.scene_origin,
                  *self.attributes.values()]
        for array in arrays + ([] if self.facing is None else [self.facing]):
            array.flags.writeable = False

    @property
    def node_count(self) -> int:
        return int(self.level_offsets[-1])

    def __repr__(self) -> str:  # the default printed every array in full
        return (f"Octree({self.name!r}: depth {self.depth}, {self.voxel_count:,} voxels, "
                f"{self.node_count:,} nodes, channels {sorted(self.attributes)})")

    @property
    def inner_count(self) -> int:
        return int(self.level_offsets[-2])

    @property
    def voxel_count(self) -> int:
        return int(self.level_offsets[-1] - self.level_offsets[-2])

    @property
    def size(self) -> int:
        """Side length of the root cube in voxels."""
        return 1 << self.depth

    @property
    def inner_nodes(self) -> np.ndarray:
        """The descriptors, as the traversal kernels take them."""
        return self.descriptors

    @cached_property
    def child_mask(self) -> np.ndarray:
        """``(nodes,)`` uint8: bit ``c`` set when child octant ``c = x | y << 1 | z << 2``
        exists (0 for voxels). Derived from the descriptors."""
        masks = np.zeros(self.node_count, np.uint8)
        masks[: self.inner_count] = self.descriptors & 0xFF
        return masks

    @cached_property
    def first_child(self) -> np.ndarray:
        """``(nodes,)`` int64: flat index of a node's first child (0 for voxels); child ``c``
        sits at ``first_child + popcount(mask & ((1 << c) - 1))``. Derived."""
        first = np.zeros(self.node_count, np.int64)
        first[: self.inner_count] = self.descriptors >> FIRST_CHILD_SHIFT
        return first

    def derived(self, key: tuple, compute):
        """``compute()``, worked out once per octree and ``key`` and kept with it (as the
        cached properties are): per-node tables several renders of one octree read. A key
        whose first item is in ``STRUCTURAL_TABLES`` names a table of the structure alone,
        which ``recoloured`` copies keep."""
        cache = self.__dict__.setdefault("_derived", {})
        if key not in cache:
            cache[key] = compute()
        return cache[key]

    def recoloured(self, **changes) -> Octree:
        """This octree with other colours (``attributes``, ``facing``, ``name``): the copy
        shares the structure, so it keeps every table derived from the structure alone,
        and the stages of one command (LOD colours, a bake) work each out once."""
        if not changes.keys() <= _COLOUR_FIELDS:
            raise ValueError(f"recoloured changes colours only, not {sorted(changes)}")
        copy = replace(self, **changes)  # new colour arrays are checked as it is made
        kept = {key: table for key, table in self.__dict__.get("_derived", {}).items()
                if key[0] in STRUCTURAL_TABLES}
        copy.__dict__["_derived"] = kept
        for name in ("child_mask", "first_child"):  # cached properties of the structure
            if name in self.__dict__:
                copy.__dict__[name] = self.__dict__[name]
        return copy

    def solid_nodes(self) -> np.ndarray:
        """``(nodes,)`` bool: is every voxel of the node's cube present? (Voxels are.)"""
        solid = np.ones(self.node_count, bool)
        solid[: self.inner_count] = (self.descriptors & SOLID_BIT) != 0
        return solid

    def derived_solid_flags(self) -> np.ndarray:
        """``(inner nodes,)`` bool: the solid bit each inner node should carry (all eight
        children present and solid; voxels are), worked out from the child masks bottom-up.
        A file's solid bits are checked against it: traversal trusts them."""
        return solid_flags(self.descriptors & 0xFF, self.descriptors >> FIRST_CHILD_SHIFT,
                           self.level_offsets)

    def occupied_box(self) -> np.ndarray:
        """``(2, 3)`` int64: the voxels' min corner and exclusive max corner as the child masks
        give them. Each face of the box is one descent that keeps only the nodes lying on
        that face (a node further in cannot hold a voxel further out), so it reads a slab
        of nodes per level, not every voxel."""
        box = np.zeros((2, 3), np.int64)
        for axis in range(3):
            for side in (0, 1):
                box[side, axis] = _extreme_coordinate(self, axis, side) + side
        return box

    @property
    def voxel_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Inclusive min and exclusive max corner of the voxels, in octree space."""
        return self.voxel_box[0].copy(), self.voxel_box[1].copy()

    def level_slice(self, level: int) -> slice:
        return slice(int(self.level_offsets[level]), int(self.level_offsets[level + 1]))

    def nodes_per_level(self) -> list[int]:
        return [int(n) for n in np.diff(self.level_offsets)]

    def node_level(self, node: np.ndarray) -> np.ndarray:
        """Level of each flat node index."""
        return np.searchsorted(self.level_offsets, np.asarray(node), side="right") - 1

    def node_coords(self, level: int, dtype=np.int64) -> np.ndarray:
        """``(nodes at level, 3)`` positions in units of the level's node size, rebuilt
        from the child masks level by level (children follow their parent's order, octants
        ascending). ``np.int32`` holds any octree's positions (extents are below 2^21) in
        half the memory: 200 MB less on a 2048² terrain's leaves."""
        if not 0 <= level <= self.depth:
            raise ValueError(f"level must be in 0..{self.depth}, got {level}")
        for current, coords in enumerate(self._coords_by_level(dtype)):
            if current == level:
                return coords
        raise AssertionError("unreachable")

    def all_node_coords(self) -> np.ndarray:
        """``(nodes, 3)`` int64 positions of every node, level after level (derived)."""
        return np.concatenate(list(self._coords_by_level()))

    def _coords_by_level(self, dtype=np.int64):
        coords = np.zeros((1, 3), dtype)
        yield coords
        for parent_level in range(self.depth):
            masks = (self.descriptors[self.level_slice(parent_level)] & 0xFF).astype(np.uint8)
            sl = self.level_slice(parent_level + 1)
            children = np.empty((sl.stop - sl.start, 3), dtype)
            child_corners(masks, coords, children)
            coords = children
            yield coords

    def lod_voxels(self, lod: int) -> np.ndarray:
        """Integer corners (in voxels) of all nodes at a given LOD (node size ``2**lod``)."""
        return self.node_coords(self.depth - lod) << lod

    @property
    def color(self) -> np.ndarray:
        """The albedo of every node as float32 linear RGB (decoded from its storage)."""
        return decode_channel(self.attributes["color"])

    def channel_linear(self, name: str) -> np.ndarray:
        """A channel of every node as float32 linear RGB, whatever its storage."""
        return decode_channel(self.channel(name))

    def stored_arrays(self) -> dict[str, np.ndarray]:
        """Every array the octree stores (what ``nbytes`` counts)."""
        arrays = {"descriptors": self.descriptors, "level_offsets": self.level_offsets,
                  "voxel_box": self.voxel_box}
        arrays.update({f"attr:{k}": v for k, v in self.attributes.items()})
        if self.facing is not None:
            arrays["facing"] = self.facing
        return arrays

    @property
    def nbytes(self) -> int:
        """Bytes of the whole octree: every stored array, no derived one."""
        return sum(a.nbytes for a in self.stored_arrays().values())

    def bytes_per_node(self) -> dict[str, float]:
        """Storage per node by array, for ``voxfield info``."""
        n = max(self.node_count, 1)
        per_node = {k: a.nbytes / n for k, a in self.stored_arrays().items()
                    if k not in ("level_offsets", "voxel_box")}
        per_node["total"] = self.nbytes / n
        return per_node

    def fingerprint(self, channel: str = "albedo") -> str:
        """Names this octree's structure and one colour channel in cache keys and probe
        files: equal octrees give equal fingerprints, any change in either gives another."""
        stored, facing = self.kernel_colours(channel)
        arrays = [self.level_offsets, self.child_mask, stored]
        return array_fingerprint(*arrays, *([facing] if facing.size else []))

    def kernel_colours(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """What colour-reading kernels take for a channel (``kernels.facing_colour.seen_rgb``):
        the stored channel and the directional colours, empty unless the channel is the
        albedo of an octree that has them."""
        stored = self.channel(name)
        if self.facing is not None and name in ("albedo", "color"):
            return stored, self.facing
        return stored, NO_FACING

    @property
    def channel_names(self) -> list[str]:
        """The colour channels by the names commands take (``albedo`` for the stored
        ``color``), sorted."""
        return sorted("albedo" if k == "color" else k for k in self.attributes)

    def channel(self, name: str) -> np.ndarray:
        """A channel as stored (``kernels.colour``: 8-bit sRGB or float32): what kernels take."""
        if name == "albedo":
            name = "color"
        if name not in self.attributes:
            known = ", ".join(self.channel_names)
            raise VoxfieldError(f"the octree has no channel {name!r}; it has: {known}")
        return self.attributes[name]


def check_octree(value, user: str) -> None:
    """A clear error where ``user`` (a function's name) was given something other than an
    octree: it would fail deep inside, on the first attribute it reads."""
    if not isinstance(value, Octree):
        raise VoxfieldError(f"{user} needs a voxfield Octree (voxfield.svo.open_octree), got "
                            f"{type(value).__name__}")


def shape_problem(octree: Octree) -> str | None:
    """What makes ``octree``'s arrays disagree with each other in shape or type (the kernels
    would read past an end), or None; checked without reading the arrays' contents."""
    off = octree.level_offsets
    if not isinstance(off, np.ndarray) or off.ndim != 1 or not np.issubdtype(off.dtype,
                                                                           np.integer):
        return "inconsistent depth or level offsets"
    if (not isinstance(octree.depth, (int, np.integer)) or not 1 <= octree.depth <= 21
            or len(off) != octree.depth + 2 or off[0] != 0 or np.any(np.diff(off) <= 0)):
        return "inconsistent depth or level offsets (or a level without nodes)"
    origin = octree.scene_origin
    if (not isinstance(origin, np.ndarray) or origin.shape != (3,)
            or not np.issubdtype(origin.dtype, np.integer)):
        return "the scene origin must be three whole numbers"
    box = octree.voxel_box
    if (not isinstance(box, np.ndarray) or box.shape != (2, 3)
            or not np.issubdtype(box.dtype, np.integer)):
        return "the voxel box must be two corners of whole numbers"
    if np.any(box[0] < 0) or np.any(box[1] <= box[0]) or np.any(box[1] > (1 << octree.depth)):
        return "voxel box outside the root cube"
    descriptors = octree.descriptors
    if (not isinstance(descriptors, np.ndarray) or descriptors.dtype != np.int64
            or descriptors.shape != (int(off[-2]),)):
        return "descriptor array has the wrong type or length"
    if not isinstance(octree.attributes, dict):
        return "attributes must be a dict of colour arrays"
    for name, values in octree.attributes.items():
        problem = colour_array_problem(values, int(off[-1]))
        if problem is not None:
            return f"attribute {name!r} {problem}"
    if octree.facing is not None:
        problem = facing_array_problem(octree.facing, int(off[-2]))
        if problem is not None:
            return f"directional colours {problem}"
    return None


def colour_array_problem(values, nodes: int) -> str | None:
    """What is wrong with ``values`` as a colour attribute of ``nodes`` nodes (the words
    after its name), or None: 8-bit sRGB or float32 ``(nodes, 3)``, or RGB9E5 ``(nodes,)``."""
    if not isinstance(values, np.ndarray) or values.dtype not in (np.uint8, np.float32,
                                                                  np.uint32):
        kind = values.dtype if isinstance(values, np.ndarray) else type(values).__name__
        return f"is {kind}, not 8-bit sRGB, float32 or RGB9E5 (a NumPy array)"
    if values.shape != ((nodes,) if values.dtype == np.uint32 else (nodes, 3)):
        return f"has shape {values.shape}, not one colour for each of the {nodes:,} nodes"
    return None


def facing_array_problem(values, inner_nodes: int) -> str | None:
    """What is wrong with ``values`` as the directional colours of ``inner_nodes`` inner
    nodes, or None: uint8 ``(inner_nodes, 6, 4)``."""
    if (not isinstance(values, np.ndarray) or values.dtype != np.uint8
            or values.shape != (inner_nodes, 6, 4)):
        return f"must be uint8 of shape ({inner_nodes:,}, 6, 4)"
    return None


#: Set bits of every byte: the number of children a child mask names.
CHILD_COUNT = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1).sum(axis=1,
                                                                                 dtype=np.int64)
#: For axis ``a`` and half ``h``, the octants whose ``a`` bit is ``h``.
_HALF_OCTANTS = np.array([[[c for c in range(8) if (c >> axis) & 1 == half] for half in (0, 1)]
                          for axis in range(3)])
#: The same halves as child-mask bits.
_HALF_MASKS = np.bitwise_or.reduce(1 << _HALF_OCTANTS, axis=-1).astype(np.uint8)


def solid_flags(masks: np.ndarray, first: np.ndarray, level_offsets: np.ndarray) -> np.ndarray:
    """``(inner nodes,)`` bool solid flags from inner nodes' child masks and first children
    (``Octree.derived_solid_flags``). A pointer past the node arrays raises IndexError
    (``load_octree`` reports a version-1 file's as corrupt; version-2 pointers are validated
    first)."""
    masks = np.asarray(masks)
    solid = np.zeros(len(masks), bool)
    child_solid = np.ones(int(level_offsets[-1] - level_offsets[-2]), bool)  # the voxels
    for level in range(len(level_offsets) - 3, -1, -1):
        start, stop = int(level_offsets[level]), int(level_offsets[level + 1])
        full = np.flatnonzero(masks[start:stop] == 0xFF)
        level_solid = np.zeros(stop - start, bool)
        if len(full):
            children = (first[start:stop][full][:, None] + np.arange(8)) - stop
            level_solid[full] = child_solid[children].all(axis=1)
        solid[start:stop] = level_solid
        child_solid = level_solid
    return solid


def _extreme_coordinate(octree: Octree, axis: int, side: int) -> int:
    """The least (``side`` 0) or greatest (1) voxel coordinate along ``axis``."""
    frontier = np.zeros(1, np.int64)  # flat indices of the nodes on the face, the root first
    coordinate = 0
    for _ in range(octree.depth):
        descriptors = octree.descriptors[frontier]
        masks = (descriptors & 0xFF).astype(np.uint8)
        first = descriptors >> FIRST_CHILD_SHIFT
        # The face's side of the nodes if any of them has a child there, else the other.
        half = side if np.any(masks & _HALF_MASKS[axis, side]) else 1 - side
        coordinate = 2 * coordinate + half
        octants = _HALF_OCTANTS[axis, half]
        present = (masks[:, None] >> octants) & 1 == 1
        below = masks[:, None] & ((1 << octants) - 1).astype(np.uint8)
        frontier = (first[:, None] + CHILD_COUNT[below])[present]
    return coordinate
