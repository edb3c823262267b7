"""Batch ray queries share their rays out as the workers are free: every ray is traced once,
the same whatever the worker count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kernels.test_traversal import adversarial_rays
from random_scenes import overhanging_terrain
from voxfield.kernels.ray_batch import RAY_RUN, occlude_rays, trace_rays, trace_rays_in_packets
from voxfield.svo import build_octree
from voxfield.svo.column_tops import no_column_tops, octree_column_tops

#: A value no query writes: an entry still holding it was never traced.
UNTOUCHED = -7


def _closest(kernel, octree, origins, directions, workers, *extra):
    n = len(origins)
    out = (np.full(n, UNTOUCHED, np.int64), np.full(n, UNTOUCHED, np.int64),
           np.full(n, float(UNTOUCHED)), np.full(n, UNTOUCHED, np.int64),
           np.full(n, UNTOUCHED, np.int64))
    kernel(origins, directions, 0.0, math.inf, octree.inner_nodes, octree.depth, octree.depth,
           *out, *extra, workers)
    return out


def _any(octree, origins, directions, workers, columns):
    n = len(origins)
    blocked = np.zeros(n, bool)
    steps = np.full(n, UNTOUCHED, np.int64)
    occlude_rays(origins, directions, 0.0, math.inf, octree.inner_nodes, octree.depth,
                 columns, blocked, steps, workers)
    return blocked, steps


@pytest.fixture(scope="module")
def scene():
    octree = build_octree(overhanging_terrain(seed=3))
    lo, hi = octree.voxel_bounds
    # Not a whole number of runs, so the last claim is a short one.
    origins, directions = adversarial_rays(lo, hi, 3 * RAY_RUN + 37, 5)
    return (octree, np.ascontiguousarray(origins, np.float64),
            np.ascontiguousarray(directions, np.float64))


@pytest.mark.parametrize("workers", [2, 3, 8])
def test_every_ray_is_traced_once_and_alike_whatever_the_workers(scene, workers):
    """One worker, two, three, or more workers than threads: the same nodes, levels, times,
    normals and steps, closest and any hit, scalar and packets, with no ray left out."""
    octree, origins, directions = scene
    columns = octree_column_tops(octree)
    for kernel, extra in ((trace_rays, (None,)), (trace_rays, (columns,)),
                          (trace_rays_in_packets, ())):
        alone = _closest(kernel, octree, origins, directions, 1, *extra)
        shared = _closest(kernel, octree, origins, directions, workers, *extra)
        for a, b in zip(alone, shared, strict=True):
            assert np.array_equal(a, b)
        assert np.all(alone[4] != UNTOUCHED) and np.all(alone[3] != UNTOUCHED)
        assert (alone[0] >= 0).sum() > len(origins) // 10  # hits and misses both
        assert (alone[0] < 0).sum() > len(origins) // 10
    for pyramid in (columns, no_column_tops()):
        alone = _any(octree, origins, directions, 1, pyramid)
        shared = _any(octree, origins, directions, workers, pyramid)
        assert np.array_equal(alone[0], shared[0]) and np.array_equal(alone[1], shared[1])
        assert np.all(alone[1] != UNTOUCHED)
        blocked_by_trace = _closest(trace_rays, octree, origins, directions, workers, None)[0] >= 0
        assert np.array_equal(alone[0], blocked_by_trace)


def test_an_empty_batch_traces_nothing(scene):
    octree, origins, directions = scene
    out = _closest(trace_rays, octree, origins[:0], directions[:0], 2, None)
    assert all(len(a) == 0 for a in out)
