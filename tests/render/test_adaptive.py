"""Variance-adaptive baseline: the thesis's cut-offs, background exclusion and ray counting."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.render import Camera
from voxfield.render.adaptive import (
    CLASS_SIDE,
    refinement_classes,
    render_adaptive,
    window_variance,
)
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree


def test_classes_follow_the_cut_offs_on_a_synthetic_variance_image():
    variance = np.array([[0.0, 0.249, 0.25, 0.5], [0.749, 0.75, 1.0, 7.0]])
    valid = np.ones_like(variance, bool)
    valid[0, 0] = False
    assert refinement_classes(variance, valid).tolist() == [[-1, 0, 1, 1], [1, 2, 2, 2]]


def test_window_variance_matches_a_direct_computation_and_skips_background():
    rng = np.random.default_rng(0)
    lum = rng.random((7, 9))
    valid = rng.random((7, 9)) > 0.3
    got = window_variance(lum, valid)
    for y in range(7):
        for x in range(9):
            if not valid[y, x]:
                assert got[y, x] == 0
                continue
            win = lum[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2]
            ok = valid[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2]
            vals = win[ok]
            assert np.isclose(got[y, x], np.sum((vals - vals.mean()) ** 2))


def test_refined_pixels_add_rays_by_class():
    # Black and white stripes: every window straddling an edge has high variance.
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], 1)
    color = np.repeat(((x.ravel() // 4) % 2)[:, None], 3, axis=1).astype(float)
    octree = build_octree(VoxelScene(coords, color))
    cam = Camera.orthographic((16, 5, 16), (0, -1, 0), (0, 0, -1), view_height=32, width=32)
    result = render_adaptive(octree, cam, base_lod=0)
    classes = result.maps["refinement_class"]
    expected = np.choose(classes.clip(0), [1 + s * s if s > 1 else 1 for s in CLASS_SIDE])
    assert np.array_equal(result.ray_count, expected)
    assert (classes == 2).any() and (classes == 0).any()
    # Flat regions away from edges keep their single ray.
    assert result.ray_count[16, 2] == 1


def _stripes():
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], 1)
    color = np.repeat(((x.ravel() // 4) % 2)[:, None], 3, axis=1).astype(float)
    cam = Camera.orthographic((16, 5, 16), (0, -1, 0), (0, 0, -1), view_height=32, width=32)
    return build_octree(VoxelScene(coords, color)), cam


def test_iterations_past_the_last_change_change_nothing():
    # A pixel's class only rises and tops out at 2, so the refinement settles; the loop stops
    # there, and a large count returns what a few do.
    octree, cam = _stripes()
    few = render_adaptive(octree, cam, base_lod=0, iterations=3)
    many = render_adaptive(octree, cam, base_lod=0, iterations=1000)
    for name in ("image", "ray_count", "steps"):
        assert np.array_equal(getattr(few, name), getattr(many, name)), name
    for name in ("variance", "refinement_class"):
        assert np.array_equal(few.maps[name], many.maps[name]), name


@pytest.mark.parametrize(("options", "message"), [
    ({"iterations": 1.5}, "iterations must be an integer"),
    ({"iterations": True}, "iterations must be an integer"),
    ({"iterations": -1}, "iterations must be an integer ≥ 0"),
    ({"variance_normalisation": "1"}, "variance normalisation must be a number"),
    ({"variance_normalisation": 0.0}, "must be positive"),
])
def test_bad_options_are_refused(options, message):
    octree, cam = _stripes()
    with pytest.raises(VoxfieldError, match=message):
        render_adaptive(octree, cam, base_lod=0, **options)
