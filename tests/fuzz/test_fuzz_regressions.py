"""What the fuzz suite and the reliability campaign found, pinned as plain tests."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from cli_output import one_error_line
from voxfield.cli import main
from voxfield.data import data_root
from voxfield.errors import OctreeFormatError, SceneFormatError
from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_folder import ProbeFileError, ProbeHeaderError, open_probe_set
from voxfield.probes.probe_set import BakeOptions
from voxfield.scene.builtin import cornell
from voxfield.scene.mesh import load_mesh
from voxfield.scene.npz_io import load_scene_npz
from voxfield.scene.terrain.dem import load_heightmap
from voxfield.scene.voxelize import voxelize_mesh
from voxfield.svo import build_octree, load_octree, save_octree
from voxfield.svo.open import open_octree


def refused_render(scene, capsys, *options: str) -> str:
    """The one error line of a ``voxfield render`` of ``scene`` that must exit 2 and write
    no picture."""
    out = Path(scene).parent / "refused.png"
    assert main(["render", str(scene), *options, "--quiet", "--out", str(out)]) == 2
    assert not out.exists()
    return one_error_line(capsys)


def test_a_triangle_with_two_equal_vertices_is_skipped(tmp_path):
    """``f 6 5 4`` with vertices 5 and 6 equal once divided by zero inside the voxelizer."""
    path = tmp_path / "degenerate.obj"
    path.write_text("v 0 0 0\nv 4 0 0\nv 0 4 0\nv 0 0 4\nv 2 2 2\nv 2 2 2\n"
                    "f 1 2 3\nf 6 5 4\nf 1 1 1\n")
    scene = voxelize_mesh(load_mesh(path), resolution=16)
    assert len(scene) > 0


def test_a_segment_triangle_voxelizes_along_its_segment(tmp_path):
    """A collinear triangle is a segment: the voxels it passes through, on the diagonal."""
    path = tmp_path / "flat.obj"
    path.write_text("v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n")
    coords = voxelize_mesh(load_mesh(path), resolution=8).coords
    assert len(coords) > 0
    spread = coords - coords.mean(axis=1, keepdims=True)
    assert np.abs(spread).max() <= 1  # x, y and z stay together along the diagonal


def test_far_away_geometry_is_voxelized_or_refused(tmp_path):
    path = tmp_path / "far.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1e30 1e30 1e30\nf 1 2 3\nf 1 2 4\n")
    voxelize_mesh(load_mesh(path), resolution=32)  # no exception


@pytest.mark.parametrize("keep", [200, 4096])
def test_a_truncated_geotiff_is_one_clear_error(tmp_path, keep):
    source = data_root() / "terrain" / "dem_srtm30.tif"
    if not source.is_file():
        pytest.skip(f"{source} is not in the shared data folder")
    path = tmp_path / "cut.tif"
    path.write_bytes(source.read_bytes()[:keep])
    with pytest.raises(SceneFormatError, match="cut.tif"):
        load_heightmap(str(path))


def test_tiff_magic_then_noise_is_one_clear_error(tmp_path):
    path = tmp_path / "noise.tif"
    path.write_bytes(b"II*\0" + bytes(range(256)) * 3)
    with pytest.raises(SceneFormatError):
        load_heightmap(str(path))


def test_an_octree_with_empty_level_offsets_is_refused(tmp_path):
    good = tmp_path / "good.npz"
    save_octree(open_octree("builtin:menger"), good)
    with np.load(good, allow_pickle=False) as data:
        arrays = {k: np.array(data[k]) for k in data.files}
    for name, value in (("level_offsets", np.zeros(0, np.int64)),
                        ("scene_origin", np.array([np.nan, 0, 0]))):
        bad = tmp_path / f"bad_{name}.npz"
        buffer = io.BytesIO()
        np.savez(buffer, **{**arrays, name: value})
        bad.write_bytes(buffer.getvalue())
        with pytest.raises(OctreeFormatError):
            load_octree(bad)


@pytest.mark.parametrize("option", ["--seed", "--size", "--camera"])
def test_an_option_given_the_end_of_options_marker_is_refused(tmp_path, option, capsys):
    """``--seed=--`` once reached the command as an empty list (argparse drops "--")."""
    with pytest.raises(SystemExit) as exc:
        main(["render", "builtin:sphere", f"{option}=--", "--out", str(tmp_path / "x.png")])
    assert exc.value.code == 2
    assert f"argument {option}: expected a value" in capsys.readouterr().err


@pytest.mark.parametrize("value", [None, [], 9.3e18, -1, 2.5, "3", True])
def test_a_probe_record_with_a_bad_cost_is_a_header_error(tmp_path, value):
    """A cost of null, a list or 2**63 in ``probes.json`` once raised TypeError/OverflowError."""
    folder = _one_probe_folder(tmp_path)
    _edit_header(folder, lambda header: header["probes"]["0"].update(geometry_rays=value))
    with pytest.raises(ProbeHeaderError, match="geometry_rays"):
        open_probe_set(folder)


def test_complex_colours_in_a_scene_file_are_refused(tmp_path):
    path = tmp_path / "complex.npz"
    np.savez(path, coords=np.zeros((1, 3), np.int32), color=np.ones((1, 3), np.complex64))
    with pytest.raises(SceneFormatError, match="real numbers"):
        load_scene_npz(path)


def _one_probe_folder(tmp_path):
    octree = build_octree(cornell(8))
    lo, hi = octree.voxel_bounds
    folder = tmp_path / "set"
    bake_to_folder(octree, ProbeGrid.fit(lo, hi, (1, 1, 2)),
                   BakeOptions(resolution=4, renderer="lod", lod=0), folder, scheduler="serial")
    return folder


def _edit_header(folder, change) -> None:
    """Apply ``change`` to the folder's ``probes.json`` (as a dict)."""
    header = json.loads((folder / "probes.json").read_text())
    change(header)
    (folder / "probes.json").write_text(json.dumps(header))


