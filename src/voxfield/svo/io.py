"""Octree files: one ``.npz`` holding the flat arrays and a JSON header, written atomically."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.atomic import atomic_path, named_for
from voxfield.errors import OctreeFormatError, VoxfieldError
from voxfield.kernels.node_descriptor import FIRST_CHILD_SHIFT, SOLID_BIT, pack_descriptors
from voxfield.svo.octree import (
    CHILD_COUNT,
    Octree,
    check_octree,
    solid_flags,
)

FORMAT = "voxfield-octree"
#: 2: packed descriptors and the voxel box; node positions and per-node masks are derived.
#: Version 1 files (masks, first children and positions per node) still load.
FORMAT_VERSION = 2


def save_octree(octree: Octree, path: str | os.PathLike) -> Path:
    """Write the octree to ``path`` (temporary file, then rename)."""
    check_octree(octree, "save_octree")
    path = named_for(path, ".npz", "save_octree")
    with atomic_path(path) as tmp:
        write_octree_file(octree, tmp)
    return path


def write_octree_file(octree: Octree, path: str | os.PathLike) -> None:
    """``save_octree``'s bytes, straight into ``path``: for a writer that commits the file
    itself (``atomic_path``) once the rest of its outputs are ready."""
    header = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "depth": octree.depth,
        "name": octree.name,  # no build time: the same octree writes the same bytes
        "attributes": sorted(octree.attributes),
        "facing": octree.facing is not None,
    }
    arrays = {
        "header": np.frombuffer(json.dumps(header).encode(), dtype=np.uint8),
        "descriptors": octree.descriptors,
        "level_offsets": octree.level_offsets,
        "voxel_box": octree.voxel_box,
        "scene_origin": octree.scene_origin,
    }
    for name, values in octree.attributes.items():
        arrays[f"attr_{name}"] = values
    if octree.facing is not None:
        arrays["facing"] = octree.facing
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def load_octree(path: str | os.PathLike) -> Octree:
    """Read and validate an octree written by ``save_octree``."""
    path = Path(path)
    if path.is_dir():
        raise OctreeFormatError(f"{path}: a folder, not an octree file")
    if not path.is_file():
        raise OctreeFormatError(f"{path}: no such octree file")
    try:
        with load_arrays(path) as data:
            header = json.loads(bytes(data["header"]).decode())
            if header.get("format") != FORMAT:
                raise OctreeFormatError(f"{path}: not a voxfield octree file")
            version = header.get("version")
            if version not in (1, FORMAT_VERSION):
                raise OctreeFormatError(
                    f"{path}: octree format version {version} is not supported "
                    f"(expected {FORMAT_VERSION}); rebuild it with `voxfield build`"
                )
            attributes = {name: data[f"attr_{name}"] for name in header["attributes"]}
            depth = int(header["depth"])
            offsets = data["level_offsets"]
            if version == 1:
                descriptors, box = _from_version_1(data, offsets, str(path))
            else:
                descriptors, box = data["descriptors"], data["voxel_box"]
            octree = Octree(
                depth=depth,
                descriptors=descriptors,
                level_offsets=offsets,
                attributes=attributes,
                voxel_box=box,
                scene_origin=data["scene_origin"],
                name=str(header.get("name", path.stem)),
                facing=data["facing"] if header.get("facing") else None,
            )
    except OctreeFormatError:
        raise
    except VoxfieldError as exc:  # arrays that disagree in shape or type
        raise OctreeFormatError(f"{path}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - zip/zlib/json fail in many ways on a bad file
        raise OctreeFormatError(f"{path}: unreadable or corrupt octree file ({exc})") from exc
    validate_octree(octree, str(path))
    return octree


def _from_version_1(data, offsets: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Descriptors and voxel box from a version-1 file's per-node arrays."""
    inner = int(offsets[-2])
    masks = np.asarray(data["child_mask"])
    first = np.asarray(data["first_child"])
    coords = np.asarray(data["node_coord"])
    if masks.ndim != 1 or first.shape != masks.shape or len(masks) < inner or coords.ndim != 2:
        raise OctreeFormatError(f"{where}: node arrays disagree in length")
    leaves = coords[inner:].astype(np.int64)
    box = np.array([leaves.min(axis=0), leaves.max(axis=0) + 1]) if len(leaves) else np.zeros(
        (2, 3), np.int64)
    solid = solid_flags(masks[:inner], first[:inner], offsets)
    return pack_descriptors(masks[:inner], first[:inner], solid), box


def validate_octree(octree: Octree, where: str = "octree") -> None:
    """Check the structural invariants a kernel relies on; raise rather than crash later.
    (The arrays' shapes and types were checked as the ``Octree`` was made.)"""
    off = octree.level_offsets
    n = octree.node_count
    box = octree.voxel_box
    for name, values in octree.attributes.items():
        if values.dtype == np.float32 and not np.all(np.isfinite(values)):
            raise OctreeFormatError(f"{where}: attribute {name!r} holds NaN or infinity")
    masks = octree.descriptors & 0xFF
    if np.any(masks == 0):
        raise OctreeFormatError(f"{where}: inner node without children")
    counts = CHILD_COUNT[masks]
    first = octree.descriptors >> FIRST_CHILD_SHIFT
    if np.any(first < 0) or np.any(first + counts > n):
        raise OctreeFormatError(f"{where}: child pointers run past the node arrays")
    for level in range(octree.depth):
        sl = octree.level_slice(level)
        expected = off[level + 1] + np.concatenate(([0], np.cumsum(counts[sl])[:-1]))
        if not np.array_equal(first[sl], expected):
            raise OctreeFormatError(f"{where}: child pointers of level {level} are not contiguous")
        if off[level + 2] - off[level + 1] != counts[sl].sum():
            raise OctreeFormatError(f"{where}: level {level + 1} holds the wrong number of nodes")
    if not np.array_equal((octree.descriptors & SOLID_BIT) != 0, octree.derived_solid_flags()):
        raise OctreeFormatError(f"{where}: solid flags disagree with the child masks")
    occupied = octree.occupied_box()
    if np.any(occupied[0] < box[0]) or np.any(occupied[1] > box[1]):
        raise OctreeFormatError(
            f"{where}: the voxel box {box[0].tolist()}..{box[1].tolist()} leaves out voxels "
            f"(they span {occupied[0].tolist()}..{occupied[1].tolist()})")
