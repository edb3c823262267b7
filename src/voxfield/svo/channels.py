"""Extra colour channels on an existing octree (lit colours per time of day, ...).

A channel is one RGB value per node, like the albedo: given per voxel, its inner levels are
derived bottom-up the way the build derives albedo (a parent is the float64 mean of its
children's float32 values, stored as float32), so a channel made from the albedo's own leaf
values reproduces the albedo bit for bit.

An optional per-voxel weight turns the parent mean into a weighted mean. The lighting bake
uses it so that voxels nobody can see (buried under the surface, facing the ground) do not
darken the coarse levels: a node's lit colour is then the colour of its visible surface.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.colour import FLOAT32, HDR_STORAGES, encode_channel
from voxfield.kernels.octree_levels import average_children
from voxfield.scene.voxel_scene import check_channel_name  # the scene's rule, kept
from voxfield.svo.octree import Octree

__all__ = [
    "check_channel_name", "check_channel_storage", "fill_inner_levels", "new_channel_block",
    "propagate_channel", "with_channel", "with_channel_block", "with_channels",
]

def check_channel_storage(storage: str) -> str:
    """``storage`` if channels can be kept in it (``kernels.colour.HDR_STORAGES``);
    VoxfieldError otherwise."""
    if storage not in HDR_STORAGES:
        raise VoxfieldError(f"unknown channel storage {storage!r}; choose one of "
                            f"{', '.join(HDR_STORAGES)}")
    return storage


def _leaf_array(octree: Octree, values, what: str, columns: int | None) -> np.ndarray:
    """``values`` as a finite float array with one row per voxel, or VoxfieldError."""
    array = np.asarray(values)
    shape = (octree.voxel_count,) if columns is None else (octree.voxel_count, columns)
    if array.shape != shape:
        raise VoxfieldError(
            f"{what} must have shape {shape} (one per voxel, in leaf order), got {array.shape}"
        )
    if not np.issubdtype(array.dtype, np.number) or np.issubdtype(array.dtype, np.complexfloating):
        raise VoxfieldError(f"{what} must be real numbers, got {array.dtype}")
    if not np.all(np.isfinite(array)):
        raise VoxfieldError(f"{what} holds NaN or infinite values")
    return array


def propagate_channel(
    octree: Octree, leaf_values: np.ndarray, leaf_weights: np.ndarray | None = None
) -> np.ndarray:
    """``(nodes, C)`` float32 values for every node from ``(voxels, C)`` leaf values (C = 3
    for one RGB channel; several channels side by side share one pass).

    Without weights a parent is the mean of its children (as the build averages albedo).
    With weights (non-negative, one per voxel) a parent is the weighted mean of its
    children and carries the sum of their weights; a parent whose children all weigh
    zero takes their plain mean.
    """
    leaf_values = np.ascontiguousarray(leaf_values, np.float32)
    out = np.empty((octree.node_count, leaf_values.shape[1]), np.float32)
    out[octree.level_slice(octree.depth)] = leaf_values
    fill_inner_levels(octree, out, leaf_weights)
    return out


def fill_inner_levels(
    octree: Octree, values: np.ndarray | Sequence[np.ndarray],
    leaf_weights: np.ndarray | None = None,
) -> None:
    """``propagate_channel`` in place: ``values`` (one channel ``(nodes, C)`` float32, a
    block of channels ``(K, nodes, C)`` as ``new_channel_block`` makes, or a sequence of
    channels sharing the weights) has its voxel rows set, and gets every inner row from
    them, with no copy of the leaves. Each level's child runs and weights are worked out
    once for all the channels of a block."""
    if isinstance(values, np.ndarray):
        blocks = [values[None] if values.ndim == 2 else values]
    else:
        blocks = [channel[None] for channel in values]
    depth = octree.depth
    weighted = leaf_weights is not None
    weights = _kernel_weights(leaf_weights) if weighted else np.zeros(0)
    first_child = octree.first_child
    for level in range(depth - 1, -1, -1):
        parents = octree.level_slice(level)
        children = octree.level_slice(level + 1)
        starts = first_child[parents] - int(octree.level_offsets[level + 1])
        parent_weights = np.empty(len(starts) if weighted else 0, np.float64)
        for block in blocks:
            average_children(starts, block[:, children], weights, weighted, block[:, parents],
                             parent_weights)
        weights = parent_weights


def _kernel_weights(weights: np.ndarray) -> np.ndarray:
    """Leaf weights as the level kernel reads them: float32 as they are (it widens each one
    exactly), anything else as float64."""
    if weights.dtype == np.float32:
        return np.ascontiguousarray(weights)
    return np.ascontiguousarray(weights, np.float64)


def new_channel_block(octree: Octree, count: int) -> np.ndarray:
    """Room for ``count`` channels, ``(count, nodes, 3)`` float32: fill the voxel rows
    (``block[:, octree.level_slice(octree.depth)]``) and pass it to ``with_channel_block``."""
    return np.empty((count, octree.node_count, 3), np.float32)


def with_channels(
    octree: Octree, channels: dict[str, np.ndarray], *, weights: np.ndarray | None = None
) -> Octree:
    """A new octree sharing ``octree``'s structure, with each ``name -> (voxels, 3)`` leaf
    array added as a channel (replacing a channel of that name, never the albedo).

    ``weights`` (one non-negative number per voxel) weights the parent averages of every
    added channel (see ``propagate_channel``); by default a parent is the plain mean.
    Leaf values are in leaf order: row ``i`` belongs to node ``level_offsets[depth] + i``.
    """
    leaf_weights = None
    if weights is not None:
        leaf_weights = _leaf_array(octree, weights, "channel weights", None)
        if np.any(leaf_weights < 0):
            raise VoxfieldError("channel weights must not be negative")
    names = list(channels)
    for name in names:
        check_channel_name(name)
    if not names:
        return octree.recoloured(attributes=dict(octree.attributes))
    block = new_channel_block(octree, len(names))
    leaves = octree.level_slice(octree.depth)
    for k, name in enumerate(names):
        block[k, leaves] = _leaf_array(octree, channels[name], f"channel {name!r}", 3)
    return with_channel_block(octree, names, block, leaf_weights)


def with_channel_block(
    octree: Octree, names: list[str], block: np.ndarray, weights: np.ndarray | None,
    storage: str = FLOAT32,
) -> Octree:
    """``with_channels`` for channels whose leaf values are already checked and in place:
    ``block`` from ``new_channel_block`` with its voxel rows set, channel ``k`` in
    ``block[k]``. Its inner rows are filled in place, from the float32 leaves, and the
    octree keeps ``block[k]`` (views of one array: no channel is copied), or each channel
    packed as ``storage`` (``kernels.colour.HDR_STORAGES``)."""
    check_channel_storage(storage)
    attributes = dict(octree.attributes)
    fill_inner_levels(octree, block, weights)
    for name, values in zip(names, block, strict=True):
        attributes[check_channel_name(name)] = encode_channel(values, storage)
    return octree.recoloured(attributes=attributes)


def with_channel(
    octree: Octree, name: str, leaf_values: np.ndarray, *, weights: np.ndarray | None = None
) -> Octree:
    """A new octree with one more channel; see ``with_channels``."""
    return with_channels(octree, {name: leaf_values}, weights=weights)
