"""MagicaVoxel ``.vox`` reader: models, palette, materials and the scene graph, as a VoxelScene.

Written from ephtracy/voxel-model's ``MagicaVoxel-file-format-vox.txt`` and
``MagicaVoxel-file-format-vox-extension.txt`` (versions 150 and 200). Every malformed input
ends in a :class:`~voxfield.errors.SceneFormatError` naming the file and what is wrong, so a
corrupt download never surfaces as an IndexError deep inside NumPy.

Conventions chosen here (the format leaves them open):

* **Axes.** MagicaVoxel is z-up, voxfield is y-up: ``(x, y, z)_mv -> (x, z, -y)``, a proper
  rotation, so handedness and mirroring survive. ``load_vox`` then moves the minimum corner to
  the origin.
* **Placement.** A voxel ``v`` of a model of ``size`` lands at
  ``floor(R · (v + 0.5 - floor(size / 2))) + t`` under the accumulated rotation ``R`` and
  translation ``t``: the pivot lies on the grid between voxels, so an axis the rotation flips
  lands one voxel lower when its size is odd (a centre-voxel pivot would keep it in place).
  This is the rule voxel-io and vengi apply; on ``test-transform.vox``, built mirror-symmetric
  in x with a mirrored 39-voxel-wide model, only it gives a symmetric scene.
* **Emission.** A ``MATL`` of type ``_emit`` or ``_blend`` emits ``linear colour * _emit *
  (1 + _flux)``: ``_emit`` is the 0..1 emission slider, ``_flux`` the integer power step.
  MagicaVoxel's own radiance scale is undocumented, so this is a monotone stand-in. Legacy
  ``MATT`` emissive materials (v150) emit ``linear colour * weight``.
* **No scene graph.** Files without ``nTRN``/``nGRP``/``nSHP`` (plain v150) hold unrelated
  models (T-Rex stores 8 animation frames), so ``load_vox`` takes model 0 unless ``model=``
  names another; overlapping all frames would be nonsense.
"""

from __future__ import annotations

import os
import struct
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from voxfield.errors import DataNotFoundError, SceneFormatError, SceneTooLargeError, VoxfieldError
from voxfield.scene.voxel_scene import MAX_EXTENT, VoxelScene, srgb_to_linear

__all__ = [
    "DEFAULT_PALETTE",
    "MAX_PLACED_VOXELS",
    "VoxFile",
    "VoxModel",
    "VoxNode",
    "decode_rotation",
    "encode_rotation",
    "load_vox",
    "load_vox_models",
    "read_vox",
]

#: Largest model edge MagicaVoxel writes; voxel coordinates are single bytes anyway.
MAX_MODEL_SIZE = 256
#: Cap on voxels placed by the scene graph before overlaps are resolved (memory guard: a
#: shared subgraph can multiply instances exponentially).
MAX_PLACED_VOXELS = 1 << 26
#: Cap on scene-graph node visits, for the same reason (real scenes visit thousands).
MAX_NODE_VISITS = 1 << 18
#: Largest translation component accepted from a file.
_MAX_TRANSLATION = MAX_EXTENT

_I32 = struct.Struct("<i")
_U32 = struct.Struct("<I")
_IDENTITY_ROTATION = 4  # row 0 -> column 0, row 1 -> column 1, all signs positive
_SUPPORTED_VERSIONS = (150, 200)
_EMISSIVE_MATL_TYPES = ("_emit", "_blend")
_MATT_EMISSIVE = 3

Source = str | os.PathLike | bytes


def _default_palette() -> np.ndarray:
    """The palette MagicaVoxel uses when a file has no RGBA chunk, indexed by colour index.

    Built from its pattern: index 0 empty; a 6-level colour cube (R slowest, B fastest, levels
    ff cc 99 66 33 00) without black; then ten-step ramps of red, green, blue and grey.
    """
    pal = np.zeros((256, 4), dtype=np.uint8)
    levels = (255, 204, 153, 102, 51, 0)
    cube = np.array([(r, g, b) for r in levels for g in levels for b in levels], dtype=np.uint8)
    pal[1:216, :3] = cube[:215]
    ramp = np.array([238, 221, 187, 170, 136, 119, 85, 68, 34, 17], dtype=np.uint8)
    for channel in range(3):
        pal[216 + 10 * channel : 226 + 10 * channel, channel] = ramp
    pal[246:256, :3] = ramp[:, None]
    pal[1:, 3] = 255
    pal.setflags(write=False)
    return pal


