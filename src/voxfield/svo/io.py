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
            header = _read_header(data, path)
            if header.get("format") != FORMAT:
                raise OctreeFormatError(f"{path}: not a voxfield octree file")
            version = header.get("version")
            if version not in (1, FORMAT_VERSION):
                raise OctreeFormatError(
                    f"{path}: octree format version {version} is not supported "
                    f"(expected {FORMAT_VERSION}); rebuild it with `voxfield build`"
                )
            attributes = {name: _array(data, f"attr_{name}", path)
                          for name in _attribute_names(header, path)}
            depth = _header_depth(header, path)
            offsets = _array(data, "level_offsets", path)
            if version == 1:
                descriptors, box = _from_version_1(data, offsets, str(path))
            else:
                descriptors = _array(data, "descriptors", path)
                box = _array(data, "voxel_box", path)
            octree = Octree(
                depth=depth,
                descriptors=descriptors,
                level_offsets=offsets,
                attributes=attributes,
                voxel_box=box,
                scene_origin=_array(data, "scene_origin", path),
                name=str(header.get("name", path.stem)),
                facing=_array(data, "facing", path) if header.get("facing") else None,
            )
    except OctreeFormatError:
        raise
    except VoxfieldError as exc:  # arrays that disagree in shape or type
        raise OctreeFormatError(f"{path}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - zip/zlib/json fail in many ways on a bad file
        raise OctreeFormatError(f"{path}: unreadable or corrupt octree file ({exc})") from exc
    validate_octree(octree, str(path))
    return octree


#: What a JSON value is, in words, for a header of the wrong kind.
_JSON_KINDS = {list: "a list", str: "a string", bool: "true or false", int: "a number",
               float: "a number", type(None): "null"}


def _read_header(data, where) -> dict:
    """The file's JSON header, refused unless it is an object: a list or a number failed
    on its first ``.get`` with Python's words ("'list' object has no attribute 'get')."""
    header = json.loads(bytes(_array(data, "header", where)).decode())
    if not isinstance(header, dict):
        kind = _JSON_KINDS.get(type(header), type(header).__name__)
        raise OctreeFormatError(f"{where}: the header is {kind}, not an object")
    return header


def _array(data, name: str, where) -> np.ndarray:
    """Array ``name`` of the archive, refused by name where the file lacks it (NumPy's own
    words were "attr_c is not a file in the archive")."""
    if name not in data.files:
        raise OctreeFormatError(f"{where}: the file has no {name!r} array")
    return data[name]


def _attribute_names(header: dict, where) -> list[str]:
    """The header's channel names, refused unless a list of strings: a bare string
    (``"attributes": "color"``) was read letter by letter, as channels 'c', 'o', ..."""
    names = header.get("attributes")
    if not isinstance(names, list) or not all(isinstance(name, str) for name in names):
        raise OctreeFormatError(f"{where}: the header's attributes must be a list of names, "
                                f"got {json.dumps(names)[:60]}")
    return names


def _header_depth(header: dict, where) -> int:
    """The header's depth, refused unless a whole number: ``int()`` took 6.7 as 6 without a
    word (and a string failed with Python's words); ``true`` is no depth either."""
    depth = header.get("depth")
    if (isinstance(depth, bool) or not isinstance(depth, (int, float))
            or not float(depth).is_integer()):
        raise OctreeFormatError(f"{where}: the header's depth must be a whole number, "
                                f"got {json.dumps(depth)[:60]}")
    return int(depth)


def _from_version_1(data, offsets: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Descriptors and voxel box from a version-1 file's per-node arrays."""
    inner = int(offsets[-2])
    masks = np.asarray(_array(data, "child_mask", where))
    first = np.asarray(_array(data, "first_child", where))
    coords = np.asarray(_array(data, "node_coord", where))
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
        problem = colour_range_problem(name, values)
        if problem is not None:
            raise OctreeFormatError(f"{where}: attribute {name!r} {problem}")
    _check_one_root(octree, where)
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


#: Rounding slack on a channel's range: a parent's colour is a float32 mean of its children's.
COLOUR_SLACK = 1e-5


def colour_range_problem(name: str, values: np.ndarray) -> str | None:
    """What is wrong with the values of channel ``name`` (the words after its name), or None.
    Only float32 channels can be out of range (8-bit sRGB and RGB9E5 codes decode into it):
    they must be finite; the albedo (``color``) must lie in [0, 1], as a scene's must
    (``scene.voxel_scene``), and light and emission (lit channels, a user's channels) may
    exceed 1 but are never negative. A file's -5 rendered black, 1e30 white, and NaN
    poisoned every mean; min and max are two passes, no temporary array."""
    if values.dtype != np.float32 or values.size == 0:
        return None
    low, high = float(values.min()), float(values.max())  # NaN and ±inf carry into these
    if not (np.isfinite(low) and np.isfinite(high)):
        return "holds NaN or infinity"
    if name == "color":
        if low < -COLOUR_SLACK or high > 1.0 + COLOUR_SLACK:
            return f"holds {low:g}..{high:g}; the albedo is linear in [0, 1]"
    elif low < -COLOUR_SLACK:
        return f"holds {low:g}; light and emission are never negative"
    return None


def _check_one_root(octree: Octree, where: str) -> None:
    """Level 0 must hold exactly one node: traversal starts at node 0 only, so a second
    root's voxels were counted by ``voxfield info`` and never rendered. (No octree is empty:
    a scene without voxels is refused before it is built.) The node count of every lower
    level is checked against its parents' child masks in ``validate_octree``."""
    roots = int(octree.level_offsets[1] - octree.level_offsets[0])
    if roots != 1:
        raise OctreeFormatError(f"{where}: level 0 holds {roots:,} nodes; an octree has "
                                "one root")
