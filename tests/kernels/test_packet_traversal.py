"""Packet traversal: the same hits, times, normals and steps as the scalar loop.

The scalar loop is pinned to the brute-force oracle in ``test_traversal``; here packets are
held to the oracle directly on hits and times, and to the scalar loop bit for bit on
everything, including the step counts every study compares renderers by.
"""

from __future__ import annotations

import numpy as np
import pytest

from kernels.test_traversal import adversarial_rays
from random_scenes import random_scene
from ray_oracle import first_hits
from voxfield.kernels.beam import start_distance
from voxfield.kernels.ray_batch import trace_rays, trace_rays_in_packets
from voxfield.render.beam import primary_beam
from voxfield.render.camera import Camera, oblique_camera
from voxfield.render.primary import render_reference
from voxfield.scene.terrain import recipe_scene
from voxfield.svo import build_octree


def _run(kernel, octree, origins, directions, lod=0, tmin=0.0, tmax=np.inf):
    n = len(origins)
    out = (np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n),
           np.empty(n, np.int64), np.empty(n, np.int64))
    kernel(np.ascontiguousarray(origins, np.float64),
           np.ascontiguousarray(directions, np.float64), tmin, tmax,
           octree.inner_nodes, octree.depth, octree.depth - lod, *out)
    return out


def _assert_same(octree, origins, directions, **query):
    scalar = _run(trace_rays, octree, origins, directions, **query)
    packets = _run(trace_rays_in_packets, octree, origins, directions, **query)
    for name, a, b in zip(("node", "level", "t", "normal", "steps"), scalar, packets, strict=True):
        assert np.array_equal(a, b), f"{name}: {int((a != b).sum())} of {len(a)} rays differ"
    return packets


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("lod", [0, 1, 2])
def test_packets_equal_the_scalar_loop_and_the_oracle(seed, lod):
    octree = build_octree(random_scene(seed, n=400, size=16))
    lo, hi = octree.voxel_bounds
    origins, directions = adversarial_rays(lo, hi, 3000, seed)
    node, _, t, _, _ = _assert_same(octree, origins, directions, lod=lod)
    expected, t_expected = first_hits(origins, directions, octree.lod_voxels(lod), 2**lod)
    start = octree.level_slice(octree.depth - lod).start
    got = np.where(node >= 0, node - start, -1)
    assert np.array_equal(got, expected)
    assert np.array_equal(t[got >= 0], t_expected[got >= 0])


def test_clipped_ranges_equal_the_scalar_loop():
    octree = build_octree(random_scene(3, n=400, size=16))
    lo, hi = octree.voxel_bounds
    origins, directions = adversarial_rays(lo, hi, 2000, 3)
    _assert_same(octree, origins, directions, tmin=2.5)
    _assert_same(octree, origins, directions, tmin=1.0, tmax=9.0)


def test_mixed_signs_and_broken_rays_in_one_packet():
    """All eight sign groups and non-finite rays share packets; broken rays miss in 0 steps."""
    octree = build_octree(random_scene(4, n=300, size=8))
    rng = np.random.default_rng(4)
    origins = rng.uniform(-2.0, 10.0, size=(64, 3))
    directions = rng.normal(size=(64, 3))
    directions[::7] = np.sign(directions[::7])
    origins[5, 1] = np.nan
    directions[9, 2] = np.inf
    directions[13] = 1e-310  # uninvertible: counts as zero, like an all-zero direction
    node, _, _, _, steps = _assert_same(octree, origins, directions)
    assert node[5] == -1 and steps[5] == 0 and node[9] == -1 and steps[9] == 0
    signs = {tuple(np.signbit(d)) for d in directions[np.isfinite(directions).all(axis=1)]}
    assert len(signs) == 8


def test_supersampled_renders_go_through_packets_from_their_beam_bounds(shared_data):
    """Reference pixels through the octree alone are traced in packets, each ray from its
    pixel block's beam bound: the step map equals the scalar loop's steps over each pixel's
    rays started there (plus the beam pass's share), and the image equals that of rays
    started at the camera."""
    octree = build_octree(recipe_scene("mountain", footprint=64, seed=0))
    lo, hi = octree.voxel_bounds
    camera = oblique_camera(lo, hi, size=24, fov_deg=70, elevation_deg=45)
    with_beam = render_reference(octree, camera, side=2, beam=True, threads=2, columns=False)
    from_camera = render_reference(octree, camera, side=2, beam=False, threads=1,
                                   columns=False)
    assert np.array_equal(with_beam.image, from_camera.image)
    assert np.array_equal(with_beam.depth, from_camera.depth)

    origins, directions = camera.rays(side=2, seed=0)
    for render, beam_on in ((with_beam, True), (from_camera, False)):
        beam = primary_beam(octree, camera, stop_level=octree.depth, side=2, enabled=beam_on)
        rows, cols = np.divmod(np.arange(camera.height * camera.width), camera.width)
        pixel_start = np.array([start_distance(b) for b in
                                beam.bound[rows // beam.block, cols // beam.block]])
        assert (pixel_start > 0).all() == beam_on
        ray_start = np.repeat(pixel_start, 4)  # each pixel's 2×2 rays are consecutive
        steps = np.empty(len(origins), np.int64)
        for start in np.unique(ray_start):
            rays = ray_start == start
            steps[rays] = _run(trace_rays, octree, origins[rays], directions[rays],
                               tmin=start)[4]
        want = steps.reshape(-1, 4).sum(axis=1) + beam.image_steps(camera.height,
                                                                   camera.width).reshape(-1)
        assert np.array_equal(render.steps.reshape(-1), want)
        if beam_on:  # the starts matter: rays from the camera take other steps
            assert (steps != _run(trace_rays, octree, origins, directions)[4]).sum() > 100


def test_octahedral_probe_render_through_packets_matches_per_ray_tracing():
    """Probe cameras have no beam bound, so supersampled probe texels through the octree
    alone go through packets."""
    octree = build_octree(random_scene(5, n=600, size=16))
    camera = Camera.octahedral(np.array([8.2, 8.1, 7.9]), resolution=16)
    render = render_reference(octree, camera, side=2, threads=1, columns=False)
    origins, directions = camera.rays(side=2, seed=0)
    node, _, t, _, steps = _run(trace_rays, octree, origins, directions)
    assert np.array_equal(render.steps.reshape(-1), steps.reshape(-1, 4).sum(axis=1))
    hits = (node >= 0).reshape(-1, 4).sum(axis=1)
    assert np.array_equal(render.hit_count.reshape(-1), hits)