@pytest.mark.parametrize("count", [None, float("nan"), 1.5, -1, True, "2"])
def test_a_header_with_a_bad_probe_count_is_a_header_error(tmp_path, count):
    """A probe_count of NaN, inf or null once raised ValueError/OverflowError/TypeError."""
    folder = _one_probe_folder(tmp_path)
    _edit_header(folder, lambda header: header.update(probe_count=count))
    with pytest.raises(ProbeHeaderError, match="probe_count"):
        open_probe_set(folder)


def test_a_probe_file_whose_compressed_data_is_damaged_is_a_file_error(tmp_path):
    """One zeroed byte inside a deflate stream raised zlib.error, which is no OSError."""
    folder = _one_probe_folder(tmp_path)
    path = folder / "probe_00000.npz"
    data = bytearray(path.read_bytes())
    data[70] = 0
    path.write_bytes(bytes(data))
    with pytest.raises(ProbeFileError, match="probe_00000.npz"):
        open_probe_set(folder)


def test_a_probe_record_that_is_not_an_object_is_a_header_error(tmp_path):
    folder = _one_probe_folder(tmp_path)
    _edit_header(folder, lambda header: header["probes"].update({"1": 5}))
    with pytest.raises(ProbeHeaderError, match="probe 1.s record"):
        open_probe_set(folder)


@pytest.mark.parametrize("scene", [None, {}, {"fingerprint": 7}, "cornell"])
def test_a_header_without_a_scene_fingerprint_is_a_header_error(tmp_path, scene):
    folder = _one_probe_folder(tmp_path)
    _edit_header(folder, lambda header: header.update(scene=scene))
    with pytest.raises(ProbeHeaderError, match="fingerprint"):
        open_probe_set(folder)


@pytest.mark.parametrize("arrays, words", [
    ({"spacing": [1.0, 2.0, 3.0]}, "unreadable coordinates or spacing"),
    ({"spacing": ["a"]}, "unreadable coordinates or spacing"),
    ({"dx": np.ones(3), "dy": 1.0, "xmin": 0.0, "xmax": 9.0, "ymin": 0.0, "ymax": 9.0},
     "unreadable coordinates or spacing"),
    ({"latitude": np.array(["a"] * 10), "longitude": np.arange(10.0)},
     "unreadable coordinates or spacing"),
    # Dropped without a word, the terrain built as if unplaced (no true scale).
    ({"latitude": np.linspace(35.0, 36.0, 9), "longitude": np.linspace(139.0, 140.0, 10)},
     "unreadable coordinates or spacing (latitude has 9 values for 10 rows and longitude "
     "10 for 10 columns)"),
    ({"latitude": np.r_[np.nan, np.linspace(35.0, 36.0, 9)],
      "longitude": np.linspace(139.0, 140.0, 10)}, "latitude or longitude holds NaN"),
    ({"latitude": np.linspace(85.0, 99.0, 10), "longitude": np.linspace(139.0, 140.0, 10)},
     "latitudes run 85..99, past ±90°"),
    ({"dx": 0.0, "dy": 1.0, "xmin": 0.0, "xmax": 9.0, "ymin": 0.0, "ymax": 9.0},
     "dx and dy must be positive sample spacings, got 0 and 1"),
    ({"dx": 1.0, "dy": -2.0, "xmin": 0.0, "xmax": 9.0, "ymin": 0.0, "ymax": 9.0},
     "dx and dy must be positive sample spacings, got 1 and -2"),
    # Metres per voxel that multiply to zero divided by zero in the column builder.
    ({"dx": 1e-300, "dy": 1e-300, "xmin": 0.0, "xmax": 1e-299, "ymin": 0.0, "ymax": 1e-299},
     "spacing must be at least"),
])
def test_dem_npz_metadata_that_is_not_numbers_is_one_clear_error(tmp_path, capsys, arrays,
                                                                  words):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=np.arange(100.0).reshape(10, 10), **arrays)
    assert words in refused_render(path, capsys, "--footprint", "32")


