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
from voxfield.kernels.lane_walk import (
    SLOTS,
    compiles_wide_vectors,
    land_walks,
    pick,
    walk_queue_in_lanes,
    walk_to_nodes_in_lanes,
)
from voxfield.kernels.ray_batch import new_walk_queue, trace_ray_chunk, trace_run_in_lanes
from voxfield.kernels.surface_approach import (
    FROM_CAMERA,
    FROM_SURFACE,
    HANDED_OVER,
    MISSED,
    walk_over_columns,
)
from voxfield.kernels.traversal import new_scratch


@njit
def _lane_walks(rays, per_call, depth, columns, walk_ints, walk_times, finest=0):
    n = rays.shape[0]
    for first in range(0, n, per_call):
        count = min(per_call, n - first)
        rows = slice(first, first + count)
        walk_to_nodes_in_lanes(rays[rows], count, depth, finest, columns, walk_ints[rows],
                               walk_times[rows])
        if walk_ints.shape[1] > 4:
            land_walks(rays[rows], count, walk_ints[rows], walk_times[rows], columns,
                       math.inf, finest)


@njit
def _queue_walks(rays, per_call, depth, columns, walk_ints, walk_times, start, tmax):
    n = rays.shape[0]
    for first in range(0, n, per_call):
        count = min(per_call, n - first)
        rows = slice(first, first + count)
        walk_queue_in_lanes(rays[rows], count, depth, columns, walk_ints[rows],
                            walk_times[rows], start, tmax)
        land_walks(rays[rows], count, walk_ints[rows], walk_times[rows], columns, tmax, 0)


@njit
def _one_ray_walks(rays, depth, columns, walk_ints, walk_times, start=FROM_CAMERA,
                   tmax=math.inf, finest=0):
    for k in range(rays.shape[0]):
        verdict, t, cells, cx, cz, y, t_hit, normal = walk_over_columns(
            rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], rays[k, 6],
            tmax, depth, depth - finest, columns, start)
        walk_ints[k, 0] = verdict
        walk_ints[k, 1] = cells
        walk_ints[k, 2] = cx
        walk_ints[k, 3] = cz
        walk_times[k, 0] = t
        if walk_ints.shape[1] > 4:
            walk_ints[k, 4] = y
            walk_ints[k, 5] = normal
            walk_times[k, 1] = t_hit


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


@pytest.mark.parametrize("scene", [
    overhanging_terrain(seed=9, size=45), hollow_shell_terrain(seed=6, size=40),
    pillar_field(seed=3, size=44),
], ids=lambda scene: scene.name)
def test_lane_walks_to_coarser_nodes_are_the_one_ray_walks(scene):
    """Walks to nodes of side 2, 4 and 8 (the error-aware renderer's first rays, LOD
    renders) round the cells' tops and gaps out to whole nodes and stop a level higher, as
    the one-ray walk does: verdict, cells, hand-over cell, time and the node the pyramid
    lands on, bit for bit."""
    octree, voxels, columns = octree_and_columns(scene)
    rays = _rays(voxels, 500, seed=len(voxels) + 2)
    n = len(rays)
    cells_walked = []
    for finest in (1, 2, 3):
        expected_ints = np.zeros((n, 6), np.int64)
        expected_times = np.zeros((n, 2))
        _one_ray_walks(rays, octree.depth, columns, expected_ints, expected_times,
                       finest=finest)
        for per_call in (SLOTS, 37):
            walk_ints = np.full((n, 6), -7, np.int64)
            walk_times = np.full((n, 2), -7.0)
            _lane_walks(rays, per_call, octree.depth, columns, walk_ints, walk_times, finest)
            np.testing.assert_array_equal(walk_ints, expected_ints)
            assert np.array_equal(walk_times, expected_times)
        landed = expected_ints[:, 4] >= 0
        assert landed.sum() > n // 10 and (expected_ints[:, 0] == MISSED).sum() > n // 10
        cells_walked.append(expected_ints[:, 1].sum())
    # Coarser nodes: the walk stops higher up, after fewer cells.
    assert cells_walked[0] > cells_walked[1] > cells_walked[2]


