"""Tests for the MagicaVoxel reader: hand-built files with worked answers, the real files in
data/vox/ against an independent chunk walk, and corrupted copies that must fail cleanly."""

from __future__ import annotations

import itertools
import struct
import warnings

import numpy as np
import pytest

from voxfield.data import data_root
from voxfield.errors import (
    DataNotFoundError,
    SceneFormatError,
    SceneTooLargeError,
    VoxfieldError,
)
from voxfield.scene.vox import (
    DEFAULT_PALETTE,
    decode_rotation,
    encode_rotation,
    load_vox,
    load_vox_models,
    read_vox,
)
from voxfield.scene.voxel_scene import VoxelScene, srgb_to_linear

VOX_DIR = data_root() / "vox"
VOX_FILES = sorted(p.name for p in VOX_DIR.glob("*.vox")) if VOX_DIR.is_dir() else []
NO_DATA = f"shared data folder {VOX_DIR} is absent (set VOXFIELD_DATA to run real-file tests)"
needs_data = pytest.mark.skipif(not VOX_FILES, reason=NO_DATA)

IDENTITY = 4  # the _r byte of the identity matrix: row 0 -> column 0, row 1 -> column 1


# --------------------------------------------------------------------------------------------
# A tiny .vox writer, written against the format text (independent of the reader).
# --------------------------------------------------------------------------------------------


def chunk(tag: bytes, content: bytes = b"", children: bytes = b"") -> bytes:
    return tag + struct.pack("<ii", len(content), len(children)) + content + children


def vox(*chunks: bytes, version: int = 200) -> bytes:
    return b"VOX " + struct.pack("<i", version) + chunk(b"MAIN", b"", b"".join(chunks))


def vstring(text: str) -> bytes:
    raw = text.encode()
    return struct.pack("<i", len(raw)) + raw


def vdict(items: dict[str, str] | None = None) -> bytes:
    items = items or {}
    return struct.pack("<i", len(items)) + b"".join(
        vstring(k) + vstring(v) for k, v in items.items()
    )


def size(x: int, y: int, z: int) -> bytes:
    return chunk(b"SIZE", struct.pack("<iii", x, y, z))


def xyzi(voxels) -> bytes:
    raw = np.asarray(voxels, dtype=np.uint8).reshape(-1, 4)
    return chunk(b"XYZI", struct.pack("<i", len(raw)) + raw.tobytes())


def rgba(entries: dict[int, tuple[int, int, int]]) -> bytes:
    """An RGBA chunk: ``entries`` maps *colour index* to RGB (stored at chunk entry index-1)."""
    table = np.full((256, 4), 255, dtype=np.uint8)
    table[:, :3] = 7
    for index, rgb in entries.items():
        table[index - 1, :3] = rgb
    return chunk(b"RGBA", table.tobytes())


def ntrn(node, child, t=None, r=None, layer=0, attrs=None) -> bytes:
    frame = {}
    if t is not None:
        frame["_t"] = " ".join(str(v) for v in t)
    if r is not None:
        frame["_r"] = str(r)
    body = struct.pack("<i", node) + vdict(attrs) + struct.pack("<iiii", child, -1, layer, 1)
    return chunk(b"nTRN", body + vdict(frame))


def ngrp(node, children, attrs=None) -> bytes:
    body = struct.pack("<i", node) + vdict(attrs) + struct.pack("<i", len(children))
    return chunk(b"nGRP", body + struct.pack(f"<{len(children)}i", *children))


def nshp(node, model, attrs=None) -> bytes:
    body = struct.pack("<i", node) + vdict(attrs) + struct.pack("<ii", 1, model) + vdict()
    return chunk(b"nSHP", body)


def matl(mat_id, props) -> bytes:
    return chunk(b"MATL", struct.pack("<i", mat_id) + vdict(props))


def layr(layer_id, hidden=False) -> bytes:
    attrs = {"_hidden": "1"} if hidden else {}
    return chunk(b"LAYR", struct.pack("<i", layer_id) + vdict(attrs) + struct.pack("<i", -1))


def as_set(scene: VoxelScene) -> set[tuple[int, int, int]]:
    return {tuple(int(v) for v in c) for c in scene.coords}


def voxel_at(scene: VoxelScene, xyz) -> int:
    hits = np.flatnonzero((scene.coords == np.asarray(xyz)).all(axis=1))
    assert len(hits) == 1, f"expected one voxel at {xyz}, found {len(hits)}"
    return int(hits[0])


# --------------------------------------------------------------------------------------------
# Independent chunk walk of real files (plain struct, no reader code).
# --------------------------------------------------------------------------------------------


def walk_chunks(data: bytes) -> list[tuple[bytes, int, bytes]]:
    """(id, content offset, content) for each child of MAIN."""
    out = []
    _, m = struct.unpack_from("<ii", data, 12)
    pos = 20
    while pos < 20 + m:
        tag = data[pos : pos + 4]
        n, k = struct.unpack_from("<ii", data, pos + 4)
        out.append((tag, pos + 12, data[pos + 12 : pos + 12 + n]))
        pos += 12 + n + k
    return out


