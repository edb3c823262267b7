"""Streamed octree build: bounded memory for worlds larger than a monolithic sort allows.

The monolithic build (``build.build_octree``) Morton-sorts every voxel at once, which at
~350M voxels needs more memory than the finished octree by an order of magnitude. Here the
world arrives as column blocks (a ``BlockSource``: all voxels whose x and z fall in a
``block``² square), each block is cut into ``block``³ cubes, and every cube is built on its
own into its finished levels (descriptors and colours) while only the cube's voxels are in
memory. A cube's nodes are contiguous within each level of the global Morton order, so the
cubes, put in Morton order of their position, concatenate into the global levels; the levels
above the cubes are built from the cube roots. The result is bit-identical to the monolithic
build (the same means, in the same order, in the same precision); tests hold it to that.
"""

from __future__ import annotations

import os
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from voxfield.errors import SceneTooLargeError, VoxfieldError
from voxfield.kernels.colour import SRGB8, STORAGES, encode_channel
from voxfield.kernels.node_descriptor import pack_descriptors
from voxfield.kernels.octree_build import has_repeats, sort_codes
from voxfield.memory import check_fits_in_memory
from voxfield.progress import progress_bar
from voxfield.scene.voxel_scene import MAX_EXTENT, VoxelScene
from voxfield.svo.build import _add_parent_level, morton_encode, octree_depth_for
from voxfield.svo.octree import Octree

#: Side of the column blocks and cubes: 256³ cubes keep a block's voxels to a few million
#: on terrains and leave ~2,000 cubes per 8192² world.
DEFAULT_BLOCK = 256
#: Bytes per voxel the build holds at its peak: the finished levels of every cube (3-byte
#: colours, descriptors for ~1/4 of them) and their concatenation into the final arrays.
PEAK_BYTES_PER_VOXEL = 16
#: Threads that build cubes while the source delivers the next blocks.
BUILD_THREADS = 2


class BlockSource(Protocol):
    """A voxel world delivered in column blocks (scene coordinates, as ``VoxelScene``)."""

    name: str
    attribute_names: tuple[str, ...]  # "color" first, then e.g. "emission"
    voxel_count: int

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Inclusive min and exclusive max voxel corner of the whole world."""

    def column_block(self, x0: int, z0: int, size: int) -> tuple[np.ndarray, dict]:
        """``(coords (n, 3) int64, {name: (n, 3) float32})`` of every voxel with
        ``x0 <= x < x0 + size`` and ``z0 <= z < z0 + size``, no voxel twice."""


@dataclass
class SceneBlocks:
    """A VoxelScene as a BlockSource (tests and small scenes)."""

    scene: VoxelScene

    @property
    def name(self) -> str:
        return self.scene.name

    @property
    def attribute_names(self) -> tuple[str, ...]:
        extra = ("emission",) if self.scene.emission is not None else ()
        return ("color", *extra, *self.scene.channels)

    @property
    def bounds(self):
        return self.scene.bounds

    @property
    def voxel_count(self) -> int:
        return len(self.scene)

    def column_block(self, x0: int, z0: int, size: int):
        c = self.scene.coords
        keep = (c[:, 0] >= x0) & (c[:, 0] < x0 + size) & (c[:, 2] >= z0) & (c[:, 2] < z0 + size)
        attributes = {"color": self.scene.color[keep]}
        if self.scene.emission is not None:
            attributes["emission"] = self.scene.emission[keep]
        for name, values in self.scene.channels.items():
            attributes[name] = values[keep]
        return c[keep].astype(np.int64), attributes


@dataclass
class _Cube:
    """One cube's finished levels (local level 0 is the cube root, ``bits`` its voxels)."""

    masks: list  # per inner local level: uint8
    first: list  # per inner local level: int64 index into the next local level
    solid: list  # per inner local level: bool
    colours: dict  # name -> list per local level of stored colours (root included)
    root_colour: dict  # name -> (1, 3) float32: what the levels above average
    root_solid: bool


