"""Mesh loading: our OBJ/MTL parser against hand-written files and the real data's own numbers."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from voxfield.data import data_root
from voxfield.errors import DataNotFoundError, SceneFormatError
from voxfield.scene.mesh import DEFAULT_COLOR, TriangleMesh, load_mesh
from voxfield.scene.voxel_scene import srgb_to_linear

SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_negative_indices_equal_positive_ones(tmp_path):
    second = SQUARE.replace("0 0 0", "0 0 2")
    pos = _write(tmp_path, "pos.obj", SQUARE + "f 1 2 3 4\n" + second + "f 5 6 7\n")
    neg = _write(tmp_path, "neg.obj", SQUARE + "f -4 -3 -2 -1\n" + second + "f -4 -3 -2\n")
    a, b = load_mesh(pos), load_mesh(neg)
    np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_array_equal(a.triangles, [[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(a.vertices, b.vertices)


def test_polygons_fan_triangulate_and_slash_forms_parse(tmp_path):
    text = (
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1 4/1/1 5/2/1\n"  # pentagon → 3 triangles
        "f 1//1 2//1 3//1\n"
        "f 1/1 -4/-2 -3/-1\n"
    )
    mesh = load_mesh(_write(tmp_path, "p.obj", text))
    np.testing.assert_array_equal(
        mesh.triangles, [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 1, 2], [0, 1, 2]]
    )
    np.testing.assert_array_equal(mesh.face_color, np.full((5, 3), np.float32(0.8)))
    assert mesh.uv is None  # no texture → no UVs kept


def test_materials_kd_ke_and_defaults(tmp_path):
    mtl = "newmtl red \n  Kd 0.63 0.065 0.05 # comment\nnewmtl lamp\nKd 0.5\nKe 17 12 4\n"
    _write(tmp_path, "m.mtl", mtl)
    text = "mtllib m.mtl\n" + SQUARE + "f 1 2 3\nusemtl red\nf 1 3 4\nusemtl lamp\nf 2 3 4\r\n"
    mesh = load_mesh(_write(tmp_path, "m.obj", text))
    np.testing.assert_allclose(mesh.face_color, [DEFAULT_COLOR, [0.63, 0.065, 0.05], [0.5] * 3])
    np.testing.assert_allclose(mesh.face_emission, [[0, 0, 0], [0, 0, 0], [17, 12, 4]])


def test_missing_material_library_warns_and_uses_grey(tmp_path):
    text = "mtllib nowhere.mtl\n" + SQUARE + "usemtl x\nf 1 2 3\n"
    with pytest.warns(UserWarning, match="nowhere.mtl not found"):
        mesh = load_mesh(_write(tmp_path, "w.obj", text))
    np.testing.assert_allclose(mesh.face_color, [DEFAULT_COLOR])


def test_undefined_material_warns(tmp_path):
    _write(tmp_path, "m.mtl", "newmtl a\nKd 1 0 0\n")
    text = "mtllib m.mtl\n" + SQUARE + "usemtl b\nf 1 2 3\n"
    with pytest.warns(UserWarning, match="'b'"):
        mesh = load_mesh(_write(tmp_path, "u.obj", text))
    np.testing.assert_allclose(mesh.face_color, [DEFAULT_COLOR])


def test_texture_is_decoded_from_srgb(tmp_path):
    Image.fromarray(np.full((2, 3, 3), (255, 128, 0), np.uint8)).save(tmp_path / "t.png")
    _write(tmp_path, "t.mtl", "newmtl m\nKd 1 1 1\nmap_Kd t.png\n")
    text = "mtllib t.mtl\n" + SQUARE + "vt 0 0\nvt 1 0\nvt 1 1\nusemtl m\nf 1/1 2/2 3/3\nf 1 3 4\n"
    with pytest.warns(UserWarning, match="no texture coordinates"):
        mesh = load_mesh(_write(tmp_path, "t.obj", text))
    assert len(mesh.textures) == 1 and mesh.textures[0].shape == (2, 3, 3)
    np.testing.assert_allclose(mesh.textures[0][0, 0], srgb_to_linear(np.array([1, 128 / 255, 0])))
    np.testing.assert_array_equal(mesh.face_texture, [0, -1])
    np.testing.assert_allclose(mesh.uv[0], [[0, 0], [1, 0], [1, 1]])


def test_vertex_colours_in_obj_are_srgb(tmp_path):
    text = "v 0 0 0 1 0.5 0\nv 1 0 0 0 0 0\nv 0 1 0 1 1 1\nf 1 2 3\n"
    mesh = load_mesh(_write(tmp_path, "c.obj", text))
    np.testing.assert_allclose(mesh.vertex_color[0], srgb_to_linear(np.array([1, 0.5, 0])))
    np.testing.assert_allclose(mesh.face_color, [[1, 1, 1]])  # no material: no dimming


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "0 vertices"),
        ("# only a comment\nv 0 0 0\n", "0 faces"),
        (SQUARE + "f 1 2 5\n", "vertex 5"),
        (SQUARE + "f -1 -2 -5\n", "vertex -5"),
        (SQUARE + "f 0 1 2\n", "index 0"),
        (SQUARE + "f 1 2\n", "2 corners"),
        (SQUARE + "f 1 2 x\n", "malformed face"),
        ("v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "malformed vertex"),
        ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 1 has 2 numbers"),
        ("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
        ("v 0 0 0\nv 1 0 0\nv inf 1 0\nf 1 2 3\n", "vertex 3 is at inf 1 0"),
        ("v 0 0 0\nv 1e400 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 2 is at 1e400 0 0"),
        (SQUARE + "v -1.7e308 0 0\nv 1.7e308 0 0\nf 5 6 3\n", "vertices lie too far apart"),
        ("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n", "degenerate"),
        (SQUARE + "vt 0 0\nf 1/2 2/1 3/1\n", "texture 2"),
    ],
)
def test_bad_obj_files_raise_scene_format_error(tmp_path, text, match):
    with pytest.raises(SceneFormatError, match=match):
        load_mesh(_write(tmp_path, "bad.obj", text))


def test_a_mesh_in_units_of_1e300_voxelizes_as_at_unit_size(tmp_path):
    """Finite but huge coordinates: the same voxels as the same shape at unit size, and no
    floating-point warning on the way (the suite turns one into an error)."""
    from voxfield.scene.voxelize import voxelize_mesh

    text = "v 0 0 0\nv {s} 0 0\nv {s} {s} 0\nv {h} {t} 0\nv 0 {s} 0\nf 1 2 3 4 5\n"
    unit = _write(tmp_path, "unit.obj", text.format(s=1, h=0.5, t=0.2))
    huge = _write(tmp_path, "huge.obj", text.format(s=1e300, h=5e299, t=2e299))
    a, b = (voxelize_mesh(load_mesh(p), resolution=32) for p in (unit, huge))
    np.testing.assert_array_equal(a.coords, b.coords)


def test_missing_binary_and_unknown_files(tmp_path):
    with pytest.raises(DataNotFoundError, match="does not exist"):
        load_mesh(tmp_path / "absent.obj")
    (tmp_path / "bin.obj").write_bytes(b"\x00\x01\x02garbage")
    with pytest.raises(SceneFormatError, match="binary"):
        load_mesh(tmp_path / "bin.obj")
    with pytest.raises(SceneFormatError, match="unsupported"):
        load_mesh(_write(tmp_path, "x.stlx", "solid"))
    (tmp_path / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00" + b"\xff" * 40)
    with pytest.raises(SceneFormatError, match="not a GLB file"):
        load_mesh(tmp_path / "broken.glb")
    with pytest.raises(SceneFormatError):
        load_mesh(_write(tmp_path, "empty.ply", ""))


def test_triangle_mesh_validates_its_arrays():
    v = np.eye(3)
    with pytest.raises(SceneFormatError, match="indices"):
        TriangleMesh(v, [[0, 1, 3]], face_color=[[1, 1, 1]])
    with pytest.raises(SceneFormatError, match="face_color"):
        TriangleMesh(v, [[0, 1, 2]], face_color=[[1, 1]])
    with pytest.raises(SceneFormatError, match="empty"):
        TriangleMesh(np.zeros((0, 3)), np.zeros((0, 3), int), face_color=np.zeros((0, 3)))
    with pytest.raises(SceneFormatError, match="uv"):
        TriangleMesh(v, [[0, 1, 2]], face_color=[[1, 1, 1]], uv=np.zeros((1, 3, 2)))


# --------------------------------------------------------------------------------------------
# glTF / GLB / PLY through trimesh (files written by trimesh, read back by us)


def _tm_box():
    import trimesh

    return trimesh.creation.box(extents=(2.0, 1.0, 0.5))


def test_ply_vertex_colours_are_srgb_decoded(tmp_path):
    box = _tm_box()
    box.visual.vertex_colors = np.tile([255, 128, 0, 255], (len(box.vertices), 1)).astype(np.uint8)
    box.export(tmp_path / "b.ply")
    mesh = load_mesh(tmp_path / "b.ply")
    np.testing.assert_allclose(mesh.extents, [2.0, 1.0, 0.5])
    expected = srgb_to_linear(np.array([1, 128 / 255, 0]))
    np.testing.assert_allclose(mesh.vertex_color - expected, 0.0, atol=1e-6)


def test_ply_with_nan_vertex_raises(tmp_path):
    text = (
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\nnan 1 0\n0 1 0\n3 0 1 2\n"
    )
    with pytest.raises(SceneFormatError, match="NaN"):
        load_mesh(_write(tmp_path, "n.ply", text))


@pytest.mark.parametrize("kind, value", [("float", "1e300"), ("double", "inf"),
                                         ("double", "1e400")])
def test_ply_vertex_past_its_type_is_refused_in_one_message(tmp_path, kind, value):
    """A float property of 1e300 reads as infinity (trimesh's cast warned first)."""
    text = (
        f"ply\nformat ascii 1.0\nelement vertex 3\nproperty {kind} x\nproperty {kind} y\n"
        f"property {kind} z\nelement face 1\nproperty list uchar int vertex_indices\n"
        f"end_header\n0 0 0\n{value} 1 0\n0 1 0\n3 0 1 2\n"
    )
    with pytest.raises(SceneFormatError, match=r"p\.ply: a vertex reads as \(inf, 1, 0\)"):
        load_mesh(_write(tmp_path, "p.ply", text))


def test_gltf_nodes_scaling_far_from_unit_size(tmp_path):
    """trimesh's arithmetic on a node scaled by 1e300 overflows in its checks (warnings) but
    places the vertices right; a scale that carries them past the largest number is
    refused, naming the file."""
    import json

    doc = _one_triangle_gltf()
    doc["nodes"][0]["scale"] = [1e300, 1e300, 1e300]
    (tmp_path / "huge.gltf").write_text(json.dumps(doc))
    np.testing.assert_array_equal(load_mesh(tmp_path / "huge.gltf").vertices,
                                  [[0, 0, 0], [1e300, 0, 0], [0, 1e300, 0]])
    doc["nodes"][0]["scale"] = [1e308] * 3
    doc["nodes"][0]["translation"] = [1e308, 0, 0]
    (tmp_path / "past.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneFormatError, match=r"past\.gltf: a vertex lands at \(inf"):
        load_mesh(tmp_path / "past.gltf")


_PLY_HEADER = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
               "end_header\n")


@pytest.mark.parametrize("text, words", [
    ("ply\nformat ascii 1.0\nelement vertex 3\n", "its header stops before 'end_header'"),
    (_PLY_HEADER + "0 0 0\n1 0\n0 1 0\n3 0 1 2\n",
     "line 11: vertex 1 has 2 values where the header's properties need 3"),
    (_PLY_HEADER + "0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", "line 11: 'x' is not a number"),
    (_PLY_HEADER + "0 0 0\n1 0 0\n", "it ends after 2 of the 3 vertex lines"),
    (_PLY_HEADER.replace("float x", "flot x") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
     "header line 4: property 'x' has type 'flot', which PLY does not define"),
    (_PLY_HEADER.replace("ascii", "binary_little_endian") + "\0\0\0\0",
     "cannot be read as a PLY mesh: its data does not match its header \\(damaged or cut "
     "short\\)"),
])
def test_a_damaged_ply_is_refused_in_plain_words(tmp_path, text, words):
    """trimesh's own words named its internals ("IndexError: list index out of range" for
    a header cut short, "setting an array element with a sequence" for a short line)."""
    with pytest.raises(SceneFormatError, match=f"d\\.ply: {words}") as caught:
        load_mesh(_write(tmp_path, "d.ply", text))
    assert "Error" not in str(caught.value)


@pytest.mark.parametrize("change", [
    lambda header: header.replace("uchar int vertex", "uchar int64 vertex"),
    lambda header: header.replace("float z", "float16 z"),
])
def test_a_ply_trimesh_reads_is_not_refused_by_the_header_check(tmp_path, change):
    """64-bit and half types are read by trimesh though PLY's own list lacks them: the
    check refused them as types PLY does not define."""
    mesh = load_mesh(_write(tmp_path, "ok.ply", change(_PLY_HEADER) + "0 0 0\n1 0 0\n0 1 0\n"
                            "3 0 1 2\n"))
    assert len(mesh.vertices) == 3 and len(mesh.triangles) == 1


@pytest.mark.parametrize("change, words", [
    (lambda doc: doc.pop("bufferViews"), "accessor 0 names buffer view 0, but the file has "
     "no buffer views"),
    (lambda doc: doc.update(accessors=[]), "mesh 0 primitive 0's POSITION names accessor 0, "
     "but the file has no accessors"),
    (lambda doc: doc["meshes"][0]["primitives"][0].update(indices=4),
     "mesh 0 primitive 0's indices names accessor 4, but the file has 1 accessor "),
    (lambda doc: doc["accessors"][0].update(componentType=1),
     "accessor 0 has component type 1, which glTF does not define"),
    (lambda doc: doc["accessors"][0].update(count=300), "cannot be read as a glTF mesh: its "
     "data is damaged"),
])
def test_a_damaged_gltf_is_refused_in_plain_words(tmp_path, change, words):
    """trimesh's own words named its internals ("UnboundLocalError: cannot access local
    variable 'access'" for a file without buffer views)."""
    import json

    doc = _one_triangle_gltf()
    change(doc)
    (tmp_path / "d.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneFormatError, match=f"d\\.gltf: .*{words}") as caught:
        load_mesh(tmp_path / "d.gltf")
    assert "Error" not in str(caught.value)


def test_glb_base_colour_texture_and_node_transforms(tmp_path):
    import trimesh
    from trimesh.visual.material import PBRMaterial
    from trimesh.visual.texture import TextureVisuals

    quad = trimesh.Trimesh(
        vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
        faces=[[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    img = np.zeros((8, 8, 3), np.uint8)
    img[:4] = (255, 0, 0)  # top red
    img[4:] = (0, 0, 255)  # bottom blue
    material = PBRMaterial(
        baseColorFactor=[128, 255, 255, 255], baseColorTexture=Image.fromarray(img)
    )
    quad.visual = TextureVisuals(uv=[[0, 0], [1, 0], [1, 1], [0, 1]], material=material)
    plain = _tm_box()
    plain.visual = trimesh.visual.ColorVisuals(plain, vertex_colors=[64, 128, 255, 255])
    scene = trimesh.Scene()
    scene.add_geometry(quad, node_name="quad")
    shift = trimesh.transformations.translation_matrix([10, 0, 0])
    scene.add_geometry(plain, node_name="box", transform=shift)
    scene.export(tmp_path / "s.glb")

    mesh = load_mesh(tmp_path / "s.glb")
    assert len(mesh) == 2 + 12
    lo, hi = mesh.bounds
    np.testing.assert_allclose(lo, [0, -0.5, -0.25])
    np.testing.assert_allclose(hi, [11, 1, 0.25])
    textured = mesh.face_texture >= 0
    assert textured.sum() == 2 and len(mesh.textures) == 1
    np.testing.assert_allclose(mesh.face_color[textured], [[128 / 255, 1, 1]] * 2, atol=1e-6)
    # glTF vertex colours are linear: no sRGB decode.
    box_vc = mesh.vertex_color[mesh.triangles[~textured]].reshape(-1, 3)
    np.testing.assert_allclose(box_vc - [64 / 255, 128 / 255, 1], 0.0, atol=1e-6)

    from voxfield.scene.voxelize import surface_color

    top = surface_color(mesh, np.array([np.flatnonzero(textured)[0]]), np.array([[0, 0.1, 0.9]]))
    np.testing.assert_allclose(top, [[128 / 255, 0, 0]], atol=1e-6)  # (1, 0, 0) texel × factor


# --------------------------------------------------------------------------------------------
# Real data


def _mesh_file(*parts):
    path = data_root().joinpath("mesh", *parts)
    if not path.is_file():
        pytest.skip(f"shared data file {path} is absent (set VOXFIELD_DATA to the data folder)")
    return path


def _obj_vertex_extents(path):
    """Independent reading: min/max over every 'v' line of the file."""
    rows = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if parts and parts[0] == "v":
            rows.append([float(x) for x in parts[1:4]])
    rows = np.array(rows)
    return rows.min(axis=0), rows.max(axis=0)


def test_cornell_original_loads_with_its_true_extents():
    path = _mesh_file("cornell", "CornellBox-Original.obj")
    mesh = load_mesh(path)
    lo, hi = _obj_vertex_extents(path)
    np.testing.assert_allclose(mesh.bounds[0], lo, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mesh.bounds[1], hi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mesh.extents, [2.02, 1.99, 2.03], atol=1e-12)
    assert len(mesh.vertices) == 72 and len(mesh) == 36  # 18 quads
    red = np.all(np.isclose(mesh.face_color, [0.63, 0.065, 0.05]), axis=1)
    assert red.sum() == 2 and (mesh.vertices[mesh.triangles[red]][..., 0] < -0.98).all()


@pytest.mark.parametrize(
    "name", ["CornellBox-Sphere.obj", "CornellBox-Water.obj", "CornellBox-Glossy.obj"]
)
def test_other_cornell_variants_load(name):
    path = _mesh_file("cornell", name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Glossy names a 'light' material its MTL lacks
        mesh = load_mesh(path)
    lo, hi = _obj_vertex_extents(path)
    assert (mesh.bounds[0] >= lo - 1e-12).all() and (mesh.bounds[1] <= hi + 1e-12).all()
    assert np.isclose(mesh.extents[0], 2.02, atol=0.01)


@pytest.mark.parametrize(
    "name, n_verts, n_tris", [("bunny.obj", 34835, 69666), ("dragon.obj", 50000, 100000)]
)
def test_stanford_meshes_load(name, n_verts, n_tris):
    path = _mesh_file("stanford", name)
    with pytest.warns(UserWarning, match="material library"):
        mesh = load_mesh(path)
    assert len(mesh.vertices) == n_verts and len(mesh) == n_tris
    lo, hi = _obj_vertex_extents(path)
    np.testing.assert_allclose(mesh.bounds[0], lo, atol=1e-12)
    np.testing.assert_allclose(mesh.bounds[1], hi, atol=1e-12)
    np.testing.assert_allclose(mesh.face_color, np.full((n_tris, 3), np.float32(0.8)))


def _one_triangle_gltf(materials=None, material=None, **top) -> dict:
    """A glTF document of one triangle, its buffer inline."""
    import base64

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    primitive = {"attributes": {"POSITION": 0}}
    if material is not None:
        primitive["material"] = material
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}], "meshes": [{"primitives": [primitive]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": len(positions)}],
        "buffers": [{"byteLength": len(positions), "uri": "data:application/octet-stream;"
                     "base64," + base64.b64encode(positions).decode()}],
        **top,
    }
    if materials is not None:
        doc["materials"] = materials
    return doc


def _as_glb(doc: dict) -> bytes:
    import json
    import struct

    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    return struct.pack("<4sIIII", b"glTF", 2, 20 + len(text), len(text), 0x4E4F534A) + text


def test_gltf_emissive_strength_scales_the_emission(tmp_path):
    # Blender writes KHR_materials_emissive_strength for every emission stronger than 1
    import json

    glowing = {"emissiveFactor": [1.0, 0.5, 0.0],
               "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5.0}}}
    doc = _one_triangle_gltf([glowing], material=0,
                             extensionsUsed=["KHR_materials_emissive_strength"])
    (tmp_path / "glow.gltf").write_text(json.dumps(doc))
    (tmp_path / "glow.glb").write_bytes(_as_glb(doc))
    for name in ("glow.gltf", "glow.glb"):
        mesh = load_mesh(tmp_path / name)
        np.testing.assert_allclose(mesh.face_emission, [[5.0, 2.5, 0.0]])


def test_gltf_without_a_material_is_white(tmp_path):
    # the glTF specification's default material: base colour factor 1 (OBJ's default is grey)
    import json

    (tmp_path / "plain.gltf").write_text(json.dumps(_one_triangle_gltf()))
    np.testing.assert_array_equal(load_mesh(tmp_path / "plain.gltf").face_color, [[1, 1, 1]])


def test_gltf_requiring_mesh_compression_is_refused(tmp_path):
    # trimesh reads Draco-compressed positions as zeros: a degenerate or misplaced mesh
    import json

    doc = _one_triangle_gltf(extensionsUsed=["KHR_draco_mesh_compression"],
                             extensionsRequired=["KHR_draco_mesh_compression"])
    doc["meshes"][0]["primitives"][0]["extensions"] = {
        "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
    (tmp_path / "draco.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneFormatError, match="compressed with KHR_draco_mesh_compression"):
        load_mesh(tmp_path / "draco.gltf")


def test_a_textured_material_on_a_file_without_texture_coordinates(tmp_path):
    # no 'vt' line at all: the texture cannot be placed, the material's colour is used
    Image.fromarray(np.full((2, 2, 3), 200, np.uint8)).save(tmp_path / "t.png")
    _write(tmp_path, "t.mtl", "newmtl T\nKd 0.5 0.25 1\nmap_Kd t.png\n")
    path = _write(tmp_path, "t.obj", "mtllib t.mtl\nusemtl T\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                  "f 1 2 3\n")
    with pytest.warns(UserWarning, match="no texture coordinates"):
        mesh = load_mesh(path)
    np.testing.assert_allclose(mesh.face_color, [[0.5, 0.25, 1.0]])
    assert mesh.face_texture is None or np.all(mesh.face_texture < 0)
