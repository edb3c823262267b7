"""Every reader, fed damaged or hostile input, either returns something valid or raises a
``VoxfieldError`` (the command line's one clean line): never another exception."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from voxfield.errors import VoxfieldError
from voxfield.scene.mesh import load_mesh
from voxfield.scene.terrain.dem import load_heightmap
from voxfield.scene.vox import load_vox
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.scene.voxelize import voxelize_mesh
from voxfield.svo import build_octree, load_octree, save_octree
from voxfield.svo.open import open_octree


def _accepts_or_refuses(read, *args):
    """Run ``read``: a result or a VoxfieldError are both fine."""
    try:
        return read(*args)
    except VoxfieldError:
        return None


# --------------------------------------------------------------------------- .vox


def _chunk(name: bytes, content: bytes, children: bytes = b"") -> bytes:
    return name + struct.pack("<ii", len(content), len(children)) + content + children


@given(st.binary(max_size=400))
def test_vox_bytes_after_a_valid_magic(tmp_path_factory, payload):
    path = tmp_path_factory.mktemp("vox") / "fuzz.vox"
    path.write_bytes(b"VOX " + struct.pack("<i", 150) + payload)
    _accepts_or_refuses(load_vox, path)


@given(size=st.tuples(*[st.integers(-3, 300)] * 3),
       voxels=st.lists(st.tuples(*[st.integers(0, 255)] * 4), max_size=40),
       claimed=st.integers(-5, 100))
def test_vox_size_and_voxel_chunks_that_disagree(tmp_path_factory, size, voxels, claimed):
    xyzi = struct.pack("<i", claimed) + b"".join(struct.pack("<4B", *v) for v in voxels)
    body = _chunk(b"SIZE", struct.pack("<3i", *size)) + _chunk(b"XYZI", xyzi)
    path = tmp_path_factory.mktemp("vox") / "fuzz.vox"
    path.write_bytes(b"VOX " + struct.pack("<i", 150) + _chunk(b"MAIN", b"", body))
    scene = _accepts_or_refuses(load_vox, path)
    if scene is not None:
        assert np.isfinite(scene.color).all()


# --------------------------------------------------------------------------- meshes

_coord = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@given(vertices=st.lists(st.tuples(_coord, _coord, _coord), min_size=1, max_size=8),
       faces=st.lists(st.tuples(*[st.integers(-10, 10)] * 3), max_size=8),
       resolution=st.integers(1, 48))
def test_obj_with_any_vertices_and_faces(tmp_path_factory, vertices, faces, resolution):
    """Degenerate, repeated, out-of-range and negative face indices included."""
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in vertices)
    text += "".join(f"f {a} {b} {c}\n" for a, b, c in faces)
    path = tmp_path_factory.mktemp("obj") / "fuzz.obj"
    path.write_text(text)
    mesh = _accepts_or_refuses(load_mesh, path)
    if mesh is not None:
        _accepts_or_refuses(voxelize_mesh, mesh, resolution)


@pytest.mark.parametrize("suffix", [".ply", ".glb", ".gltf"])
@given(payload=st.binary(max_size=300))
def test_trimesh_formats_from_any_bytes(tmp_path_factory, suffix, payload):
    path = tmp_path_factory.mktemp("mesh") / f"fuzz{suffix}"
    path.write_bytes(payload)
    _accepts_or_refuses(load_mesh, path)


# --------------------------------------------------------------------------- DEMs


@given(payload=st.binary(max_size=400))
def test_geotiff_from_any_bytes_after_its_magic(tmp_path_factory, payload):
    path = tmp_path_factory.mktemp("dem") / "fuzz.tif"
    path.write_bytes(b"II*\0" + payload)
    _accepts_or_refuses(load_heightmap, str(path))


@given(side=st.integers(0, 40), fill=st.integers(-32768, 32767))
def test_hgt_of_any_size(tmp_path_factory, side, fill):
    path = tmp_path_factory.mktemp("dem") / "N00E000.hgt"
    path.write_bytes(np.full(side * side, fill, ">i2").tobytes())
    _accepts_or_refuses(load_heightmap, str(path))


# --------------------------------------------------------------------------- octrees


@pytest.fixture(scope="module")
def octree_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("octree") / "menger.npz"
    save_octree(open_octree("builtin:menger"), path)
    return path


@given(name=st.sampled_from(["descriptors", "level_offsets", "voxel_box", "scene_origin",
                             "attr_color"]),
       change=st.sampled_from(["float", "nan", "negative", "huge", "truncate", "empty"]))
def test_octree_files_with_one_array_damaged(tmp_path_factory, octree_file, name, change):
    with np.load(octree_file, allow_pickle=False) as data:
        arrays = {k: np.array(data[k]) for k in data.files}
    if name not in arrays:
        return
    a = arrays[name]
    if change == "float":
        a = a.astype(np.float64) + 0.5
    elif change == "nan":
        a = a.astype(np.float64)
        a.flat[0] = np.nan
    elif change == "negative":
        a = -np.abs(a.astype(np.int64)) - 1
    elif change == "huge":
        a = a.astype(np.int64) + 2**40
    elif change == "truncate":
        a = a[: max(len(a) // 2, 0)]
    else:
        a = a[:0]
    arrays[name] = a
    path = tmp_path_factory.mktemp("bad") / "octree.npz"
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    octree = _accepts_or_refuses(load_octree, path)
    if octree is not None:  # whatever loads must be whole
        assert np.isfinite(octree.color).all()


@given(coords=st.lists(st.tuples(*[st.integers(-50, 50)] * 3), min_size=1, max_size=30))
def test_octree_build_from_any_voxels(coords):
    points = np.unique(np.array(coords, np.int64), axis=0)
    octree = build_octree(VoxelScene(points, np.full((len(points), 3), 0.5, np.float32)))
    assert octree.voxel_count == len(points)