def build_octree_streamed(
    source: BlockSource, *, block: int = DEFAULT_BLOCK, progress: bool = False,
    colour_storage: str = SRGB8,
) -> Octree:
    """Build the octree of a block source (see the module docstring for how)."""
    if colour_storage not in STORAGES:
        raise VoxfieldError(f"unknown colour storage {colour_storage!r}; choose one of "
                            f"{', '.join(STORAGES)}")
    if block < 2 or block & (block - 1):
        raise VoxfieldError(f"block must be a power of two of at least 2, got {block}")
    start = time.perf_counter()
    lo, hi = (np.asarray(b, np.int64) for b in source.bounds)
    extent = hi - lo
    if np.any(extent <= 0):
        raise VoxfieldError(f"scene {source.name!r} has no voxels; nothing to build")
    if int(extent.max()) > MAX_EXTENT:
        raise SceneTooLargeError(
            f"scene {source.name!r} spans {extent.tolist()} voxels; at most {MAX_EXTENT} per axis")
    need = int(source.voxel_count) * PEAK_BYTES_PER_VOXEL
    check_fits_in_memory(
        need, f"scene {source.name!r} has {source.voxel_count:,} voxels: building its octree",
        "lower the footprint or the fill depth", SceneTooLargeError)
    depth = octree_depth_for(extent)
    bits = min(int(block).bit_length() - 1, depth)
    size = 1 << bits
    names = tuple(source.attribute_names)
    storages = {name: (colour_storage if name == "color" else "float32") for name in names}

    cubes: dict[int, _Cube] = {}
    columns = [(bx, bz) for bz in range(-(-int(extent[2]) // size))
               for bx in range(-(-int(extent[0]) // size))]

    def build_block(coords: np.ndarray, attributes: dict, bx: int, bz: int) -> list:
        """The cubes of one column block, keyed by the Morton code of their position."""
        cube_y = (coords[:, 1] - lo[1]) >> bits
        if cube_y.min() == cube_y.max():  # one cube: its voxels as they came, no copy
            parts = [(int(cube_y[0]), slice(None))]
        else:  # (small keys: NumPy radix-sorts them)
            key = cube_y.astype(np.uint16) if cube_y.max() < 1 << 16 else cube_y
            order = np.argsort(key, kind="stable")
            parts = [(int(cube_y[part[0]]), part) for part in
                     np.split(order, np.flatnonzero(np.diff(cube_y[order])) + 1)]
        built = []
        for cy, part in parts:
            corner = np.array([bx, cy, bz])
            cube = _build_cube(coords[part], {k: attributes[k][part] for k in names},
                               lo + (corner << bits), bits, storages)
            built.append((int(morton_encode(corner[None])[0]), cube))
        return built

    # The source delivers blocks here, in order; threads build their cubes meanwhile (NumPy
    # sorts and arithmetic release the GIL). At most ``2 × workers + 1`` blocks wait, so
    # memory stays bounded; results land in block order, so the octree does not depend on
    # timing. On an error or Ctrl-C the waiting blocks are dropped, not built.
    workers = max(1, min(BUILD_THREADS, os.cpu_count() or 1))
    with progress_bar(total=len(columns), desc="octree", unit="block", enabled=progress) as bar, \
            ThreadPoolExecutor(workers) as pool:
        pending: deque = deque()

        def collect() -> None:
            cubes.update(pending.popleft().result())
            bar.update(1)

        try:
            for bx, bz in columns:
                coords, attributes = source.column_block(int(lo[0]) + bx * size,
                                                         int(lo[2]) + bz * size, size)
                if len(coords):
                    pending.append(pool.submit(build_block, coords, attributes, bx, bz))
                else:
                    bar.update(1)
                while len(pending) > 2 * workers:
                    collect()
            while pending:
                collect()
        except BaseException:
            for future in pending:
                future.cancel()
            raise
    if not cubes:
        raise VoxfieldError(f"scene {source.name!r} has no voxels; nothing to build")
    return _assemble(cubes, depth, bits, names, storages, lo, hi, source.name,
                     time.perf_counter() - start)


def _build_cube(coords: np.ndarray, attributes: dict, origin: np.ndarray, bits: int,
                storages: dict) -> _Cube:
    """A cube's levels from its voxels (scene corners, ``origin`` the cube's lowest), as the
    monolithic build makes them: Morton sort, then parents grouped level by level."""
    codes, order = sort_codes(morton_encode(coords, origin), 3 * bits)
    if has_repeats(codes):
        raise VoxfieldError("the scene holds duplicate voxels; deduplicate it first")
    n = len(codes)
    level_masks = [np.zeros(n, np.uint8)]
    level_first = [np.zeros(n, np.int64)]
    level_solid = [np.ones(n, bool)]
    level_attrs = [{k: np.asarray(v, np.float32)[order] for k, v in attributes.items()}]
    for _ in range(bits):
        codes = _add_parent_level(codes, level_masks, level_first, level_solid, level_attrs)
    level_masks.reverse()
    level_first.reverse()
    level_solid.reverse()
    level_attrs.reverse()
    colours = {k: [encode_channel(level[k], storages[k]) for level in level_attrs]
               for k in attributes}
    return _Cube(
        masks=level_masks[:-1], first=level_first[:-1], solid=level_solid[:-1],
        colours=colours, root_colour={k: level_attrs[0][k] for k in attributes},
        root_solid=bool(level_solid[0][0]),
    )


def _assemble(cubes: dict, depth: int, bits: int, names: tuple, storages: dict,
              lo: np.ndarray, hi: np.ndarray, name: str, seconds: float) -> Octree:
    """Concatenate the cubes' levels in Morton order under the levels built from their roots."""
    codes = np.array(sorted(cubes), dtype=np.uint64)
    ordered = [cubes[int(c)] for c in codes]
    upper = depth - bits  # level of the cube roots
    # Levels above the cubes: the cube roots are the "voxels" of a depth-``upper`` build.
    level_masks = [np.zeros(len(codes), np.uint8)]
    level_first = [np.zeros(len(codes), np.int64)]
    level_solid = [np.array([c.root_solid for c in ordered])]
    level_attrs = [{k: np.concatenate([c.root_colour[k] for c in ordered]) for k in names}]
    for _ in range(upper):
        codes = _add_parent_level(codes, level_masks, level_first, level_solid, level_attrs)
    level_masks.reverse()
    level_first.reverse()
    level_solid.reverse()
    level_attrs.reverse()
    sizes = [len(m) for m in level_masks]  # levels 0..upper
    sizes += [sum(len(c.colours[names[0]][j]) for c in ordered) for j in range(1, bits + 1)]
    offsets = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    parts = [pack_descriptors(level_masks[lv], level_first[lv] + offsets[lv + 1],
                              level_solid[lv]) for lv in range(upper)]
    # Cube levels: local first-child indices move by the children of the cubes before.
    for j in range(bits):
        base = offsets[upper + j + 1]
        before = np.cumsum([0] + [len(c.colours[names[0]][j + 1]) for c in ordered[:-1]])
        parts.append(np.concatenate([
            pack_descriptors(c.masks[j], c.first[j] + base + shift, c.solid[j])
            for c, shift in zip(ordered, before, strict=True)
        ]))
    attributes = {}
    for k in names:
        upper_levels = [encode_channel(level[k], storages[k]) for level in level_attrs]
        cube_levels = [np.concatenate([c.colours[k][j] for c in ordered])
                       for j in range(1, bits + 1)]
        attributes[k] = np.concatenate(upper_levels + cube_levels)
    return Octree(
        depth=depth,
        descriptors=np.concatenate(parts) if parts else np.zeros(0, np.int64),
        level_offsets=offsets,
        attributes=attributes,
        voxel_box=np.array([np.zeros(3, np.int64), hi - lo]),
        scene_origin=lo,
        build_seconds=seconds,
        name=name,
    )
