"""Bottom-up octree build: Morton-sort the voxels, then group children under parents per level."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from voxfield.errors import SceneTooLargeError, VoxfieldError
from voxfield.kernels.colour import SRGB8, STORAGES, encode_channel
from voxfield.kernels.node_descriptor import pack_descriptors
from voxfield.kernels.octree_build import (
    child_means,
    group_parents,
    has_repeats,
    morton_codes,
    sort_codes,
)
from voxfield.progress import progress_bar
from voxfield.scene.voxel_scene import MAX_EXTENT, VoxelScene
from voxfield.svo.channels import check_channel_name
from voxfield.svo.lod_colours import DEFAULT_LOD_COLOUR, apply_lod_colour, check_lod_colour
from voxfield.svo.octree import Octree


def morton_encode(coords: np.ndarray, origin=(0, 0, 0)) -> np.ndarray:
    """63-bit Morton codes of corners relative to ``origin``, with x in bit 0, y in bit 1,
    z in bit 2 of each octal digit."""
    return morton_codes(np.ascontiguousarray(coords, np.int64).reshape(-1, 3),
                        np.asarray(origin, np.int64))


def octree_depth_for(extent: np.ndarray) -> int:
    """Smallest depth whose root cube covers the extent (at least 1)."""
    longest = int(np.max(extent)) if len(extent) else 1
    return max(1, int(np.ceil(np.log2(max(longest, 2)))))


def _add_parent_level(codes, level_masks, level_first, level_solid, level_attrs) -> np.ndarray:
    """Group the last level's nodes under their parents (Morton code >> 3) and append the
    parent level: OR-ed child masks, first-child offsets, solid flags (all eight children
    solid) and mean attributes. Returns the parents' Morton codes."""
    parent_codes, starts, masks, solid = group_parents(codes, level_solid[-1])
    level_masks.append(masks)
    level_first.append(starts)
    level_solid.append(solid)
    level_attrs.append({k: child_means(starts, v) for k, v in level_attrs[-1].items()})
    return parent_codes


def build_octree(
    scene: VoxelScene, *, memory_limit_bytes: int | None = None, progress: bool = False,
    lod_colour: str = DEFAULT_LOD_COLOUR, colour_storage: str = SRGB8,
) -> Octree:
    """Build the SVO of a scene; the scene is moved so its minimum corner is the origin.

    ``lod_colour`` is how coarse levels are coloured (``svo.lod_colours.LOD_COLOURS``).

    ``colour_storage`` is how the albedo is kept: 8-bit sRGB (``srgb8``, 3 bytes a node; an
    8-bit input survives exactly) or ``float32`` (12 bytes). Other channels stay float32.
    """
    if not isinstance(scene, VoxelScene):
        raise VoxfieldError("build_octree needs a VoxelScene (voxfield.scene.loaders."
                            f"load_scene), got {type(scene).__name__}")
    check_lod_colour(lod_colour)
    if colour_storage not in STORAGES:
        raise VoxfieldError(f"unknown colour storage {colour_storage!r}; choose one of "
                            f"{', '.join(STORAGES)}")
    if len(scene) == 0:
        raise VoxfieldError(f"scene {scene.name!r} has no voxels; nothing to build")
    start = time.perf_counter()
    lo, hi = scene.bounds
    extent = hi - lo
    if int(extent.max()) > MAX_EXTENT:
        raise SceneTooLargeError(
            f"scene {scene.name!r} spans {extent.tolist()} voxels; at most {MAX_EXTENT} per axis"
        )
    n = len(scene)
    estimate = n * 120  # bytes: codes, order, attributes, per-level copies
    if memory_limit_bytes is not None and estimate > memory_limit_bytes:
        raise SceneTooLargeError(
            f"building {n:,} voxels needs about {estimate / 2**30:.1f} GiB, over the "
            f"{memory_limit_bytes / 2**30:.1f} GiB limit; crop or downsample the scene"
        )
    depth = octree_depth_for(extent)
    codes, order = sort_codes(morton_encode(scene.coords, lo), 3 * depth)
    if has_repeats(codes):
        # Only a scene made in code gets here: the file readers merge repeats themselves.
        repeats = int(np.count_nonzero(codes[1:] == codes[:-1]))
        raise VoxfieldError(f"scene {scene.name!r} holds {repeats:,} duplicate voxel(s), at "
                            "positions already taken; its .dedupe() keeps the last at each")

    attributes = {"color": scene.color[order]}
    if scene.emission is not None:
        attributes["emission"] = scene.emission[order]
    for name, values in scene.channels.items():
        attributes[check_channel_name(name)] = values[order]

    del order
    # Levels are gathered leaf-first, then reversed into root-first order.
    level_masks = [np.zeros(n, np.uint8)]
    level_first = [np.zeros(n, np.int64)]
    level_solid = [np.ones(n, bool)]
    level_attrs = [attributes]
    with progress_bar(total=depth + 1, desc="octree", unit="level", enabled=progress) as bar:
        bar.update(1)  # the Morton sort, done above
        for _ in range(depth):
            codes = _add_parent_level(codes, level_masks, level_first, level_solid, level_attrs)
            bar.update(1)

    level_masks.reverse()
    level_first.reverse()
    level_solid.reverse()
    level_attrs.reverse()
    sizes = np.array([len(m) for m in level_masks], dtype=np.int64)
    offsets = np.concatenate(([0], np.cumsum(sizes)))
    descriptors = np.concatenate([
        pack_descriptors(level_masks[level], level_first[level] + offsets[level + 1],
                         level_solid[level])
        for level in range(depth)
    ])
    octree = Octree(
        depth=depth,
        descriptors=descriptors,
        level_offsets=offsets,
        attributes={k: np.concatenate([a[k] for a in level_attrs]) for k in attributes},
        voxel_box=np.array([np.zeros(3, np.int64), (hi - lo).astype(np.int64)]),
        scene_origin=lo.astype(np.int64),
        build_seconds=time.perf_counter() - start,
        name=scene.name,
    )
    attributes = dict(octree.attributes)
    attributes["color"] = encode_channel(attributes["color"], colour_storage)
    return apply_lod_colour(replace(octree, attributes=attributes), lod_colour)