def raw_models(data: bytes) -> list[np.ndarray]:
    return [
        np.frombuffer(body, np.uint8, offset=4).reshape(-1, 4)
        for tag, _, body in walk_chunks(data)
        if tag == b"XYZI"
    ]


def count_unique(xyz: np.ndarray) -> int:
    """Distinct positions among byte coordinates (packed to one integer: np.unique is fast)."""
    xyz = xyz.astype(np.int64)
    return len(np.unique(xyz[:, 0] | xyz[:, 1] << 8 | xyz[:, 2] << 16))


def has_scene_graph(data: bytes) -> bool:
    return any(tag in (b"nTRN", b"nGRP", b"nSHP") for tag, _, _ in walk_chunks(data))


def load_quietly(source, **kwargs) -> VoxelScene:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_vox(source, **kwargs)


# --------------------------------------------------------------------------------------------
# Rotation byte
# --------------------------------------------------------------------------------------------


def signed_permutations():
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            mat = np.zeros((3, 3), dtype=np.int64)
            for row, (col, sign) in enumerate(zip(perm, signs, strict=True)):
                mat[row, col] = sign
            yield mat


def test_all_48_signed_permutations_round_trip():
    seen = set()
    for mat in signed_permutations():
        packed = encode_rotation(mat)
        assert 0 <= packed < 128
        np.testing.assert_array_equal(decode_rotation(packed), mat)
        seen.add(packed)
    assert len(seen) == 48


def test_exactly_48_bytes_decode():
    valid = []
    for packed in range(128):
        try:
            mat = decode_rotation(packed)
        except ValueError:
            continue
        valid.append(packed)
        assert abs(round(np.linalg.det(mat))) == 1
        np.testing.assert_array_equal(mat @ mat.T, np.eye(3))
    assert len(valid) == 48


def test_identity_byte():
    np.testing.assert_array_equal(decode_rotation(IDENTITY), np.eye(3))
    assert encode_rotation(np.eye(3, dtype=int)) == IDENTITY


def test_format_documents_example_rotation():
    # The extension text's example: rows (0 1 0), (0 0 -1), (-1 0 0) pack to
    # (1 << 0) | (2 << 2) | (0 << 4) | (1 << 5) | (1 << 6) = 1 + 8 + 32 + 64 = 105.
    mat = np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]])
    assert encode_rotation(mat) == 105
    np.testing.assert_array_equal(decode_rotation(105), mat)


def test_known_rotation_acts_on_column_vectors():
    # 90° about z (x -> y): rows (0 -1 0), (1 0 0), (0 0 1) = 1 | 0 << 2 | sign of row 0 (16).
    mat = decode_rotation(17)
    np.testing.assert_array_equal(mat @ np.array([1, 0, 0]), [0, 1, 0])
    np.testing.assert_array_equal(mat @ np.array([0, 1, 0]), [-1, 0, 0])


@pytest.mark.parametrize("packed", [3, 12, 0b0101, 128, -1, 255])
def test_invalid_rotation_bytes(packed):
    with pytest.raises(ValueError):
        decode_rotation(packed)


def test_encode_rejects_non_permutations():
    with pytest.raises(ValueError):
        encode_rotation(np.ones((3, 3)))
    with pytest.raises(ValueError):
        encode_rotation(np.diag([1, 2, 1]))


# --------------------------------------------------------------------------------------------
# Synthetic files with worked answers
# --------------------------------------------------------------------------------------------


def test_default_palette_matches_format_text():
    # Spot values from the default_palette table (0xAABBGGRR words) in the format text.
    expected = {
        0: (0, 0, 0, 0),  # 0x00000000
        1: (255, 255, 255, 255),  # 0xffffffff
        2: (255, 255, 204, 255),  # 0xffccffff
        7: (255, 204, 255, 255),  # 0xffffccff
        37: (204, 255, 255, 255),  # 0xffffffcc
        215: (0, 0, 51, 255),  # 0xff330000
        216: (238, 0, 0, 255),  # 0xff0000ee
        226: (0, 238, 0, 255),  # 0xff00ee00
        236: (0, 0, 238, 255),  # 0xffee0000
        255: (17, 17, 17, 255),  # 0xff111111
    }
    for index, value in expected.items():
        assert tuple(DEFAULT_PALETTE[index]) == value, index


def test_single_voxel_colour_uses_shifted_palette():
    # Colour index 3 must read chunk entry 2; decoys sit at entries 1 and 3 (indices 2 and 4).
    data = vox(
        size(1, 1, 1),
        xyzi([(0, 0, 0, 3)]),
        rgba({2: (0, 0, 255), 3: (255, 128, 0), 4: (0, 255, 0)}),
    )
    scene = load_vox(data)
    assert len(scene) == 1
    np.testing.assert_array_equal(scene.coords, [[0, 0, 0]])
    want = srgb_to_linear(np.array([1.0, 128 / 255, 0.0]))
    np.testing.assert_allclose(scene.color[0], want, rtol=1e-6)
    # Hand value: sRGB 128/255 = 0.50196 decodes to ((0.50196 + 0.055) / 1.055) ** 2.4 = 0.21586.
    assert scene.color[0, 1] == pytest.approx(0.21586, abs=1e-5)
    assert scene.emission is None