#: Default palette as RGBA bytes, row ``i`` is the colour of XYZI colour index ``i``.
DEFAULT_PALETTE = _default_palette()


# --------------------------------------------------------------------------------------------
# Rotation byte
# --------------------------------------------------------------------------------------------


def decode_rotation(packed: int) -> np.ndarray:
    """The 3×3 signed permutation matrix a ``_r`` byte encodes (rows act on column vectors).

    Bits 0-1 and 2-3 give the column of the non-zero entry in rows 0 and 1 (row 2 takes the
    remaining column); bits 4, 5, 6 are the signs of rows 0, 1, 2 (set = negative).
    """
    packed = int(packed)
    if not 0 <= packed < 128:
        raise ValueError(f"rotation byte {packed} is outside 0..127")
    c0, c1 = packed & 3, (packed >> 2) & 3
    if c0 > 2 or c1 > 2 or c0 == c1:
        raise ValueError(f"rotation byte {packed} does not encode a permutation")
    cols = (c0, c1, 3 - c0 - c1)
    mat = np.zeros((3, 3), dtype=np.int64)
    for row, col in enumerate(cols):
        mat[row, col] = -1 if packed & (1 << (4 + row)) else 1
    return mat


def encode_rotation(matrix) -> int:
    """The ``_r`` byte for a 3×3 signed permutation matrix (inverse of ``decode_rotation``)."""
    mat = np.asarray(matrix)
    if mat.shape != (3, 3) or not np.isin(mat, (-1, 0, 1)).all():
        raise ValueError("a .vox rotation must be a 3×3 matrix of -1, 0 and 1")
    nonzero = mat != 0
    if not (nonzero.sum(axis=0) == 1).all() or not (nonzero.sum(axis=1) == 1).all():
        raise ValueError("a .vox rotation must be a signed permutation matrix")
    cols = np.argmax(nonzero, axis=1)
    packed = int(cols[0]) | int(cols[1]) << 2
    for row in range(3):
        if mat[row, cols[row]] < 0:
            packed |= 1 << (4 + row)
    return packed


# --------------------------------------------------------------------------------------------
# Parsed file
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class VoxModel:
    """One SIZE/XYZI pair: ``size`` (x, y, z, z-up) and ``voxels`` (N×4 uint8: x, y, z, index).

    ``voxels`` is a read-only view of the file's bytes (no copy of large models), a copy
    where the model lists empty (colour index 0) voxels to drop.
    """

    size: tuple[int, int, int]
    voxels: np.ndarray


@dataclass(frozen=True)
class VoxNode:
    """A scene-graph node: ``kind`` is ``"transform"``, ``"group"`` or ``"shape"``.

    Transforms carry ``rotation``/``translation`` of frame 0 and ``layer``; groups list
    ``children``; shapes hold the model id in ``children[0]`` (none when the node lists none).
    """

    node_id: int
    kind: str
    attributes: Mapping[str, str]
    children: tuple[int, ...]
    rotation: int = _IDENTITY_ROTATION
    translation: tuple[int, int, int] = (0, 0, 0)
    layer: int = -1

    @property
    def hidden(self) -> bool:
        return self.attributes.get("_hidden", "0") == "1"


@dataclass(frozen=True)
class VoxFile:
    """A parsed ``.vox`` file before placement: what the chunks say, checked for consistency.

    ``palette`` is RGBA bytes indexed by XYZI colour index (the RGBA chunk's shift undone);
    ``emission`` is the emitted-radiance multiplier per colour index (0 for non-emissive).
    """

    name: str
    version: int
    models: list[VoxModel]
    palette: np.ndarray
    emission: np.ndarray
    nodes: dict[int, VoxNode] = field(default_factory=dict)
    hidden_layers: frozenset[int] = frozenset()
    orphan_sizes: int = 0


