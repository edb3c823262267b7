"""glTF and GLB files made ready for trimesh: what it would read wrongly without a word is
refused or folded in first.

- Geometry compression trimesh cannot decode (``KHR_draco_mesh_compression`` without DracoPy,
  ``EXT_meshopt_compression``) leaves placeholder zeros where the vertices should be: a file
  that requires it is refused in one line.
- ``KHR_materials_emissive_strength`` (Blender writes it for every emission above 1) scales
  ``emissiveFactor``; trimesh drops it, so it is multiplied in here.
- An index that names no accessor, buffer view or buffer, and an accessor of a type glTF
  does not define, are refused by name: trimesh failed on them with its own internals
  (``UnboundLocalError: ... 'access'``, ``IndexError``, ``KeyError: 1``).
"""

from __future__ import annotations

import importlib.util
import json
import struct
from pathlib import Path

from voxfield.errors import SceneFormatError

#: Geometry compression extensions and whether trimesh decodes them here.
_COMPRESSION = {
    "KHR_draco_mesh_compression": lambda: importlib.util.find_spec("DracoPy") is not None,
    "EXT_meshopt_compression": lambda: False,
}
_GLB_MAGIC, _GLB_JSON, _GLB_HEADER = b"glTF", 0x4E4F534A, struct.Struct("<4sII")


def prepared_gltf(path: Path) -> bytes:
    """The file's bytes with its JSON checked and emission strengths folded in (unchanged
    when there is nothing to fold)."""
    data = path.read_bytes()
    binary = path.suffix.lower() == ".glb"
    text, rest = _glb_json(data, path) if binary else (data, b"")
    try:
        tree = json.loads(text.decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise SceneFormatError(f"{path}: not valid glTF (its JSON does not parse: "
                               f"{exc})") from exc
    if not isinstance(tree, dict):
        raise SceneFormatError(f"{path}: not valid glTF (its JSON is not an object)")
    _check_required(tree, path)
    _check_references(tree, path)
    if not _fold_emissive_strength(tree):
        return data
    text = json.dumps(tree).encode("utf-8")
    return _glb(text, rest) if binary else text


def _check_required(tree: dict, path: Path) -> None:
    required = tree.get("extensionsRequired") or []
    for name in required if isinstance(required, list) else []:
        if name in _COMPRESSION and not _COMPRESSION[name]():
            raise SceneFormatError(
                f"{path}: its meshes are compressed with {name}, which cannot be decoded "
                "here; export it again without mesh compression")


#: glTF's accessor component types and element types (glTF 2.0, §5.1).
_COMPONENT_TYPES = {5120, 5121, 5122, 5123, 5125, 5126}
_ELEMENT_TYPES = {"SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"}


def _items(tree: dict, key: str) -> list:
    items = tree.get(key)
    return items if isinstance(items, list) else []


def _check_index(index, tree: dict, key: str, what: str, path: Path) -> None:
    """``index`` must name one of ``tree[key]``: said in plain words where it does not."""
    count = len(_items(tree, key))
    if isinstance(index, int) and not isinstance(index, bool) and 0 <= index < count:
        return
    singular = {"accessors": "accessor", "bufferViews": "buffer view", "buffers": "buffer"}[key]
    holds = f"has {count} {singular}{'s' if count > 1 else ''} (numbered from 0)" if count \
        else f"has no {singular}s"
    raise SceneFormatError(f"{path}: damaged glTF: {what} names {singular} {index!r}, but the "
                           f"file {holds}")


def _check_references(tree: dict, path: Path) -> None:
    """The accessors the meshes read, and the buffer views and buffers those read, exist and
    are of types glTF defines."""
    for m, mesh in enumerate(_items(tree, "meshes")):
        primitives = mesh.get("primitives") if isinstance(mesh, dict) else None
        for k, primitive in enumerate(primitives if isinstance(primitives, list) else []):
            if not isinstance(primitive, dict):
                continue
            attributes = primitive.get("attributes")
            attributes = attributes if isinstance(attributes, dict) else {}
            if "POSITION" not in attributes:
                raise SceneFormatError(f"{path}: mesh {m} primitive {k} has no vertex "
                                       "positions (no POSITION attribute)")
            for name, index in attributes.items():
                _check_index(index, tree, "accessors", f"mesh {m} primitive {k}'s {name}",
                             path)
            if "indices" in primitive:
                _check_index(primitive["indices"], tree, "accessors",
                             f"mesh {m} primitive {k}'s indices", path)
    for a, accessor in enumerate(_items(tree, "accessors")):
        if not isinstance(accessor, dict):
            continue
        if accessor.get("componentType") not in _COMPONENT_TYPES:
            raise SceneFormatError(f"{path}: damaged glTF: accessor {a} has component type "
                                   f"{accessor.get('componentType')!r}, which glTF does not "
                                   "define")
        if accessor.get("type") not in _ELEMENT_TYPES:
            raise SceneFormatError(f"{path}: damaged glTF: accessor {a} has type "
                                   f"{accessor.get('type')!r}, which glTF does not define")
        if "bufferView" in accessor:
            _check_index(accessor["bufferView"], tree, "bufferViews", f"accessor {a}", path)
    for v, view in enumerate(_items(tree, "bufferViews")):
        if isinstance(view, dict):
            _check_index(view.get("buffer"), tree, "buffers", f"buffer view {v}", path)


def _fold_emissive_strength(tree: dict) -> bool:
    """``emissiveFactor × emissiveStrength`` for every material that has both; whether any
    changed."""
    changed = False
    for material in tree.get("materials") or []:
        if not isinstance(material, dict):
            continue
        extension = (material.get("extensions") or {}).get("KHR_materials_emissive_strength")
        strength = extension.get("emissiveStrength") if isinstance(extension, dict) else None
        factor = material.get("emissiveFactor")
        if (isinstance(strength, (int, float)) and not isinstance(strength, bool)
                and strength >= 0 and strength != 1 and isinstance(factor, list)
                and all(isinstance(v, (int, float)) for v in factor)):
            material["emissiveFactor"] = [v * strength for v in factor]
            changed = True
    return changed


def _glb_json(data: bytes, path: Path) -> tuple[bytes, bytes]:
    """A GLB's JSON chunk and the chunks after it."""
    if len(data) < 20:
        raise SceneFormatError(f"{path}: not a GLB file (only {len(data)} bytes)")
    magic, _version, _length = _GLB_HEADER.unpack_from(data)
    length, kind = struct.unpack_from("<II", data, 12)
    if magic != _GLB_MAGIC or kind != _GLB_JSON or 20 + length > len(data):
        raise SceneFormatError(f"{path}: not a GLB file (no JSON chunk where GLB keeps it)")
    return data[20 : 20 + length], data[20 + length :]


def _glb(text: bytes, rest: bytes) -> bytes:
    """A GLB of ``text`` as its JSON chunk (space-padded to 4 bytes) and the chunks after."""
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), _GLB_JSON) + text + rest
    return _GLB_HEADER.pack(_GLB_MAGIC, 2, 12 + len(body)) + body