def test_colour_index_zero_is_no_voxel():
    # Index 0 is the format's "empty"; readers (ogt_vox, vengi) skip such entries.
    data = vox(size(3, 1, 1), xyzi([(0, 0, 0, 0), (1, 0, 0, 5), (2, 0, 0, 0)]))
    scene = load_vox(data)
    np.testing.assert_array_equal(scene.coords, [[0, 0, 0]])
    np.testing.assert_allclose(scene.color[0], srgb_to_linear(DEFAULT_PALETTE[5, :3] / 255.0))


def test_default_palette_when_rgba_absent():
    scene = load_vox(vox(size(1, 1, 1), xyzi([(0, 0, 0, 2)]), version=150))
    want = srgb_to_linear(np.array([255, 255, 204]) / 255.0)
    np.testing.assert_allclose(scene.color[0], want, rtol=1e-6)


def test_axis_mapping_z_up_to_y_up():
    # MagicaVoxel (x, y, z) -> ours (x, z, -y), then the min corner moves to the origin:
    # raw (0,0,0) (1,0,0) (0,0,-1) (0,1,0); min (0,0,-1).
    data = vox(size(2, 2, 2), xyzi([(0, 0, 0, 1), (1, 0, 0, 2), (0, 1, 0, 3), (0, 0, 1, 4)]))
    scene = load_vox(data)
    assert as_set(scene) == {(0, 0, 1), (1, 0, 1), (0, 0, 0), (0, 1, 1)}
    # MagicaVoxel +z (up) became our +y; +y (depth) became our -z.
    up = voxel_at(scene, (0, 1, 1))
    np.testing.assert_allclose(scene.color[up], srgb_to_linear(DEFAULT_PALETTE[4, :3] / 255.0))
    deep = voxel_at(scene, (0, 0, 0))
    np.testing.assert_allclose(scene.color[deep], srgb_to_linear(DEFAULT_PALETTE[3, :3] / 255.0))


def _two_shape_scene(bar_transform: bytes, extra: bytes = b"") -> bytes:
    """Model 0: a 3×1×1 bar (colour 10 at x=0, 11 at x=2); model 1: one voxel (colour 12) that
    stays at the world origin and anchors the normalisation."""
    return vox(
        size(3, 1, 1),
        xyzi([(0, 0, 0, 10), (2, 0, 0, 11)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 12)]),
        ntrn(0, 1),
        ngrp(1, [2, 4]),
        bar_transform,
        nshp(3, 0),
        ntrn(4, 5, t=(0, 0, 0)),
        nshp(5, 1),
        layr(0),
        extra,
    )


def _by_colour(scene: VoxelScene, data: bytes) -> dict[int, tuple[int, int, int]]:
    palette = srgb_to_linear(DEFAULT_PALETTE[:, :3] / 255.0)
    out = {}
    for c, col in zip(scene.coords, scene.color, strict=True):
        index = int(np.argmin(np.abs(palette - col).sum(axis=1)))
        out[index] = tuple(int(v) for v in c)
    return out


def test_scene_graph_translation_and_rotation():
    # Bar (3×1×1) rotated 90° about z (byte 17: R = [[0,-1,0],[1,0,0],[0,0,1]]) and moved to
    # (10, 20, 30): floor(R (v + 0.5 - (1, 0, 0))) + t takes x=0 to floor(-0.5, -0.5, 0.5)
    # + t = (9, 19, 30) and x=2 to floor(-0.5, 1.5, 0.5) + t = (9, 21, 30) (the flipped y
    # axis has odd size 1, so it lands one lower); the anchor voxel is at (0, 0, 0).
    # Ours (x, z, -y): anchor (0,0,0), colour 10 (9,30,-19), colour 11 (9,30,-21);
    # normalised by min (0,0,-21): anchor (0,0,21), 10 -> (9,30,2), 11 -> (9,30,0).
    data = _two_shape_scene(ntrn(2, 3, t=(10, 20, 30), r=17))
    scene = load_vox(data)
    assert _by_colour(scene, data) == {12: (0, 0, 21), 10: (9, 30, 2), 11: (9, 30, 0)}


def test_mirror_of_odd_model_pivots_between_voxels():
    # The 3-wide bar mirrored in x (byte 20) at (10, 0, 0): floor(-(v + 0.5 - 1)) + 10 puts
    # x=0 (colour 10) at 10 and x=2 (colour 11) at 8, so the bar spans 8..10, not the 9..11 a
    # centre-voxel pivot would keep; the anchor stays at 0.
    data = _two_shape_scene(ntrn(2, 3, t=(10, 0, 0), r=20))
    assert _by_colour(load_vox(data), data) == {11: (8, 0, 0), 10: (10, 0, 0), 12: (0, 0, 0)}