# --------------------------------------------------------------------------------------------
# Byte-level reading
# --------------------------------------------------------------------------------------------


class _Cursor:
    """Bounds-checked little-endian reads within one chunk's content."""

    __slots__ = ("buf", "pos", "end", "where")

    def __init__(self, buf: bytes, pos: int, end: int, where: str) -> None:
        self.buf, self.pos, self.end, self.where = buf, pos, end, where

    def fail(self, what: str) -> SceneFormatError:
        return SceneFormatError(f"{self.where}: {what}")

    def need(self, n: int) -> None:
        if self.pos + n > self.end:
            raise self.fail(
                f"needs {n} more bytes at byte {self.pos} but the chunk ends at byte {self.end}"
            )

    def i32(self) -> int:
        if self.pos + 4 > self.end:
            self.need(4)
        (value,) = _I32.unpack_from(self.buf, self.pos)
        self.pos += 4
        return value

    def u32(self) -> int:
        """A byte count or a length prefix: unsigned, so 0x80000000 reads as 2,147,483,648
        bytes, as its writer meant it, not as a negative number."""
        self.need(4)
        (value,) = _U32.unpack_from(self.buf, self.pos)
        self.pos += 4
        return value

    def f32(self) -> float:
        self.need(4)
        value = float(np.frombuffer(self.buf, dtype="<f4", count=1, offset=self.pos)[0])
        self.pos += 4
        return value

    def count(self, what: str, item_bytes: int) -> int:
        """A length prefix, checked against what is left so a bad one cannot allocate or loop."""
        n = self.u32()
        if n * item_bytes > self.end - self.pos:
            left = self.end - self.pos
            raise self.fail(f"{what} count {n} does not fit in the {left} bytes left")
        return n

    def string(self) -> str:
        n = self.count("string byte", 1)
        text = self.buf[self.pos : self.pos + n].decode("utf-8", errors="replace")
        self.pos += n
        return text

    def dict(self) -> dict[str, str]:
        n = self.count("dictionary entry", 8)
        out = {}
        for _ in range(n):
            key = self.string()
            out[key] = self.string()
        return out


def _read_bytes(source: Source) -> tuple[bytes, str, str]:
    """File contents, the label used in messages, and a scene name."""
    if isinstance(source, bytes | bytearray | memoryview):
        return bytes(source), "<bytes>", "vox"
    path = Path(source)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DataNotFoundError(f"{path}: no such .vox file") from None
    except OSError as exc:
        raise VoxfieldError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    return data, str(path), path.stem


