"""What the fuzz suite and the reliability campaign found, pinned as plain tests."""

from __future__ import annotations

import io

import numpy as np
import pytest

from voxfield.data import data_root
from voxfield.errors import OctreeFormatError, SceneFormatError
from voxfield.scene.mesh import load_mesh
from voxfield.scene.terrain.dem import load_heightmap
from voxfield.scene.voxelize import voxelize_mesh
from voxfield.svo import load_octree, save_octree
from voxfield.svo.open import open_octree


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