@pytest.mark.parametrize("scene", [
    overhanging_terrain(seed=3), hollow_shell_terrain(seed=5),
    random_scene(seed=6, n=700, size=17), pillar_field(seed=4, size=36),
], ids=lambda scene: scene.name)
def test_queued_lane_walks_are_the_one_ray_walks(scene):
    """With lanes refilled from the queue as their rays stop, from the camera or from a
    surface, over a bounded segment or not: every ray's walk and landing, bit for bit."""
    octree, voxels, columns = octree_and_columns(scene)
    rays = _rays(voxels, 500, seed=len(voxels) + 1)
    n = len(rays)
    for start in (FROM_CAMERA, FROM_SURFACE):
        for tmax in (math.inf, 9.5):
            expected_ints = np.zeros((n, 6), np.int64)
            expected_times = np.zeros((n, 2))
            _one_ray_walks(rays, octree.depth, columns, expected_ints, expected_times, start,
                           tmax)
            for per_call in (n, 3 * SLOTS + 5, SLOTS, 1):
                walk_ints = np.full((n, 6), -7, np.int64)
                walk_times = np.full((n, 2), -7.0)
                _queue_walks(rays, per_call, octree.depth, columns, walk_ints, walk_times,
                             start, tmax)
                np.testing.assert_array_equal(walk_ints, expected_ints)
                assert np.array_equal(walk_times, expected_times)
            landed = expected_ints[:, 4] >= 0
            assert landed.sum() > n // 10 and (expected_ints[:, 0] == MISSED).sum() > n // 10
            assert expected_ints[:, 1].max() > 8


@njit
def _trace_runs(origins, directions, tmin, tmax, octree_nodes, depth, columns, lanes, out):
    scratch = new_scratch(depth)
    walks = new_walk_queue()
    node, level, t, normal, steps = out
    n = origins.shape[0]
    run = walks[0].shape[0]
    for first in range(0, n, run):
        last = min(n, first + run)
        if lanes:
            trace_run_in_lanes(origins, directions, first, last, tmin, tmax, octree_nodes,
                               depth, node, level, t, normal, steps, scratch, columns, walks)
        else:
            trace_ray_chunk(origins, directions, first, last, tmin, tmax, octree_nodes, depth,
                            depth, node, level, t, normal, steps, scratch, columns)


def test_ray_queries_walked_in_lanes_are_those_walked_one_by_one():
    """``ray_batch``'s runs with their walks in lanes answer every ray as the one-ray walk
    does: node, level, time, entry face and steps, whatever the target decides to run."""
    octree, voxels, columns = octree_and_columns(overhanging_terrain(seed=12, size=40))
    origins, directions = any_rays(voxels, 700, seed=3)
    n = len(origins)
    for tmin, tmax in ((0.0, math.inf), (1.5, math.inf), (0.0, 6.0)):
        answers = []
        for lanes in (True, False):
            out = (np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n),
                   np.zeros(n, np.int64), np.zeros(n, np.int64))
            _trace_runs(origins, directions, tmin, tmax, octree.inner_nodes, octree.depth,
                        columns, lanes, out)
            answers.append(out)
        for walked, alone in zip(*answers, strict=True):
            assert np.array_equal(walked, alone)
        assert (answers[0][0] >= 0).sum() > n // 4


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


@njit(cache=True)
def _picks(conditions, ints, floats):
    out_ints = np.empty(len(conditions), np.int64)
    out_floats = np.empty(len(conditions))
    out_bools = np.empty(len(conditions), np.bool_)
    for i in range(len(conditions)):
        c = conditions[i]
        out_ints[i] = pick(c, ints[i], 0) + pick(not c, 1, np.int32(2))
        out_floats[i] = pick(c, floats[i], ints[i])  # an int side is converted
        out_bools[i] = pick(c, floats[i] > 0.0, pick(ints[i] > 0, True, c))
    return out_ints, out_floats, out_bools


def test_pick_is_a_conditional_expression_of_the_sides_common_type():
    conditions = np.array([True, False, True, False])
    ints = np.array([5, -3, 0, 7])
    floats = np.array([0.5, -1.5, -2.0, 3.0])
    out_ints, out_floats, out_bools = _picks(conditions, ints, floats)
    np.testing.assert_array_equal(out_ints, np.where(conditions, ints, 0)
                                  + np.where(conditions, 2, 1))
    np.testing.assert_array_equal(out_floats, np.where(conditions, floats, ints))
    np.testing.assert_array_equal(out_bools, np.where(conditions, floats > 0.0,
                                                      (ints > 0) | conditions))
    assert out_floats.dtype == np.float64
    # and plain Python, where the CUDA simulator runs the CPU's walks uncompiled
    assert (pick(True, 1, 2.5), pick(False, 1, 2.5)) == (1, 2.5)