@pytest.mark.parametrize("heights, words", [
    # Their range overflows: every column once became a one-voxel slab, exit 0.
    ([[0.0, 1.7e308], [0.0, -1.7e308]], "span more than a number can hold"),
    # A range of one denormal metre: its voxels per metre overflow.
    ([[0.0, 5e-324], [0.0, 0.0]], "too little to scale"),
])
def test_heights_whose_range_cannot_be_scaled_are_refused(tmp_path, capsys, heights, words):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=np.array(heights))
    assert words in refused_render(path, capsys, "--footprint", "32")


@pytest.mark.parametrize("text, words", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n", "malformed face"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/99999999999999999999 2/1 3/1\n",
     "malformed face"),
    ("v 0 0 0\nv 5e-324 0 0\nv 0 5e-324 0\nf 1 2 3\n", "too small to voxelize"),
])
def test_obj_indices_past_int64_and_denormal_meshes_are_one_clear_error(tmp_path, capsys,
                                                                        text, words):
    path = tmp_path / "m.obj"
    path.write_text(text)
    assert words in refused_render(path, capsys)


def test_a_texture_claiming_a_huge_size_is_skipped_with_a_note(tmp_path, capsys):
    """Pillow refuses an image past its decompression-bomb limit with its own error."""
    Image.MAX_IMAGE_PIXELS, before = 500, Image.MAX_IMAGE_PIXELS  # 40² is past twice it
    try:
        Image.fromarray(np.zeros((40, 40, 3), np.uint8)).save(tmp_path / "big.png")
        (tmp_path / "m.mtl").write_text("newmtl a\nKd 0.5 0.5 0.5\nmap_Kd big.png\n")
        (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                        "vt 0 0\nvt 1 0\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3\n")
        assert main(["info", str(tmp_path / "m.obj")]) == 0
    finally:
        Image.MAX_IMAGE_PIXELS = before
    assert "cannot be read" in capsys.readouterr().err


def test_a_probe_header_nested_past_the_recursion_limit_is_one_clear_error(tmp_path):
    bake_to_folder(build_octree(cornell(16)), ProbeGrid.fit([2, 2, 2], [14, 14, 14], [1, 1, 1]),
                   BakeOptions(resolution=4), tmp_path / "p")
    (tmp_path / "p" / "probes.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ProbeHeaderError, match="unreadable header"):
        open_probe_set(tmp_path / "p")


def test_probe_records_swapped_in_the_header_are_caught(tmp_path):
    """Each record's file and checksum agree, so only the file's name tells that probe 0's
    record now points at probe 1's maps."""
    folder = tmp_path / "p"
    bake_to_folder(build_octree(cornell(16)), ProbeGrid.fit([2, 2, 2], [14, 14, 14], [2, 1, 1]),
                   BakeOptions(resolution=4), folder)
    header = json.loads((folder / "probes.json").read_text())
    header["probes"]["0"], header["probes"]["1"] = header["probes"]["1"], header["probes"]["0"]
    (folder / "probes.json").write_text(json.dumps(header))
    with pytest.raises(ProbeFileError, match="probe 0"):
        open_probe_set(folder)


@pytest.mark.parametrize("line", ["Ke 1e39 0 0", "Kd 0.5 -1e39 0.5"])
def test_an_mtl_colour_past_single_precision_is_one_line(tmp_path, capsys, line):
    """It passed the finite check in double precision and overflowed when stored: two
    NumPy notes before the error."""
    (tmp_path / "m.mtl").write_text(f"newmtl a\n{line}\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\n"
                                    "f 1 2 3\n")
    assert "not a finite colour" in refused_render(tmp_path / "m.obj", capsys)


@pytest.mark.parametrize("vt", ["1e300 0", "0.5 -1e39"])
def test_a_texture_coordinate_past_single_precision_is_one_line(tmp_path, capsys, vt):
    """It overflowed when stored as float32: two NumPy notes before the error."""
    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "t.png")
    (tmp_path / "m.mtl").write_text("newmtl a\nmap_Kd t.png\n")
    (tmp_path / "m.obj").write_text(f"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt {vt}\n"
                                    "vt 0 1\nvt 1 1\nusemtl a\nf 1/1 2/2 3/3\n")
    assert "texture coordinates contain NaN or infinite" in refused_render(tmp_path / "m.obj",
                                                                           capsys)


@pytest.mark.parametrize("field", ["color", "emission"])
def test_a_voxel_colour_past_single_precision_is_one_line(tmp_path, capsys, field):
    arrays = {"coords": np.array([[0, 0, 0], [1, 0, 0]]),
              "color": np.array([[1.0, 0.0, 0.0], [0.5, 0.5, 0.5]]),
              "emission": np.zeros((2, 3))}
    arrays[field][0, 0] = 1e300
    np.savez(tmp_path / "s.npz", **arrays)
    assert f"{field} holds NaN or infinite values" in refused_render(tmp_path / "s.npz", capsys)


@pytest.mark.parametrize("shape", [(1, 1000), (1000, 1)])
def test_a_one_row_tiff_says_what_a_dem_needs(tmp_path, capsys, shape):
    """It was called "an RGB image?"."""
    path = tmp_path / "strip.tif"
    Image.fromarray(np.zeros(shape, np.int16)).save(path)
    assert main(["info", str(path), "--quiet"]) == 2
    assert "2×2" in one_error_line(capsys)