def test_mirror_of_even_model_stays_in_its_box():
    # Size 2 along x, mirrored in x (byte 20): the flipped box holds colour 11 at 0, colour 10
    # at 1; its voxel floor(2/2) = 1 sits at the translation (5, 0, 0): 11 -> x=4, 10 -> x=5.
    data = vox(
        size(2, 1, 1),
        xyzi([(0, 0, 0, 10), (1, 0, 0, 11)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 12)]),
        ntrn(0, 1),
        ngrp(1, [2, 4]),
        ntrn(2, 3, t=(5, 0, 0), r=20),
        nshp(3, 0),
        ntrn(4, 5),
        nshp(5, 1),
    )
    assert _by_colour(load_vox(data), data) == {12: (0, 0, 0), 11: (4, 0, 0), 10: (5, 0, 0)}


def test_animation_keys_are_read_by_frame_number_not_by_order():
    # Keys listed out of order (other tools than MagicaVoxel may write them so): the
    # transform's frame 0 moves the bar to x=20, and the shape's frame 0 is model 1 (the
    # single voxel of colour 12), though frame 5 and frame 3 come first.
    frames = [{"_f": "5", "_t": "-30 0 0"}, {"_f": "0", "_t": "20 0 0"}]
    trn = chunk(b"nTRN", struct.pack("<i", 2) + vdict() + struct.pack("<iiii", 3, -1, 0, 2)
                + b"".join(vdict(f) for f in frames))
    shp = chunk(b"nSHP", struct.pack("<i", 3) + vdict() + struct.pack("<i", 2)
                + struct.pack("<i", 0) + vdict({"_f": "3"})
                + struct.pack("<i", 1) + vdict({"_f": "0"}))
    data = vox(size(3, 1, 1), xyzi([(0, 0, 0, 10), (2, 0, 0, 11)]), size(1, 1, 1),
               xyzi([(0, 0, 0, 12)]), ntrn(0, 1), ngrp(1, [2, 4]), trn, shp,
               ntrn(4, 5), nshp(5, 0))
    # the shape shows model 1 at x=20; model 0's instance (node 4) sits at the origin, x -1..1
    assert _by_colour(load_vox(data), data) == {10: (0, 0, 0), 11: (2, 0, 0), 12: (21, 0, 0)}


def test_parent_rotation_turns_child_translation():
    # Parent: 90° about z; child: translation (5, 0, 0) -> (0, 5, 0) in MagicaVoxel, and the
    # one voxel floor(R (0.5, 0.5, 0.5)) = (-1, 0, 0) from it (x flipped, odd size 1): world
    # (-1, 5, 0), ours (-1, 0, -5); with the anchor at the origin, normalised by min
    # (-1, 0, -5): anchor (1,0,5), voxel (0,0,0).
    data = vox(
        size(1, 1, 1),
        xyzi([(0, 0, 0, 10)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 12)]),
        ntrn(0, 1),
        ngrp(1, [2, 6]),
        ntrn(2, 3, r=17),
        ngrp(3, [4]),
        ntrn(4, 5, t=(5, 0, 0)),
        nshp(5, 0),
        ntrn(6, 7),
        nshp(7, 1),
    )
    assert _by_colour(load_vox(data), data) == {12: (1, 0, 5), 10: (0, 0, 0)}


def test_shared_node_is_instanced_and_later_instance_wins():
    # Two transforms share shape 3 (as test-transform.vox does); a third shape with another
    # colour overlaps the second instance and comes later in graph order, so it wins there.
    data = vox(
        size(1, 1, 1),
        xyzi([(0, 0, 0, 10)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 11)]),
        ntrn(0, 1),
        ngrp(1, [2, 4, 5]),
        ntrn(2, 3, t=(0, 0, 0)),
        nshp(3, 0),
        ntrn(4, 3, t=(3, 0, 0)),
        ntrn(5, 6, t=(3, 0, 0)),
        nshp(6, 1),
    )
    assert _by_colour(load_vox(data), data) == {10: (0, 0, 0), 11: (3, 0, 0)}


def test_hidden_nodes_and_layers_are_skipped():
    hidden_node = _two_shape_scene(ntrn(2, 3, t=(10, 0, 0), attrs={"_hidden": "1"}))
    assert len(load_vox(hidden_node)) == 1
    hidden_layer = _two_shape_scene(ntrn(2, 3, t=(10, 0, 0), layer=1), layr(1, hidden=True))
    assert len(load_vox(hidden_layer)) == 1
    shown = _two_shape_scene(ntrn(2, 3, t=(10, 0, 0), layer=1), layr(1, hidden=False))
    assert len(load_vox(shown)) == 3


def test_matl_emission():
    # Colour 5 is emissive: _emit 0.5, _flux 2 -> linear colour * 0.5 * (1 + 2).
    # Colour 6 is metal with stale emission keys (as in teardown.vox): no emission.
    data = vox(
        size(3, 1, 1),
        xyzi([(0, 0, 0, 5), (1, 0, 0, 6), (2, 0, 0, 7)]),
        matl(5, {"_type": "_emit", "_emit": "0.5", "_flux": "2"}),
        matl(6, {"_type": "_metal", "_emit": "0.5", "_flux": "2"}),
    )
    scene = load_vox(data)
    assert scene.emission is not None
    emitter = voxel_at(scene, (0, 0, 0))
    np.testing.assert_allclose(scene.emission[emitter], scene.color[emitter] * 1.5, rtol=1e-6)
    for x in (1, 2):
        assert not scene.emission[voxel_at(scene, (x, 0, 0))].any()


