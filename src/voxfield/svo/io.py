"""Octree files: one ``.npz`` holding the flat arrays and a JSON header, written atomically."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from voxfield.atomic import atomic_path
from voxfield.errors import OctreeFormatError
from voxfield.svo.octree import Octree

FORMAT = "voxfield-octree"
FORMAT_VERSION = 1


def save_octree(octree: Octree, path: str | os.PathLike) -> Path:
    """Write the octree to ``path`` (temporary file, then rename)."""
    path = Path(path)
    header = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "depth": octree.depth,
        "name": octree.name,
        "build_seconds": octree.build_seconds,
        "attributes": sorted(octree.attributes),
    }
    arrays = {
        "header": np.frombuffer(json.dumps(header).encode(), dtype=np.uint8),
        "child_mask": octree.child_mask,
        "first_child": octree.first_child,
        "node_coord": octree.node_coord,
        "level_offsets": octree.level_offsets,
        "scene_origin": octree.scene_origin,
    }
    for name, values in octree.attributes.items():
        arrays[f"attr_{name}"] = values
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)
    return path


def load_octree(path: str | os.PathLike) -> Octree:
    """Read and validate an octree written by ``save_octree``."""
    path = Path(path)
    if not path.is_file():
        raise OctreeFormatError(f"{path}: no such octree file")
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(bytes(data["header"]).decode())
            if header.get("format") != FORMAT:
                raise OctreeFormatError(f"{path}: not a voxfield octree file")
            if header.get("version") != FORMAT_VERSION:
                raise OctreeFormatError(
                    f"{path}: octree format version {header.get('version')} is not supported "
                    f"(expected {FORMAT_VERSION}); rebuild it with `voxfield build`"
                )
            attributes = {name: data[f"attr_{name}"] for name in header["attributes"]}
            octree = Octree(
                depth=int(header["depth"]),
                child_mask=data["child_mask"],
                first_child=data["first_child"],
                node_coord=data["node_coord"],
                level_offsets=data["level_offsets"],
                attributes=attributes,
                scene_origin=data["scene_origin"],
                build_seconds=float(header.get("build_seconds", 0.0)),
                name=str(header.get("name", path.stem)),
            )
    except OctreeFormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - zip/zlib/json fail in many ways on a bad file
        raise OctreeFormatError(f"{path}: unreadable or corrupt octree file ({exc})") from exc
    validate_octree(octree, str(path))
    return octree


def validate_octree(octree: Octree, where: str = "octree") -> None:
    """Check the structural invariants a kernel relies on; raise rather than crash later."""
    n = octree.node_count
    off = octree.level_offsets
    if octree.depth < 1 or octree.depth > 21 or len(off) != octree.depth + 2 or off[0] != 0:
        raise OctreeFormatError(f"{where}: inconsistent depth or level offsets")
    if np.any(np.diff(off) <= 0):
        raise OctreeFormatError(f"{where}: a level has no nodes")
    if octree.child_mask.shape != (n,) or octree.first_child.shape != (n,):
        raise OctreeFormatError(f"{where}: node arrays disagree in length")
    if octree.node_coord.shape != (n, 3):
        raise OctreeFormatError(f"{where}: node coordinates have the wrong shape")
    for name, values in octree.attributes.items():
        if values.shape != (n, 3):
            raise OctreeFormatError(f"{where}: attribute {name!r} has the wrong shape")
    inner = slice(0, int(off[-2]))
    masks = octree.child_mask[inner]
    if np.any(masks == 0) or np.any(octree.child_mask[int(off[-2]) :] != 0):
        raise OctreeFormatError(f"{where}: inner node without children or leaf with children")
    counts = np.unpackbits(masks[:, None], axis=1).sum(axis=1)
    first = octree.first_child[inner].astype(np.int64)
    if np.any(first + counts > n):
        raise OctreeFormatError(f"{where}: child pointers run past the node arrays")
    for level in range(octree.depth):
        sl = octree.level_slice(level)
        expected = off[level + 1] + np.concatenate(([0], np.cumsum(counts[sl])[:-1]))
        if not np.array_equal(first[sl], expected):
            raise OctreeFormatError(f"{where}: child pointers of level {level} are not contiguous")


def open_octree(spec: str, options=None, *, progress: bool = False,
                lod_colour: str = "mean") -> Octree:
    """An octree from a saved octree file, or built from any scene description (inner-node
    colours by ``lod_colour``, see ``build.LOD_COLOURS``; a saved octree keeps its own)."""
    from voxfield.scene.loaders import load_scene, npz_kind
    from voxfield.svo.build import build_octree

    path = Path(spec)
    if path.suffix.lower() == ".npz" and path.is_file() and npz_kind(path) == "octree":
        return load_octree(path)
    return build_octree(load_scene(spec, options), progress=progress,
                        lod_colour=lod_colour)
