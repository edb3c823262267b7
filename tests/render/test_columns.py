"""Renders that cross the air in the column-top pyramid are the octree's renders, pixel for
pixel, in every renderer that traces at a fixed level."""

from __future__ import annotations

import numpy as np
import pytest
from tests.random_scenes import overhanging_terrain

from voxfield.error_table import build_error_table
from voxfield.render import Camera, render_lod, render_reference
from voxfield.render.adaptive import render_adaptive
from voxfield.render.error_aware import render_error_aware
from voxfield.svo import build_octree

_SAME = ("image", "depth", "normal", "hit_count", "ray_count", "finest_lod")


@pytest.fixture(scope="module")
def scene():
    """Ground with ledges, caves and hollows: rays land on tops, on sides, under overhangs,
    and miss past the edges."""
    return build_octree(overhanging_terrain(seed=4, size=40))


def _cameras(octree):
    lo, hi = octree.voxel_bounds
    c = (lo + hi) / 2
    return [
        Camera.look_at((c[0] + 3, hi[1] + 30, c[2] + 1), tuple(c), fov_deg=70, width=40),
        Camera.look_at((lo[0] - 10, hi[1] + 6, lo[2] - 14), tuple(c), fov_deg=60, width=40),
        Camera.look_at((c[0], lo[1] + 1.5, c[2]), (hi[0], lo[1] + 4, hi[2]), fov_deg=80,
                       width=40),  # low, inside the scene, looking across it
    ]


def _assert_same(a, b):
    for name in _SAME:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


@pytest.mark.parametrize("beam", [True, False])
def test_lod_and_reference_renders_are_unchanged(scene, beam):
    for camera in _cameras(scene):
        for lod in (0, 1, 3):
            _assert_same(render_lod(scene, camera, lod=lod, beam=beam, columns=True),
                         render_lod(scene, camera, lod=lod, beam=beam, columns=False))
        _assert_same(render_reference(scene, camera, side=2, seed=5, beam=beam, columns=True),
                     render_reference(scene, camera, side=2, seed=5, beam=beam, columns=False))


def test_cone_lod_does_not_use_the_pyramid(scene):
    """The cone's node size grows along the ray, so its rays stay in the octree: steps too."""
    camera = _cameras(scene)[1]
    a = render_lod(scene, camera, lod=None, columns=True)
    b = render_lod(scene, camera, lod=None, columns=False)
    _assert_same(a, b)
    assert np.array_equal(a.steps, b.steps)


def test_error_aware_and_adaptive_renders_are_unchanged(scene):
    table = build_error_table(n_directions=32, resolution=32, oct_resolution=8, seed=0)
    for camera in _cameras(scene)[:2]:
        for reuse in (False, True):
            on = render_error_aware(scene, camera, table, threshold=0.2, base_lod=2,
                                    reuse_parent=reuse, seed=1, columns=True)
            off = render_error_aware(scene, camera, table, threshold=0.2, base_lod=2,
                                     reuse_parent=reuse, seed=1, columns=False)
            _assert_same(on, off)
            assert np.array_equal(on.maps["refined"], off.maps["refined"])
        _assert_same(render_adaptive(scene, camera, base_lod=1, columns=True),
                     render_adaptive(scene, camera, base_lod=1, columns=False))


def test_one_ray_pixels_shaded_in_batches_are_shaded_alike(scene, monkeypatch):
    """Over colours too large for the caches, one-ray pixels are traced in batches before
    they are shaded (``kernels.primary.SHADING_BATCH``): the same pixels, partial batches
    included."""
    from voxfield.kernels.primary import SHADING_BATCH, SHADING_BATCH_BYTES

    colors, facing = scene.kernel_colours("albedo")
    padded = np.zeros((SHADING_BATCH_BYTES // colors[:1].nbytes + 1, *colors.shape[1:]),
                      colors.dtype)
    padded[: len(colors)] = colors
    lo, hi = scene.voxel_bounds
    c = (lo + hi) / 2
    # 37 × 37 pixels: chunks of 64 pixels end in partial batches.
    camera = Camera.look_at((c[0] + 3, hi[1] + 30, c[2] + 1), tuple(c), fov_deg=70, width=37)
    assert (37 * 37) % 64 % SHADING_BATCH != 0
    plain = render_lod(scene, camera, lod=0)
    monkeypatch.setattr(type(scene), "kernel_colours", lambda self, name: (padded, facing))
    batched = render_lod(scene, camera, lod=0)
    _assert_same(plain, batched)
    assert np.array_equal(plain.steps, batched.steps)
    assert plain.hit_count.sum() > 0