def test_no_emissive_material_means_no_emission_array():
    data = vox(size(1, 1, 1), xyzi([(0, 0, 0, 5)]), matl(5, {"_type": "_diffuse"}))
    assert load_vox(data).emission is None


def test_missing_model_warns_or_raises():
    data = vox(
        size(1, 1, 1),
        xyzi([(0, 0, 0, 10)]),
        ntrn(0, 1),
        ngrp(1, [2, 4]),
        ntrn(2, 3),
        nshp(3, 0),
        ntrn(4, 5, t=(4, 0, 0)),
        nshp(5, 3),
    )
    with pytest.warns(UserWarning, match=r"missing model\(s\) 3"):
        scene = load_vox(data)
    assert len(scene) == 1
    with pytest.raises(SceneFormatError, match=r"missing model\(s\) 3"):
        load_vox(data, missing_models="error")
    with pytest.raises(VoxfieldError, match="missing_models"):
        load_vox(data, missing_models="ignore")


def test_multi_model_without_scene_graph_loads_model_zero_or_the_one_named():
    data = vox(
        chunk(b"PACK", struct.pack("<i", 2)),
        size(2, 1, 1),
        xyzi([(0, 0, 0, 1), (1, 0, 0, 1)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 1)]),
        version=150,
    )
    assert len(load_vox(data)) == 2
    assert len(load_vox(data, model=1)) == 1
    with pytest.raises(VoxfieldError, match="out of range"):
        load_vox(data, model=2)


def test_load_vox_models_keeps_box_relative_coordinates():
    # A voxel at MagicaVoxel (1, 0, 3) in a 2×3×4 box: ours (x, z, size_y - 1 - y) = (1, 3, 2).
    data = vox(size(2, 3, 4), xyzi([(1, 0, 3, 1)]), size(1, 1, 1), xyzi([(0, 0, 0, 2)]))
    models = load_vox_models(data)
    assert [len(m) for m in models] == [1, 1]
    np.testing.assert_array_equal(models[0].coords, [[1, 3, 2]])
    np.testing.assert_array_equal(models[1].coords, [[0, 0, 0]])


def test_duplicate_voxels_in_a_model_are_merged_last_wins():
    scene = load_vox(vox(size(1, 1, 1), xyzi([(0, 0, 0, 1), (0, 0, 0, 2)])))
    assert len(scene) == 1
    np.testing.assert_allclose(scene.color[0], srgb_to_linear(DEFAULT_PALETTE[2, :3] / 255.0))


def test_unknown_chunks_are_skipped_by_size():
    data = vox(
        chunk(b"NOTE", vdict({"a": "b"})),
        size(1, 1, 1),
        chunk(b"ABCD", b"\x01\x02\x03", chunk(b"INNR", b"xyz")),
        xyzi([(0, 0, 0, 1)]),
        chunk(b"rOBJ", vdict({"_type": "_bg"})),
    )
    assert len(load_vox(data)) == 1


def test_read_vox_exposes_parsed_file():
    data = vox(size(2, 1, 1), xyzi([(1, 0, 0, 9)]), rgba({9: (1, 2, 3)}))
    vf = read_vox(data)
    assert vf.version == 200
    assert vf.models[0].size == (2, 1, 1)
    assert tuple(vf.palette[9, :3]) == (1, 2, 3)


def test_missing_file_is_a_data_not_found_error(tmp_path):
    with pytest.raises(DataNotFoundError):
        load_vox(tmp_path / "nope.vox")


def test_deep_transform_chain_needs_no_recursion():
    # 5000 nested transforms, each moving +1 in x: deeper than Python's recursion limit.
    n = 5000
    chain = [ntrn(i, i + 1, t=(1, 0, 0)) for i in range(n)] + [nshp(n, 0)]
    data = vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), *chain)
    assert len(load_vox(data)) == 1


def test_exponential_shared_graph_is_refused():
    # 40 groups, each listing the next twice: 2^40 instances of one voxel.
    graph = [ntrn(0, 1)] + [ngrp(i, [i + 1, i + 1]) for i in range(1, 40)]
    data = vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), *graph, ntrn(40, 41), nshp(41, 0))
    with pytest.raises(SceneTooLargeError):
        load_vox(data)


