"""glTF and GLB files made ready for trimesh: what it would read wrongly without a word is
refused or folded in first.

- Geometry compression trimesh cannot decode (``KHR_draco_mesh_compression`` without DracoPy,
  ``EXT_meshopt_compression``) leaves placeholder zeros where the vertices should be: a file
  that requires it is refused in one line.
- ``KHR_materials_emissive_strength`` (Blender writes it for every emission above 1) scales
  ``emissiveFactor``; trimesh drops it, so it is multiplied in here.
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
