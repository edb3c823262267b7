"""Renders that cross the air in the column-top pyramid are the octree's renders, pixel for
pixel, in every renderer that traces at a fixed level or with a cone."""

from __future__ import annotations

import numpy as np
import pytest
from tests.random_scenes import overhanging_terrain

from voxfield.error_table import build_error_table
from voxfield.render import Camera, render_lod, render_reference
from voxfield.render.adaptive import render_adaptive
from voxfield.render.error_aware import render_error_aware
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

_SAME = ("image", "depth", "normal", "hit_count", "ray_count", "finest_lod")


@pytest.fixture(scope="module")
def scene():
    """Ground with ledges, caves and hollows: rays land on tops, on sides, under overhangs,
    and miss past the edges."""
    return build_octree(overhanging_terrain(seed=4, size=40))


@pytest.fixture(scope="module")
def tall_scene():
    """The same ground with one voxel 40,000 voxels above it: a pyramid with int32 heights
    (``svo.column_tops.height_type``), whose records the lanes walk as they walk int16."""
    ground = overhanging_terrain(seed=4, size=40)
    spire = np.array([[0, 40_000, 0]])
    return build_octree(VoxelScene(np.concatenate([ground.coords, spire]),
                                   np.concatenate([ground.color, [[1.0, 1.0, 1.0]]]),
                                   name="tall"))


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


@pytest.mark.parametrize("lod", [0, 1])
def test_a_batch_without_its_walk_hands_every_ray_to_the_octree(scene, monkeypatch, lod):
    """Fixed-level renders compile only the lane walk of their level
    (``primary.walks_for_level``); a batch left without it (None for both) sends its rays to
    the octree from their starts: the same pixels, in other steps (more of them here). Where
    the lanes do not pay (Numba compiling for AVX2: ``LANE_WALK_PAYS``) every batch takes
    the one-ray walk, which the flags do not select: the same pixels and steps."""
    from voxfield.kernels import primary
    from voxfield.kernels.lane_walk import LANE_WALK_PAYS

    assert primary.walks_for_level(12, 12) == (True, None)
    assert primary.walks_for_level(11, 12) == (None, True)
    camera = _cameras(scene)[0]
    walked = render_lod(scene, camera, lod=lod, columns=True)
    monkeypatch.setattr(primary, "walks_for_level", lambda stop_level, depth: (None, None))
    unwalked = render_lod(scene, camera, lod=lod, columns=True)
    _assert_same(walked, unwalked)
    if LANE_WALK_PAYS:
        assert unwalked.steps.sum() > walked.steps.sum()
    else:
        assert np.array_equal(unwalked.steps, walked.steps)


@pytest.mark.parametrize("side", [1, 2])
def test_cone_lod_renders_are_unchanged(scene, side):
    """Cone-LOD rays walk the pyramid as their cone allows (``kernels.cone_walk``): the
    same pixels from every camera, with and without start bounds; the steps count its
    cells."""
    walked = 0
    for camera in _cameras(scene):
        for beam in (True, False):
            a = render_lod(scene, camera, lod=None, side=side, beam=beam, columns=True)
            b = render_lod(scene, camera, lod=None, side=side, beam=beam, columns=False)
            _assert_same(a, b)
            walked += int(not np.array_equal(a.steps, b.steps))
    assert walked == 2 * len(_cameras(scene))


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


@pytest.mark.parametrize("tall", [False, True])
def test_rays_traced_in_batches_step_as_each_ray_alone(scene, tall_scene, tall):
    """A render walks its rays in batches (``kernels.primary.RAY_BATCH``) before it settles
    and shades them: the same pixels as the octree alone, partial batches and batches across
    pixels included, and every pixel's steps those of its rays traced one by one
    (``trace_over_columns`` from where the pixel's start bound lets rays start,
    ``beam.start_distance``) plus its share of the bound's. So too in a world whose pyramid
    keeps int32 heights."""
    from voxfield.kernels.beam import start_distance
    from voxfield.kernels.primary import RAY_BATCH
    from voxfield.kernels.surface_approach import trace_over_columns
    from voxfield.kernels.traversal import new_scratch
    from voxfield.render.beam import pixel_start_bounds
    from voxfield.svo.column_tops import octree_column_tops

    lo, hi = scene.voxel_bounds  # (the ground's, with the spire or without)
    if tall:
        scene = tall_scene
        assert octree_column_tops(scene).tops.dtype == np.int32
    c = (lo + hi) / 2
    # 37 × 37 pixels: chunks of 64 pixels end in partial batches; 9 rays a pixel straddle
    # batches.
    camera = Camera.look_at((c[0] + 3, hi[1] + 30, c[2] + 1), tuple(c), fov_deg=70, width=37)
    assert (37 * 37) % 64 % RAY_BATCH != 0 and RAY_BATCH % 9 != 0
    for lod in (0, 1):
        on = render_lod(scene, camera, lod=lod, columns=True)
        _assert_same(on, render_lod(scene, camera, lod=lod, columns=False))
        stop_level = scene.depth - lod
        columns = octree_column_tops(scene)
        bounds = pixel_start_bounds(scene, camera, columns, stop_level=stop_level)
        # The raster's bound, one per pixel; a block's where the spire's cells cross the
        # eye plane.
        assert bounds.block == (8 if tall else 1)
        block = bounds.block
        starts = np.repeat(np.repeat(bounds.bound, block, 0), block, 1)
        starts = starts[:camera.height, :camera.width].reshape(-1)
        origins, directions = camera.rays(side=1)
        scratch = new_scratch(scene.depth)
        alone = np.zeros(len(starts), np.int64)
        for k in np.flatnonzero(starts < np.inf):
            alone[k] = trace_over_columns(*origins[k], *directions[k],
                                          start_distance(starts[k]), np.inf,
                                          scene.inner_nodes, scene.depth, stop_level,
                                          scratch, columns)[4]
        drawn = bounds.image_steps(camera.height, camera.width).reshape(-1)
        assert np.array_equal(on.steps.reshape(-1), alone + drawn)
    _assert_same(render_reference(scene, camera, side=3, seed=2, columns=True),
                 render_reference(scene, camera, side=3, seed=2, columns=False))
