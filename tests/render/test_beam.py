"""The beam pass: exact start bounds that change steps and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.render import Camera, orbit_camera, render_lod, render_reference
from voxfield.render.beam import no_beam, plan_beam, primary_beam
from voxfield.render.ray_query import trace
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree

SAME = ("image", "depth", "normal", "ray_count", "hit_count", "finest_lod")


@pytest.fixture(scope="module")
def octree():
    return build_octree(pillars(48))


def cameras(octree):
    lo, hi = octree.voxel_bounds
    yield orbit_camera(lo, hi, size=40)
    yield Camera.look_at((24, 90, -30), (24, 0, 24), fov_deg=70, width=37, height=29)
    yield Camera.orthographic((24, 60, 24), (0.3, -1, 0.2), (0, 0, -1), view_height=40,
                              width=33)


@pytest.mark.parametrize("lod", [0, 2, None])
def test_beam_changes_no_pixel(octree, lod):
    for cam in cameras(octree):
        on = render_lod(octree, cam, lod=lod, beam=True)
        off = render_lod(octree, cam, lod=lod, beam=False)
        for name in SAME:
            assert np.array_equal(getattr(on, name), getattr(off, name)), name
        on = render_reference(octree, cam, side=3, beam=True)
        off = render_reference(octree, cam, side=3, beam=False)
        for name in SAME:
            assert np.array_equal(getattr(on, name), getattr(off, name)), name


@pytest.mark.parametrize("lod", [0, 1, 3])
def test_bounds_never_pass_a_hit_of_their_block(lod):
    octree = build_octree(random_scene(3, n=1500, size=32))
    lo, hi = octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=48)
    for blocks in ((8,), (8, 4), (8, 4, 2, 1)):
        beam = plan_beam(octree, cam, stop_level=octree.depth - lod, blocks=blocks)
        side = 3
        origins, directions = cam.rays(side=side, seed=0)
        hits = trace(octree, origins, directions, lod=lod)
        pixel = np.arange(len(origins)) // (side * side)
        row, col = np.divmod(pixel, cam.width)
        bound = beam.bound[row // beam.block, col // beam.block]
        assert np.all(bound[hits.hit] <= hits.t[hits.hit])
        assert np.all(np.isinf(bound) <= ~hits.hit)  # an infinite bound: the block misses
        assert np.mean(bound[hits.hit] > 0) > 0.5  # and the bounds are not trivial


def test_no_bound_for_octahedral_maps_and_steps_shared_out_exactly(octree):
    probe = Camera.octahedral((24, 30, 24), resolution=16)
    assert np.all(primary_beam(octree, probe, stop_level=octree.depth).bound == 0)
    cam = next(cameras(octree))
    beam = plan_beam(octree, cam, stop_level=octree.depth, blocks=(8, 4))
    pixels = np.arange(cam.width * cam.height)
    assert beam.pixel_steps(pixels, cam.width).sum() == beam.total_steps > 0
    some = pixels[::7]
    part = plan_beam(octree, cam, stop_level=octree.depth, blocks=(8, 4), pixels=some)
    assert part.pixel_steps(some, cam.width).sum() == part.total_steps
    assert no_beam(cam).total_steps == 0


def test_image_steps_equal_the_listed_share_on_ragged_blocks(octree):
    """The sort-free whole-image share gives every pixel what ``pixel_steps`` gives it, on an
    image whose sides are not multiples of the blocks."""
    cam = Camera.look_at((24, 90, -30), (24, 0, 24), fov_deg=70, width=37, height=29)
    beam = plan_beam(octree, cam, stop_level=octree.depth, blocks=(8, 4))
    listed = beam.pixel_steps(np.arange(cam.width * cam.height), cam.width)
    image = beam.image_steps(cam.height, cam.width)
    assert image.sum() == beam.total_steps > 0
    assert np.array_equal(image, listed.reshape(cam.height, cam.width))
