"""Rising rays walked in SIMD lanes get ``rising_ray_query``'s answers, bit for bit."""

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
    rising_rays,
)
from voxfield.kernels.ray_batch import RAY_RUN, occlude_ray_chunk, occlude_run_in_lanes
from voxfield.kernels.rising_lanes import (
    RISING_RAY_COLUMNS,
    lanes_walk_rising,
    new_rising_walks,
    walk_rising_in_lanes,
    walk_rising_rays,
)
from voxfield.kernels.traversal import new_scratch
from voxfield.kernels.upward_rays import BLOCKED, CLEAR, UNDECIDED, rising_ray_query
from voxfield.svo.column_tops import no_column_tops


@njit
def _one_by_one(rays, columns, out_verdict, out_t, out_steps):
    for k in range(rays.shape[0]):
        out_verdict[k], out_t[k], out_steps[k] = rising_ray_query(
            rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], rays[k, 6],
            columns, rays[k, 7])


@njit
def _in_calls(rays, per_call, columns, lanes, out_verdict, out_t, out_steps):
    n = rays.shape[0]
    for first in range(0, n, per_call):
        rows = slice(first, min(n, first + per_call))
        if lanes:
            walk_rising_in_lanes(rays[rows], rows.stop - first, columns, out_verdict[rows],
                                 out_t[rows], out_steps[rows])
        else:
            walk_rising_rays(rays[rows], rows.stop - first, columns, out_verdict[rows],
                             out_t[rows], out_steps[rows])


def _queued_rays(voxels, seed):
    """``rising_rays`` with a mix of stops (the top of the voxels, none, short) and of
    ``t_clear`` (none, or part of the way to the stop), plus rays too flat to walk."""
    origins, directions = rising_rays(voxels, 600, seed=seed)
    rng = np.random.default_rng(seed)
    n = len(origins)
    top = voxels[:, 1].max() + 1.0
    tmax = np.where(rng.random(n) < 0.5, (top - origins[:, 1]) / directions[:, 1],
                    rng.choice([math.inf, 2.0, 7.5], n))
    t_clear = np.where(rng.random(n) < 0.3, rng.random(n) * np.minimum(tmax, 20.0), 0.0)
    t_clear[::50] = tmax[::50]  # clear all the way
    rays = np.concatenate([origins, directions, tmax[:, None], t_clear[:, None]], axis=1)
    rays[::97, 4] = 1e-12  # too flat for the pyramid
    assert rays.shape[1] == RISING_RAY_COLUMNS
    return np.ascontiguousarray(rays)


def _answers(rays, columns, per_call=None, lanes=True):
    n = len(rays)
    out = (np.full(n, -1, np.int64), np.full(n, np.nan), np.full(n, -1, np.int64))
    if per_call is None:
        _one_by_one(rays, columns, *out)
    else:
        _in_calls(rays, per_call, columns, lanes, *out)
    return out


@pytest.mark.parametrize("scene", [
    overhanging_terrain(seed=0), overhanging_terrain(seed=5, size=37),
    random_scene(seed=6, n=900, size=17), hollow_shell_terrain(seed=3), pillar_field(seed=2),
], ids=["overhangs", "overhangs-37", "random", "hollow-shell", "pillars"])
def test_rising_rays_walked_in_lanes_are_those_walked_one_by_one(scene):
    """Every verdict, time and step count, for the whole queue in one call, in calls of a
    lane group's worth and fewer, and one ray at a time."""
    _, voxels, columns = octree_and_columns(scene)
    assert columns.cell_records.shape[0] > 0
    rays = _queued_rays(voxels, seed=len(voxels))
    expected = _answers(rays, columns)
    assert set(expected[0].tolist()) == {CLEAR, BLOCKED, UNDECIDED}
    assert np.any((expected[0] == CLEAR) & (expected[2] > 3))  # walks that climb and skip
    for per_call in (len(rays), 64, 17, 1):
        got = _answers(rays, columns, per_call)
        for want, have in zip(expected, got, strict=True):
            assert np.array_equal(want, have)
    # The choice of walk gives the same answers, wherever it walks in lanes.
    chosen = _answers(rays, columns, 256, lanes=False)
    for want, have in zip(expected, chosen, strict=True):
        assert np.array_equal(want, have)


def test_without_a_pyramid_or_cell_records_rays_are_walked_one_by_one():
    _, voxels, columns = octree_and_columns(overhanging_terrain(seed=2, size=12))
    rays = _queued_rays(voxels, seed=4)[:200]
    no_records = columns._replace(cell_records=np.zeros(0, np.int64))
    assert not lanes_walk_rising(no_records)
    for pyramid in (no_records, no_column_tops()):
        expected = _answers(rays, pyramid)
        got = _answers(rays, pyramid, 64, lanes=False)
        for want, have in zip(expected, got, strict=True):
            assert np.array_equal(want, have)
    assert np.all(_answers(rays, no_column_tops(), 64, lanes=False)[0] == UNDECIDED)


@njit
def _occlusion_runs(origins, directions, tmax, inner, depth, columns, lanes, blocked, steps):
    scratch = new_scratch(depth)
    walks = new_rising_walks(RAY_RUN)
    n = origins.shape[0]
    for first in range(0, n, RAY_RUN):
        last = min(n, first + RAY_RUN)
        if lanes:
            occlude_run_in_lanes(origins, directions, first, last, tmax, inner, depth,
                                 columns, blocked, steps, scratch, walks)
        else:
            occlude_ray_chunk(origins, directions, first, last, 0.0, tmax, inner, depth,
                              columns, blocked, steps, scratch)


def test_any_hit_queries_walked_in_lanes_are_those_walked_one_by_one():
    """``occlude_run_in_lanes`` against ``occlude_ray_chunk``: rising, level and falling
    rays, blocked and steps alike, with and without a stop."""
    octree, voxels, columns = octree_and_columns(hollow_shell_terrain(seed=8))
    rising_o, rising_d = rising_rays(voxels, 400, seed=2)
    any_o, any_d = any_rays(voxels, 200, seed=3)
    origins = np.ascontiguousarray(np.concatenate([rising_o, any_o]))
    directions = np.ascontiguousarray(np.concatenate([rising_d, any_d]))
    n = len(origins)
    assert n > 2 * RAY_RUN and n % RAY_RUN != 0
    for tmax in (math.inf, 6.5):
        answers = []
        for lanes in (False, True):
            blocked, steps = np.zeros(n, np.bool_), np.full(n, -1, np.int64)
            _occlusion_runs(origins, directions, tmax, octree.inner_nodes, octree.depth,
                            columns, lanes, blocked, steps)
            answers.append((blocked, steps))
        assert np.array_equal(answers[0][0], answers[1][0])
        assert np.array_equal(answers[0][1], answers[1][1])
        assert 0.1 < answers[0][0].mean() < 0.9
