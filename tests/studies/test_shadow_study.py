"""The shadow study where its view cannot measure shadows: a scene without light is refused
with what the study needs, a view of almost no lit pixel is noted."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.render.camera import Camera
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.studies.shadow_study import run_shadow_study
from voxfield.svo import build_octree


def test_a_scene_without_emission_is_refused_with_what_it_needs(tmp_path):
    """A MagicaVoxel model or a mesh has albedo only: the study said "the octree has no
    channel 'emission'", read for its cache key, instead of asking for emitting voxels."""
    octree = build_octree(VoxelScene(np.array([[0, 0, 0], [1, 1, 1]]), np.full((2, 3), 0.5)))
    camera = Camera.look_at((5, 5, 5), (0, 0, 0), width=8)
    with pytest.raises(VoxfieldError, match="direct lighting needs emitting voxels"):
        run_shadow_study(octree, camera, tmp_path / "study")
    assert not (tmp_path / "study").exists()


@pytest.fixture(scope="module")
def lamp_over_a_floor():
    """A 16² floor (top face at y = 1) under one emitting voxel at (8, 5, 8)."""
    x, z = np.meshgrid(np.arange(16), np.arange(16), indexing="ij")
    coords = np.concatenate([np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], axis=1),
                             [(8, 5, 8)]])
    emission = np.zeros((len(coords), 3))
    emission[-1] = 12.0
    return build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5),
                                   emission=emission, name="lamp"))


def _study(octree, eye, out, **options):
    shift = np.asarray(octree.scene_origin, np.float64)
    camera = Camera.look_at(np.asarray(eye, float) - shift, np.array([8.0, 0.5, 8.5]) - shift,
                            fov_deg=40.0, width=12)
    return run_shadow_study(octree, camera, out, light_samples=2, reference_samples=4,
                            floor_samples=2, **options)


def test_a_view_of_the_floor_s_unlit_underside_is_noted(lamp_over_a_floor, tmp_path):
    """Seen from below, the floor turns its unlit face to the camera: every pixel is black in
    every render, so the PSNRs are high and say nothing of the shadows."""
    with pytest.warns(UserWarning, match=r"0\.0 % of the reference's pixels show a lit surface"):
        report = _study(lamp_over_a_floor, (8.0, -20.0, 8.6), tmp_path / "below")
    assert all(row.get("psnr", np.inf) > 50.0 for row in report["rows"])


def test_a_view_of_an_emitter_alone_is_noted(tmp_path, capsys):
    """The Cornell box from the top: its roof faces away from the lamp (no shadow ray, every
    row PSNR ∞) and the lamp shows through it, 6 % of the pixels; counted as light, they
    kept the note from speaking."""
    from voxfield.cli import main

    assert main(["shadows", "builtin:cornell", "--camera", "top", "--size", "32",
                 "--reference-samples", "4", "--light-samples", "1", "--floor-samples", "1",
                 "--quiet", "--out", str(tmp_path / "top")]) == 0
    assert ("voxfield: note: 0.0 % of the reference's pixels show a lit surface"
            in capsys.readouterr().err)


def test_a_view_of_the_lit_floor_is_not(lamp_over_a_floor, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _study(lamp_over_a_floor, (8.0, 20.0, 8.6), tmp_path / "above")


def test_the_study_is_titled_by_the_file_it_was_opened_from(lamp_over_a_floor, tmp_path):
    """As the other studies title theirs: the file's name, not the octree's (``lamp``) nor
    the whole path, which ``results.json`` keeps; from the library, the octree's name."""
    deep = "/srv/scenes/2026/lighting/lamp_over_floor.npz"
    report = _study(lamp_over_a_floor, (8.0, 20.0, 8.6), tmp_path / "named", scene_name=deep)
    assert report["scene"]["description"] == deep
    markdown = (tmp_path / "named" / "results.md").read_text(encoding="utf-8")
    assert markdown.startswith("# Shadow rays by LOD — lamp_over_floor.npz\n")
    unnamed = _study(lamp_over_a_floor, (8.0, 20.0, 8.6), tmp_path / "unnamed")
    assert "description" not in unnamed["scene"]
    assert (tmp_path / "unnamed" / "results.md").read_text(encoding="utf-8").startswith(
        "# Shadow rays by LOD — lamp\n")
