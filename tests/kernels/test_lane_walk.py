"""The pyramid walk in SIMD lanes ends every ray as the one-ray walk does, bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from random_scenes import (
    any_rays,
    hollow_shell_terrain,
    octree_and_columns,
    overhanging_terrain,
    pillar_field,
    random_scene,
)
from voxfield.kernels.lane_walk import SLOTS, compiles_wide_vectors, walk_to_voxels_in_lanes
from voxfield.kernels.surface_approach import HANDED_OVER, MISSED, walk_over_columns


@njit
def _lane_walks(rays, per_call, depth, columns, walk_ints, walk_times):
    n = rays.shape[0]
    for first in range(0, n, per_call):
        count = min(per_call, n - first)
        walk_to_voxels_in_lanes(rays[first:first + count], count, depth, columns,
                                walk_ints[first:first + count], walk_times[first:first + count])


@njit
def _one_ray_walks(rays, depth, columns, walk_ints, walk_times):
    for k in range(rays.shape[0]):
        verdict, t, cells, cx, cz, _, _, _ = walk_over_columns(
            rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], rays[k, 6],
            math.inf, depth, depth, columns)
        walk_ints[k, 0] = verdict
        walk_ints[k, 1] = cells
        walk_ints[k, 2] = cx
        walk_ints[k, 3] = cz
        walk_times[k, 0] = t


def _rays(voxels, n, seed):
    """``any_rays`` with start bounds as primary rays have them: none (from the camera, the
    walk starts at the top), before the surface, and anywhere along the ray."""
    origins, directions = any_rays(voxels, n, seed=seed)
    rng = np.random.default_rng(seed)
    m = len(origins)
    tmin = np.select([rng.random(m) < 0.4, rng.random(m) < 0.5], [0.0, 2.0],
                     rng.uniform(0.0, 40.0, m))
    return np.column_stack([origins, directions, tmin])


@pytest.mark.parametrize("scene", [
    overhanging_terrain(seed=1), overhanging_terrain(seed=7, size=37),
    hollow_shell_terrain(seed=4), random_scene(seed=8, n=900, size=19),
    pillar_field(seed=2, size=40),
], ids=lambda scene: scene.name)
def test_lane_walks_are_the_one_ray_walks(scene):
    """Verdict, cells, hand-over cell and time of every ray, whether a call fills its lanes
    or leaves some idle."""
    octree, voxels, columns = octree_and_columns(scene)
    rays = _rays(voxels, 500, seed=len(voxels))
    n = len(rays)
    expected_ints = np.zeros((n, 4), np.int64)
    expected_times = np.zeros((n, 1))
    _one_ray_walks(rays, octree.depth, columns, expected_ints, expected_times)
    for per_call in (SLOTS, 37, 1):
        walk_ints = np.full((n, 4), -7, np.int64)
        walk_times = np.full((n, 1), -7.0)
        _lane_walks(rays, per_call, octree.depth, columns, walk_ints, walk_times)
        np.testing.assert_array_equal(walk_ints, expected_ints)
        assert np.array_equal(walk_times, expected_times)  # bit for bit, infinities too
    verdicts = expected_ints[:, 0]
    landed = (verdicts == HANDED_OVER) & (expected_ints[:, 2] >= 0)
    assert landed.sum() > n // 4 and (verdicts == MISSED).sum() > n // 10
    assert expected_ints[:, 1].max() > 8  # long walks too: climbs, descents, gaps


def test_rays_that_cannot_walk_are_handed_over_where_they_start():
    """A non-finite ray takes no step and goes to the octree at its start, as
    ``approach_surface`` hands it over."""
    octree, voxels, columns = octree_and_columns(overhanging_terrain(seed=2))
    rays = np.array([[1.5, 40.0, 1.5, 0.0, -1.0, 0.0, 0.0],
                     [math.nan, 40.0, 1.5, 0.0, -1.0, 0.0, 2.0],
                     [1.5, 40.0, 1.5, 0.0, -math.inf, 0.0, 0.0]])
    walk_ints = np.zeros((3, 4), np.int64)
    walk_times = np.zeros((3, 1))
    _lane_walks(rays, SLOTS, octree.depth, columns, walk_ints, walk_times)
    expected_ints = np.zeros((3, 4), np.int64)
    expected_times = np.zeros((3, 1))
    _one_ray_walks(rays, octree.depth, columns, expected_ints, expected_times)
    np.testing.assert_array_equal(walk_ints, expected_ints)
    np.testing.assert_array_equal(walk_ints[1:], [[HANDED_OVER, 0, -1, -1]] * 2)
    assert walk_ints[0, 1] > 0


def test_only_avx_512_targets_walk_their_batches_in_lanes():
    """The choice follows Numba's target features: compiled for AVX2 the lane walk was
    slower than the one-ray walk, so only a target with AVX-512 takes it."""
    assert compiles_wide_vectors("+sse4.2,+avx,+avx2,+fma,+avx512f,+avx512dq")
    assert not compiles_wide_vectors("+sse4.2,+avx,+avx2,+fma,-avx512f,-avx512dq")
    assert not compiles_wide_vectors("+avx2,+avx512fp16x")  # a name that only starts alike
    assert not compiles_wide_vectors("")