BAD_FILES = {
    "empty": b"",
    "short header": b"VOX ",
    "bad magic": b"VOXX" + vox(size(1, 1, 1))[4:],
    "unsupported version": vox(size(1, 1, 1), version=99),
    "first chunk not MAIN": b"VOX " + struct.pack("<i", 150) + chunk(b"MAIM"),
    "MAIN runs past the end": vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]))[:-3],
    "negative chunk size": vox(b"SIZE" + struct.pack("<ii", -12, 0)),
    "chunk past MAIN": vox(b"XYZI" + struct.pack("<ii", 400, 0) + b"\0" * 8),
    "negative model size": vox(size(-1, 2, 2), xyzi([])),
    "absurd model size": vox(size(100000, 2, 2), xyzi([])),
    "short SIZE": vox(chunk(b"SIZE", b"\1\0\0\0")),
    "XYZI without SIZE": vox(xyzi([(0, 0, 0, 1)])),
    "voxel outside SIZE": vox(size(2, 2, 2), xyzi([(0, 2, 0, 1)])),
    "voxel count too big": vox(size(2, 2, 2), chunk(b"XYZI", struct.pack("<i", 99) + b"\0" * 8)),
    "negative voxel count": vox(size(2, 2, 2), chunk(b"XYZI", struct.pack("<i", -1))),
    "no root node": vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), ntrn(2, 3), nshp(3, 0)),
    "missing child node": vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), ntrn(0, 7)),
    "cycle": vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), ntrn(0, 1), ngrp(1, [2]), ntrn(2, 1)),
    "self loop": vox(ntrn(0, 0)),
    "duplicate node id": vox(ntrn(0, 1), ngrp(1, []), ngrp(1, [])),
    "bad rotation": vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)]), ntrn(0, 1, r=15), nshp(1, 0)),
    "rotation not a number": vox(ntrn(0, 1, r="x"), ngrp(1, [])),  # type: ignore[arg-type]
    "bad translation": vox(ntrn(0, 1, t=(1, 2)), ngrp(1, [])),
    "huge translation": vox(ntrn(0, 1, t=(10**12, 0, 0)), ngrp(1, [])),
    "huge dict count": vox(chunk(b"nGRP", struct.pack("<ii", 0, 1 << 30))),
    "huge string": vox(chunk(b"MATL", struct.pack("<iii", 1, 1, 1 << 30))),
    "bad emission": vox(matl(1, {"_type": "_emit", "_emit": "nan"})),
    "scene too wide": vox(
        size(1, 1, 1),
        xyzi([(0, 0, 0, 1)]),
        ntrn(0, 1),
        ngrp(1, [2, 4]),
        ntrn(2, 3, t=(-(1 << 21), 0, 0)),
        nshp(3, 0),
        ntrn(4, 5, t=(1 << 21, 0, 0)),
        nshp(5, 0),
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_malformed_files_raise_scene_format_error(case, tmp_path):
    path = tmp_path / "bad.vox"
    path.write_bytes(BAD_FILES[case])
    with pytest.raises(SceneFormatError) as info:
        load_quietly(path)
    assert str(path) in str(info.value), "the message must name the file"


# --------------------------------------------------------------------------------------------
# Real files
# --------------------------------------------------------------------------------------------


@needs_data
@pytest.mark.parametrize("name", VOX_FILES or ["<none>"])
def test_every_real_file_loads(name):
    path = VOX_DIR / name
    data = path.read_bytes()
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        scene = load_vox(path)
    assert isinstance(scene, VoxelScene)
    assert scene.name == path.stem
    if len(scene):
        np.testing.assert_array_equal(scene.coords.min(axis=0), [0, 0, 0])
        assert ((scene.color >= 0) & (scene.color <= 1)).all()
    models = raw_models(data)
    if not has_scene_graph(data):
        # Model 0 alone: its distinct positions, with MagicaVoxel (x, y, z) extents -> (x, z, y).
        xyz = models[0][:, :3]
        assert len(scene) == count_unique(xyz)
        mv_extent = xyz.max(axis=0).astype(int) - xyz.min(axis=0) + 1
        np.testing.assert_array_equal(scene.extent, mv_extent[[0, 2, 1]])
    elif name == "PineFluffy.vox":
        # Two 128³ models placed at the same translation: overlaps removed, nothing lost.
        unique = [count_unique(m[:, :3]) for m in models]
        assert max(unique) <= len(scene) <= sum(unique)


@needs_data
def test_monu3_matches_published_size():
    scene = load_vox(VOX_DIR / "monu3.vox")
    assert len(scene) == 848_469
    # 112×112×120 z-up is 112 wide, 120 tall, 112 deep here.
    np.testing.assert_array_equal(scene.extent, [112, 120, 112])


@needs_data
def test_real_palette_colour_matches_rgba_chunk():
    data = (VOX_DIR / "chr_knight.vox").read_bytes()
    chunks = {tag: body for tag, _, body in walk_chunks(data)}
    table = np.frombuffer(chunks[b"RGBA"], np.uint8).reshape(256, 4)
    voxels = raw_models(data)[0]
    scene = load_vox(VOX_DIR / "chr_knight.vox")
    # Undo the normalisation by hand: ours = (x, z, -y) - min.
    mv = voxels[:, :3].astype(int)
    ours = np.stack([mv[:, 0], mv[:, 2], -mv[:, 1]], axis=1)
    ours -= ours.min(axis=0)
    for k in (0, len(voxels) // 2, len(voxels) - 1):
        i = voxel_at(scene, ours[k])
        want = srgb_to_linear(table[voxels[k, 3] - 1, :3] / 255.0)
        np.testing.assert_allclose(scene.color[i], want, rtol=1e-6)


@needs_data
def test_test_transform_floor_tiles_exactly():
    # Four 128×128×6 floor instances (two of them mirrored, the others turned 180°) must tile
    # a 256×256 slab with neither gap nor overlap; an off-by-one in the pivot of flipped even
    # axes would overlap a column and widen the scene to 257.
    scene = load_vox(VOX_DIR / "test-transform.vox")
    floor = scene.coords[:, 1] < 6
    assert floor.sum() == 256 * 256 * 6
    np.testing.assert_array_equal(scene.extent, [256, 50, 256])
    # 20 instances of 3 models: at most the sum of their voxels, overlaps removed.
    models = raw_models((VOX_DIR / "test-transform.vox").read_bytes())
    assert len(scene) <= 4 * (len(models[0]) + 2 * len(models[1]) + 2 * len(models[2]))


@needs_data
def test_test_transform_is_mirror_symmetric_in_x():
    # The file places each model beside its mirror image, a 39-voxel-wide one among them: the
    # whole scene is its own mirror in x only if odd flipped axes pivot between voxels (a
    # centre-voxel pivot shifts the mirrored 39-wide instances by one: 2,992 voxels differ).
    coords = load_vox(VOX_DIR / "test-transform.vox").coords.astype(np.int64)
    mirrored = coords.copy()
    mirrored[:, 0] = coords[:, 0].min() + coords[:, 0].max() - coords[:, 0]
    assert {tuple(c) for c in coords.tolist()} == {tuple(c) for c in mirrored.tolist()}


@needs_data
def test_test_material_emission():
    # MATL 230 (model 0: _emit 1, _flux 1) and 135 (model 1: _emit 1, _flux 3) -> x2 and x4.
    scene = load_vox(VOX_DIR / "test_material.vox")
    assert len(scene) == 12 * 40**3  # twelve solid 40³ cubes, placed apart
    assert scene.emission is not None
    emits = scene.emission.any(axis=1)
    assert emits.sum() == 2 * 40**3
    ratio = scene.emission[emits] / np.maximum(scene.color[emits], 1e-12)
    lit = scene.color[emits] > 1e-4
    assert set(np.round(ratio[lit], 4).tolist()) == {2.0, 4.0}


@needs_data
def test_kloster_legacy_matt_emission():
    data = (VOX_DIR / "kloster.vox").read_bytes()
    emissive = (raw_models(data)[0][:, 3] == 82).sum()  # MATT 82 is type 3 (emissive)
    scene = load_vox(VOX_DIR / "kloster.vox")
    assert scene.emission is not None
    assert emissive > 0
    assert scene.emission.any(axis=1).sum() == emissive


@needs_data
def test_t_rex_frames():
    path = VOX_DIR / "T-Rex.vox"
    models = raw_models(path.read_bytes())
    assert len(models) == 8
    scenes = load_vox_models(path)
    assert [len(s) for s in scenes] == [count_unique(m[:, :3]) for m in models]
    assert len(load_vox(path, model=7)) == len(scenes[7])
    with pytest.raises(VoxfieldError):
        load_vox(path, model=8)


@needs_data
def test_teardown_missing_models():
    path = VOX_DIR / "teardown.vox"
    # Its voxels are in Teardown's TDCZ chunks, not XYZI, so its shapes name absent models.
    with pytest.warns(UserWarning, match=r"missing model\(s\) 0, 1, 2, 3, 4, 5, 6, 7"):
        scene = load_vox(path)
    assert isinstance(scene, VoxelScene)
    assert len(scene) == 0
    with pytest.raises(SceneFormatError, match="teardown.vox"):
        load_vox(path, missing_models="error")


# --------------------------------------------------------------------------------------------
# Corruption: every outcome is a VoxelScene or a VoxfieldError
# --------------------------------------------------------------------------------------------


def _must_load_or_fail_cleanly(data: bytes, **kwargs) -> str:
    """Any exception other than a VoxfieldError propagates and fails the test."""
    try:
        scene = load_quietly(data, **kwargs)
    except VoxfieldError:
        return "error"
    assert isinstance(scene, VoxelScene)
    return "loaded"


def rich_synthetic_file() -> bytes:
    """Small but dense in structure: shared nodes, rotations, layers, materials, palette."""
    return vox(
        chunk(b"PACK", struct.pack("<i", 3)),
        size(3, 2, 2),
        xyzi([(0, 0, 0, 5), (2, 1, 1, 6), (1, 0, 1, 7)]),
        size(2, 2, 1),
        xyzi([(0, 0, 0, 8), (1, 1, 0, 9)]),
        size(1, 1, 1),
        xyzi([(0, 0, 0, 10)]),
        ntrn(0, 1),
        ngrp(1, [2, 4, 6, 8]),
        ntrn(2, 3, t=(1, 2, 3), r=17, layer=0),
        nshp(3, 0),
        ntrn(4, 3, t=(-4, 0, 2), r=105, layer=1),
        ntrn(6, 7, t=(0, 5, 0), r=52, layer=0),
        ngrp(7, [10]),
        ntrn(8, 9, t=(2, 2, 2), attrs={"_hidden": "0", "_name": "leaf"}),
        nshp(9, 2),
        ntrn(10, 11, t=(3, -3, 0), r=20),
        nshp(11, 1),
        layr(0),
        layr(1, hidden=False),
        rgba({5: (200, 10, 10), 6: (10, 200, 10), 8: (1, 2, 3)}),
        matl(5, {"_type": "_emit", "_emit": "0.7", "_flux": "1"}),
        matl(8, {"_type": "_blend", "_emit": "0.2"}),
        chunk(b"rOBJ", vdict({"_type": "_bg", "_color": "0 0 0"})),
    )


def test_rich_synthetic_file_loads():
    scene = load_vox(rich_synthetic_file())
    assert len(scene) == 9  # model 0 twice (3 + 3), model 1 once (2), model 2 once (1)
    assert scene.emission is not None


def test_chunk_sizes_past_two_gigabytes_read_as_unsigned():
    """Sizes of 0x80000000 and more were read as signed: "claims 0 + -2147483648 bytes"."""
    data = bytearray(vox(size(1, 1, 1), xyzi([(0, 0, 0, 1)])))
    main_children = bytearray(data)
    main_children[16:20] = struct.pack("<I", 0x80000000)
    with pytest.raises(SceneFormatError, match="claims 0 \\+ 2,147,483,648 bytes"):
        load_vox(bytes(main_children))
    chunk_content = bytearray(data)
    chunk_content[24:28] = struct.pack("<I", 0xFFFFFFF0)  # SIZE's content
    with pytest.raises(SceneFormatError, match="'SIZE' claims 4,294,967,280 \\+ 0 bytes"):
        load_vox(bytes(chunk_content))
    voxel_count = bytearray(data)
    voxel_count[len(data) - 8:len(data) - 4] = struct.pack("<I", 0x80000000)
    with pytest.raises(SceneFormatError, match="voxel count 2147483648 does not fit"):
        load_vox(bytes(voxel_count))


def _with_main_size(data: bytes) -> bytes:
    """Patch MAIN's child size to the truncated length so parsing must go inside the chunks."""
    if len(data) < 20:
        return data
    return data[:16] + struct.pack("<i", len(data) - 20) + data[20:]


CORRUPT_SOURCES = ["<synthetic>", "chr_knight.vox", "T-Rex.vox", "PineFluffy.vox"]


def corrupt_source(name: str) -> bytes:
    if name == "<synthetic>":
        return rich_synthetic_file()
    if not VOX_FILES:
        pytest.skip(NO_DATA)
    return (VOX_DIR / name).read_bytes()


@pytest.mark.parametrize("name", CORRUPT_SOURCES)
def test_truncated_copies(name):
    data = corrupt_source(name)
    rng = np.random.default_rng(1234)
    starts = [off - 12 for _, off, _ in walk_chunks(data)]
    starts = rng.permutation(starts)[:40]
    boundaries = {int(s) + d for s in starts for d in (0, 4, 8, 12, 13, 16, 17)}
    cuts = sorted(set(range(0, 40)) | boundaries | set(rng.integers(0, len(data), 150).tolist()))
    outcomes = set()
    for cut in cuts:
        assert _must_load_or_fail_cleanly(data[:cut]) == "error", f"cut at {cut} loaded"
        outcomes.add(_must_load_or_fail_cleanly(_with_main_size(data[:cut])))
    assert "error" in outcomes


@pytest.mark.parametrize("name", CORRUPT_SOURCES)
def test_bit_flipped_copies(name):
    data = corrupt_source(name)
    # Half the flips land anywhere; half on structure (headers, dicts, graph), not voxel payload.
    structure = np.ones(len(data), dtype=bool)
    for tag, off, body in walk_chunks(data):
        if tag == b"XYZI":
            structure[off + 4 : off + len(body)] = False
    structural = np.flatnonzero(structure)
    rng = np.random.default_rng(20240611)
    outcomes = {"loaded": 0, "error": 0}
    for variant in range(200):
        buf = bytearray(data)
        pool = structural if variant % 2 else np.arange(len(data))
        for _ in range(int(rng.integers(1, 9))):
            pos = int(rng.choice(pool))
            buf[pos] ^= 1 << int(rng.integers(0, 8))
        mode = "error" if variant % 4 == 3 else "skip"
        outcomes[_must_load_or_fail_cleanly(bytes(buf), missing_models=mode)] += 1
    assert outcomes["error"] > 0 and outcomes["loaded"] > 0, outcomes


def test_random_garbage_after_header():
    rng = np.random.default_rng(7)
    for _ in range(200):
        body = rng.integers(0, 256, int(rng.integers(0, 200)), dtype=np.uint8).tobytes()
        for tag in (b"SIZE", b"XYZI", b"nTRN", b"nGRP", b"nSHP", b"MATL", b"LAYR", b"RGBA"):
            _must_load_or_fail_cleanly(vox(size(2, 2, 2), xyzi([(0, 0, 0, 1)]), chunk(tag, body)))