def _parse_int_list(text: str, n: int, what: str, cur: _Cursor) -> tuple[int, ...]:
    parts = text.split()
    try:
        values = tuple(int(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != n:
        raise cur.fail(f"{what} {text!r} is not {n} integer(s)")
    return values


def _parse_float(text: str, what: str, cur: _Cursor) -> float:
    try:
        value = float(text)
    except ValueError:
        raise cur.fail(f"{what} {text!r} is not a number") from None
    if not np.isfinite(value) or not 0.0 <= value <= 1e6:
        raise cur.fail(f"{what} {text!r} is outside 0..1e6")
    return value


def _matl_strength(props: Mapping[str, str], cur: _Cursor) -> float:
    """Emission multiplier of a MATL material (see the module docstring for the formula)."""
    if props.get("_type") not in _EMISSIVE_MATL_TYPES:
        return 0.0
    emit = _parse_float(props.get("_emit", props.get("_weight", "0")), "_emit", cur)
    flux = _parse_float(props.get("_flux", "0"), "_flux", cur)
    return emit * (1.0 + flux)


def _parse(data: bytes, label: str, name: str) -> VoxFile:
    """Walk the chunks once, validating every length and index against the file."""
    if len(data) < 8:
        raise SceneFormatError(f"{label}: only {len(data)} bytes, too short for a .vox header")
    if data[:4] != b"VOX ":
        raise SceneFormatError(
            f"{label}: not a MagicaVoxel file (starts with {data[:4]!r}, expected b'VOX ')"
        )
    version = int.from_bytes(data[4:8], "little", signed=True)
    if version not in _SUPPORTED_VERSIONS:
        raise SceneFormatError(
            f"{label}: .vox version {version} is not supported (expected 150 or 200)"
        )
    head = _Cursor(data, 8, len(data), f"{label}: MAIN chunk")
    head.need(12)
    if data[8:12] != b"MAIN":
        raise head.fail(f"the first chunk is {data[8:12]!r}, expected b'MAIN'")
    head.pos = 12
    main_content, main_children = head.u32(), head.u32()
    start = 20 + main_content
    end = start + main_children
    if end > len(data):
        raise head.fail(
            f"claims {main_content:,} + {main_children:,} bytes (content + children) but the "
            f"file has {len(data) - 20:,} after its header (cut short or damaged)"
        )

    models: list[VoxModel] = []
    pending_size: tuple[int, int, int] | None = None
    orphan_sizes = 0
    rgba: np.ndarray | None = None
    strength = np.zeros(256, dtype=np.float32)
    matl_seen = np.zeros(256, dtype=bool)
    nodes: dict[int, VoxNode] = {}
    hidden_layers: set[int] = set()

    pos = start
    while pos < end:
        where = f"{label}: chunk at byte {pos}"
        if pos + 12 > end:
            raise SceneFormatError(f"{where}: chunk header runs past the end of MAIN at {end}")
        chunk_id = data[pos : pos + 4]
        # Sizes are unsigned: a size of 0x80000000 read as signed was "-2147483648 bytes".
        n_content = int.from_bytes(data[pos + 4 : pos + 8], "little")
        n_children = int.from_bytes(data[pos + 8 : pos + 12], "little")
        c_start = pos + 12
        c_end = c_start + n_content
        if c_end + n_children > end:
            raise SceneFormatError(
                f"{where}: {chunk_id!r} claims {n_content:,} + {n_children:,} bytes (content + "
                f"children), past the end of MAIN at byte {end:,} (cut short or damaged)"
            )
        tag = chunk_id.decode("latin-1")
        cur = _Cursor(data, c_start, c_end, f"{label}: {tag} chunk at byte {pos}")
        pos = c_end + n_children

        if chunk_id == b"SIZE":
            size = (cur.i32(), cur.i32(), cur.i32())
            if not all(0 <= s <= MAX_MODEL_SIZE for s in size):
                raise cur.fail(f"model size {size} is outside 0..{MAX_MODEL_SIZE} per axis")
            if pending_size is not None:
                orphan_sizes += 1
            pending_size = size
        elif chunk_id == b"XYZI":
            if pending_size is None:
                raise cur.fail("XYZI chunk without a SIZE chunk before it")
            n = cur.count("voxel", 4)
            voxels = np.frombuffer(data, dtype=np.uint8, count=4 * n, offset=cur.pos).reshape(n, 4)
            if n and voxels[:, 3].min() == 0:  # colour index 0 is no voxel (as ogt_vox reads it)
                voxels = voxels[voxels[:, 3] != 0]
                n = len(voxels)
            if n:
                # Per-column reductions: an axis-0 reduction over N×3 is several times slower.
                top = [int(voxels[:, k].max()) for k in range(3)]
                if any(t >= s for t, s in zip(top, pending_size, strict=True)):
                    bad = voxels[(voxels[:, :3] >= np.asarray(pending_size)).any(axis=1)][0]
                    raise cur.fail(
                        f"voxel {tuple(int(v) for v in bad[:3])} of model {len(models)} lies "
                        f"outside its SIZE {pending_size}"
                    )
            models.append(VoxModel(pending_size, voxels))
            pending_size = None
        elif chunk_id == b"RGBA":
            # Entry k is colour index k + 1; index 0 (empty) takes the unused entry 255. Some
            # writers store only 255 entries (teardown.vox): the rest keep the default colours.
            n = min((c_end - c_start) // 4, 256)
            raw = DEFAULT_PALETTE[np.r_[1:256, 0]].copy()
            raw[:n] = np.frombuffer(data, dtype=np.uint8, count=4 * n, offset=cur.pos).reshape(n, 4)
            rgba = np.roll(raw, 1, axis=0)
        elif chunk_id == b"MATL":
            mat_id = cur.i32()
            props = cur.dict()
            if 0 <= mat_id < 256:  # some writers number 1..256; 256 is no colour index
                strength[mat_id] = _matl_strength(props, cur)
                matl_seen[mat_id] = True
        elif chunk_id == b"MATT":
            mat_id, mat_type, weight = cur.i32(), cur.i32(), cur.f32()
            if mat_type == _MATT_EMISSIVE and 0 <= mat_id < 256 and not matl_seen[mat_id]:
                if not (np.isfinite(weight) and 0.0 <= weight <= 1e6):
                    raise cur.fail(f"emissive material {mat_id} has weight {weight}")
                strength[mat_id] = weight
        elif chunk_id in (b"nTRN", b"nGRP", b"nSHP"):
            node = _parse_node(chunk_id, cur)
            if node.node_id in nodes:
                raise cur.fail(f"node id {node.node_id} is defined twice")
            nodes[node.node_id] = node
        elif chunk_id == b"LAYR":
            layer_id = cur.i32()
            if cur.dict().get("_hidden", "0") == "1":
                hidden_layers.add(layer_id)
        # PACK (model count: the SIZE/XYZI pairs are authoritative), IMAP, NOTE, rOBJ, rCAM,
        # META, TDCZ and any future chunk: skipped by their declared sizes.

    if pending_size is not None:
        orphan_sizes += 1
    palette = DEFAULT_PALETTE.copy() if rgba is None else rgba.copy()
    return VoxFile(
        name=name,
        version=version,
        models=models,
        palette=palette,
        emission=strength,
        nodes=nodes,
        hidden_layers=frozenset(hidden_layers),
        orphan_sizes=orphan_sizes,
    )


def _parse_node(chunk_id: bytes, cur: _Cursor) -> VoxNode:
    node_id = cur.i32()
    attrs = cur.dict()
    if node_id < 0:
        raise cur.fail(f"node id {node_id} is negative")
    if chunk_id == b"nTRN":
        child, _reserved, layer = cur.i32(), cur.i32(), cur.i32()
        n_frames = cur.count("frame", 4)
        frames = [cur.dict() for _ in range(n_frames)]
        frame = frames[_first_key(frames, cur)] if frames else {}
        rotation = _IDENTITY_ROTATION
        if "_r" in frame:
            (rotation,) = _parse_int_list(frame["_r"], 1, "rotation _r", cur)
            try:
                decode_rotation(rotation)
            except ValueError as exc:
                raise cur.fail(f"node {node_id}: {exc}") from None
        translation = (0, 0, 0)
        if "_t" in frame:
            translation = _parse_int_list(frame["_t"], 3, "translation _t", cur)
            if any(abs(t) > _MAX_TRANSLATION for t in translation):
                raise cur.fail(f"node {node_id}: translation {translation} is absurdly large")
        return VoxNode(node_id, "transform", attrs, (child,), rotation, translation, layer)
    if chunk_id == b"nGRP":
        n = cur.count("group child", 4)
        children = tuple(cur.i32() for _ in range(n))
        return VoxNode(node_id, "group", attrs, children)
    n = cur.count("shape model", 8)
    model_ids, keys = [], []
    for _ in range(n):
        model_ids.append(cur.i32())
        keys.append(cur.dict())
    # Animated shapes list one model per keyframe: the scene shows frame 0's.
    first = model_ids[_first_key(keys, cur)] if model_ids else None
    return VoxNode(node_id, "shape", attrs, () if first is None else (first,))


def _first_key(keys: list[dict], cur: _Cursor) -> int:
    """Which of a node's animation keys holds frame 0: the lowest ``_f`` (absent: 0), the
    first listed among equals. MagicaVoxel writes them in order; other tools need not."""
    frames = [_parse_int_list(key["_f"], 1, "frame _f", cur)[0] if "_f" in key else 0
              for key in keys]
    return frames.index(min(frames))


# --------------------------------------------------------------------------------------------
# Scene graph and placement
# --------------------------------------------------------------------------------------------


def _instances(vf: VoxFile, label: str) -> tuple[list[tuple[int, np.ndarray, np.ndarray]], list]:
    """(model id, rotation, translation) per visible shape, in graph order, and missing ids.

    Iterative depth-first walk from node 0 (no recursion limit to hit); a node met again while
    it is still on the current path is a cycle, while a node shared by several parents
    (instancing, as in test-transform.vox) is legal. An exit marker on the stack takes a node
    off the path, so the check costs O(1) however deep the graph.
    """
    nodes = vf.nodes
    if 0 not in nodes:
        raise SceneFormatError(f"{label}: the scene graph has no root node 0")
    placed: list[tuple[int, np.ndarray, np.ndarray]] = []
    missing: list[int] = []
    on_path: set[int] = set()
    visits = 0
    placed_voxels = 0
    exit_marker = None
    stack: list = [(0, np.eye(3, dtype=np.int64), np.zeros(3, dtype=np.int64), -1)]
    while stack:
        node_id, rot, trans, parent = stack.pop()
        if rot is exit_marker:
            on_path.discard(node_id)
            continue
        node = nodes.get(node_id)
        if node is None:
            raise SceneFormatError(f"{label}: node {parent} refers to missing node {node_id}")
        if node_id in on_path:
            raise SceneFormatError(f"{label}: the scene graph has a cycle through node {node_id}")
        visits += 1
        if visits > MAX_NODE_VISITS:
            raise SceneTooLargeError(
                f"{label}: the scene graph expands to more than {MAX_NODE_VISITS} node visits"
            )
        if node.hidden:
            continue
        if node.kind == "transform":
            if node.layer in vf.hidden_layers:
                continue
            trans = trans + rot @ np.asarray(node.translation, dtype=np.int64)
            rot = rot @ decode_rotation(node.rotation)
            on_path.add(node_id)
            stack.append((node_id, exit_marker, None, -1))
            stack.append((node.children[0], rot, trans, node_id))
        elif node.kind == "group":
            on_path.add(node_id)
            stack.append((node_id, exit_marker, None, -1))
            for child in reversed(node.children):
                stack.append((child, rot, trans, node_id))
        elif node.children:
            model_id = node.children[0]
            if not 0 <= model_id < len(vf.models):
                missing.append(model_id)
                continue
            placed_voxels += len(vf.models[model_id].voxels)
            if placed_voxels > MAX_PLACED_VOXELS:
                raise SceneTooLargeError(
                    f"{label}: the scene graph places more than {MAX_PLACED_VOXELS} voxels"
                )
            placed.append((model_id, rot, trans))
    return placed, missing


def _place(model: VoxModel, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """Model voxels in MagicaVoxel world coordinates (z-up) under one accumulated transform."""
    size = np.asarray(model.size, dtype=np.int64)
    local = model.voxels[:, :3].astype(np.int64)
    cols = np.argmax(rot != 0, axis=1)
    signs = rot[np.arange(3), cols]
    rotated = local[:, cols] * signs
    half = size[cols] // 2
    # floor(±(v + 0.5 - half)) is v - half, or -v + half - 1 on a flipped axis
    return rotated + (np.where(signs < 0, half - 1, -half) + trans)


def _to_y_up(coords_mv: np.ndarray) -> np.ndarray:
    """MagicaVoxel (x, y, z) z-up to voxfield (x, z, -y) y-up."""
    return np.stack([coords_mv[:, 0], coords_mv[:, 2], -coords_mv[:, 1]], axis=1)


def _build_scene(
    vf: VoxFile, coords_mv: np.ndarray, color_index: np.ndarray, name: str, label: str
) -> VoxelScene:
    if len(coords_mv):
        extent = [int(c.max()) - int(c.min()) + 1 for c in coords_mv.T]
        if max(extent) > MAX_EXTENT or extent[0] * extent[1] * extent[2] >= 2**63:
            raise SceneFormatError(
                f"{label}: the placed scene spans {tuple(extent)} voxels, more "
                f"than the {MAX_EXTENT} per axis a scene may span"
            )
    linear = srgb_to_linear(vf.palette[:, :3].astype(np.float32) / 255.0)
    color = linear[color_index]
    emission = None
    strength = vf.emission[color_index]
    if (strength > 0).any():
        emission = color * strength[:, None]
    return VoxelScene(_to_y_up(coords_mv), color, emission, name=name)


def _empty_scene(name: str) -> VoxelScene:
    return VoxelScene(np.zeros((0, 3), np.int64), np.zeros((0, 3), np.float32), name=name)


def _check_source_options(missing_models: str) -> None:
    if missing_models not in ("skip", "error"):
        raise VoxfieldError(f"missing_models must be 'skip' or 'error', not {missing_models!r}")


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def read_vox(source: Source) -> VoxFile:
    """Parse a ``.vox`` file (path or bytes) into its models, palette and scene graph."""
    data, label, name = _read_bytes(source)
    return _parse(data, label, name)


def load_vox(
    source: Source, *, model: int | None = None, missing_models: str = "skip"
) -> VoxelScene:
    """Load a ``.vox`` file as one y-up VoxelScene with its minimum corner at the origin.

    With a scene graph, every visible shape is placed by its composed transforms (hidden nodes
    and hidden layers are skipped; where instances overlap the later one in graph order wins).
    Without one, model 0 is loaded. ``model=i`` loads model ``i`` alone, untransformed.
    A shape naming a model the file lacks is skipped with a warning (``missing_models="skip"``)
    or raises SceneFormatError (``"error"``).
    """
    _check_source_options(missing_models)
    data, label, name = _read_bytes(source)
    vf = _parse(data, label, name)

    if model is not None or not vf.nodes:
        index = 0 if model is None else int(model)
        if not vf.models and model is None:
            return _empty_scene(name)
        if not 0 <= index < len(vf.models):
            raise VoxfieldError(
                f"{label}: model={index} is out of range, the file has {len(vf.models)} model(s)"
            )
        chosen = vf.models[index]
        coords = chosen.voxels[:, :3].astype(np.int64)
        return _build_scene(vf, coords, chosen.voxels[:, 3], name, label).dedupe().normalized()

    placed, missing = _instances(vf, label)
    if missing:
        ids = ", ".join(str(m) for m in sorted(set(missing)))
        note = ""
        if vf.orphan_sizes:
            note = (
                f"; it has {vf.orphan_sizes} SIZE chunk(s) without XYZI voxels (e.g. Teardown's "
                "TDCZ chunks, which this reader does not decode)"
            )
        message = (
            f"{label}: shape nodes refer to missing model(s) {ids}; the file holds "
            f"{len(vf.models)} model(s){note}"
        )
        if missing_models == "error":
            raise SceneFormatError(message)
        warnings.warn(message + "; those shapes were skipped", UserWarning, stacklevel=2)

    if not placed:
        return _empty_scene(name)
    coords = np.concatenate([_place(vf.models[m], rot, t) for m, rot, t in placed])
    index = np.concatenate([vf.models[m].voxels[:, 3] for m, _, _ in placed])
    return _build_scene(vf, coords, index, name, label).dedupe().normalized()


def load_vox_models(source: Source) -> list[VoxelScene]:
    """Every model of the file on its own, in model order, ignoring the scene graph.

    Coordinates are y-up and relative to the model's SIZE box (box corner at the origin, not
    normalized), so a model's position inside its box is kept: useful for scattering assets
    whose pivot is the box. Call ``.normalized()`` to drop the box.
    """
    data, label, name = _read_bytes(source)
    vf = _parse(data, label, name)
    scenes = []
    for i, m in enumerate(vf.models):
        coords = m.voxels[:, :3].astype(np.int64)
        scene = _build_scene(vf, coords, m.voxels[:, 3], f"{name}#{i}", label).dedupe()
        # (x, z, -y) puts the box at y_ours in [-(size_y - 1), 0]; shift it back to start at 0.
        scenes.append(scene.translated((0, 0, m.size[1] - 1)))
    return scenes
