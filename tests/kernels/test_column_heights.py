"""Column heights clip rising rays exactly: no voxel a ray can meet lies past its clear time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from kernels.test_traversal import adversarial_rays
from random_scenes import random_scene
from ray_oracle import last_exits
from voxfield.kernels.column_heights import clear_time as clear_time_kernel
from voxfield.kernels.column_heights import column_heights
from voxfield.kernels.traversal import new_scratch, occluded
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree


@njit
def _clear_and_occluded(o, d, tmin, tmax, columns, inner, depth, out_clear, out_blocked):
    """Per ray: its clear time, and whether a voxel blocks ``[tmin, tmax)`` and
    ``[tmin, clear)`` (columns 0 and 1 of ``out_blocked``), with its steps in each (2, 3)."""
    scratch = new_scratch(depth)
    for k in range(o.shape[0]):
        clear = clear_time_kernel(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                  tmin[k], tmax[k], columns)
        out_clear[k] = clear
        full, full_steps = occluded(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                    tmin[k], tmax[k], inner, depth, scratch)
        clipped, clipped_steps = occluded(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1],
                                          d[k, 2], tmin[k], clear, inner, depth, scratch)
        out_blocked[k, 0] = full
        out_blocked[k, 1] = clipped
        out_blocked[k, 2] = full_steps
        out_blocked[k, 3] = clipped_steps


def clear_and_occluded(octree, columns, origins, directions, tmin, tmax):
    n = len(origins)
    clear = np.empty(n)
    blocked = np.empty((n, 4), np.int64)
    _clear_and_occluded(np.ascontiguousarray(origins, np.float64),
                        np.ascontiguousarray(directions, np.float64),
                        np.broadcast_to(np.asarray(tmin, np.float64), n).copy(),
                        np.broadcast_to(np.asarray(tmax, np.float64), n).copy(),
                        columns, octree.inner_nodes, octree.depth, clear, blocked)
    return clear, blocked


def terrain_with_overhangs(seed: int, side: int = 40) -> VoxelScene:
    """A rough heightfield with floating slabs and an arch: columns whose top voxel is not
    their only one, so a clipped ray must still pass under them."""
    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    height = (6 + 4 * np.sin(x / 5.0) * np.cos(z / 7.0) + rng.integers(0, 3, x.shape)).astype(int)
    cells = [np.stack([x.ravel(), np.full(x.size, h), z.ravel()], 1)
             for h in range(int(height.max()) + 1)]
    ground = np.concatenate(cells)
    ground = ground[ground[:, 1] <= height[ground[:, 0], ground[:, 2]]]
    slabs = []
    for _ in range(6):
        x0, z0 = rng.integers(0, side - 8, 2)
        y = int(rng.integers(14, 24))
        sx, sz = np.meshgrid(np.arange(x0, x0 + 8), np.arange(z0, z0 + 5), indexing="ij")
        slabs.append(np.stack([sx.ravel(), np.full(sx.size, y), sz.ravel()], 1))
    coords = np.concatenate([ground, *slabs])
    return VoxelScene(coords, rng.random((len(coords), 3)), name=f"overhangs{seed}").dedupe()


def rising_rays(lo, hi, n, seed):
    """Adversarial rays turned upwards, plus rays leaving random voxel-face points the way the
    sun bake casts them: axis-aligned, vertical, on tile planes, from every corner."""
    origins, directions = adversarial_rays(lo, hi, n, seed)
    directions = directions.copy()
    directions[:, 1] = np.abs(directions[:, 1])
    rng = np.random.default_rng(seed + 1)
    m = n // 2
    o = np.floor(rng.uniform(lo, hi, size=(m, 3)))
    o[:, [0, 2]] += rng.choice([0.0, 0.25, 0.5, 1.0], size=(m, 2))
    d = rng.normal(size=(m, 3))
    d[:, 1] = np.abs(d[:, 1]) + 0.05
    d[: m // 4, 0] = 0.0
    d[m // 4: m // 2, 2] = 0.0
    d[m // 2: m // 2 + m // 8, [0, 2]] = 0.0
    d /= np.linalg.norm(d, axis=1)[:, None]
    keep = directions[:, 1] > 0.0
    from_faces = np.arange(keep.sum() + m) >= keep.sum()
    return (np.concatenate([origins[keep], o]), np.concatenate([directions[keep], d]),
            from_faces)


@pytest.mark.parametrize("finest", [0, 1, 3])
@pytest.mark.parametrize("scene", ["overhangs", "random"])
def test_no_voxel_a_rising_ray_meets_lies_past_its_clear_time(scene, finest):
    voxels = terrain_with_overhangs(5) if scene == "overhangs" else random_scene(3, 900, 24)
    octree = build_octree(voxels)
    coords = octree.node_coords(octree.depth)
    columns = column_heights(coords, octree.depth, finest)
    lo, hi = octree.voxel_bounds
    origins, directions, from_faces = rising_rays(lo, hi, 4000, seed=finest)
    rng = np.random.default_rng(7)
    tmin = np.where(rng.random(len(origins)) < 0.5, 0.0, rng.uniform(-5.0, 20.0, len(origins)))
    n = len(origins)
    tmax = np.where(rng.random(n) < 0.5, math.inf, tmin + rng.uniform(0, 60, n))
    clear, blocked = clear_and_occluded(octree, columns, origins, directions, tmin, tmax)
    assert np.all((clear >= tmin) | (clear == tmax)) and np.all(clear <= tmax)
    # The oracle: every stretch in which some voxel holds the ray ends by the clear time.
    last = last_exits(origins, directions, coords, 1.0, tmin, tmax)
    late = last > clear
    assert not late.any(), f"{late.sum()} rays meet a voxel after their clear time"
    assert np.array_equal(blocked[:, 0], blocked[:, 1])
    # And the clip is worth having: most rays from voxel faces that meet nothing stop early.
    free = (blocked[:, 0] == 0) & np.isfinite(tmax) & from_faces
    assert np.mean(clear[free] < tmax[free]) > 0.5
    assert blocked[:, 3].sum() < blocked[:, 2].sum()


def test_rays_that_do_not_rise_or_start_outside_the_columns_keep_their_range():
    octree = build_octree(terrain_with_overhangs(1, side=24))
    columns = column_heights(octree.node_coords(octree.depth), octree.depth)
    origins = np.array([[5.5, 20.0, 5.5], [5.5, 20.0, 5.5], [-3.0, 20.0, 5.0], [5.0, 20.0, 99.0],
                        [5.0, 20.0, 5.0]])
    directions = np.array([[1.0, 0.0, 0.0], [0.3, -0.5, 0.1], [1.0, 0.1, 0.0], [0.0, 1.0, -1.0],
                           [math.nan, 1.0, 0.0]])
    clear, _ = clear_and_occluded(octree, columns, origins, directions, 0.0, 50.0)
    assert np.all(clear == 50.0)


def test_a_ray_leaving_the_top_of_a_flat_floor_is_clear_at_once():
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    floor = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], 1)
    octree = build_octree(VoxelScene(floor, np.ones((len(floor), 3)), name="floor"))
    columns = column_heights(octree.node_coords(octree.depth), octree.depth)
    rng = np.random.default_rng(2)
    origins = np.column_stack([rng.uniform(0, 32, 200), np.ones(200), rng.uniform(0, 32, 200)])
    directions = rng.normal(size=(200, 3))
    directions[:, 1] = np.abs(directions[:, 1]) + 0.01
    clear, blocked = clear_and_occluded(octree, columns, origins, directions, 0.0, 30.0)
    assert np.all(clear == 0.0)
    assert not blocked[:, :2].any() and blocked[:, 3].sum() == 0


def test_each_pyramid_level_holds_the_highest_top_of_its_tile():
    octree = build_octree(terrain_with_overhangs(9))
    coords = octree.node_coords(octree.depth)
    columns = column_heights(coords, octree.depth, finest=1)
    side = 1 << octree.depth
    for level in range(columns.finest, octree.depth + 1):
        tiles = side >> level
        expected = np.zeros((tiles, tiles), np.int64)
        np.maximum.at(expected, (coords[:, 0] >> level, coords[:, 2] >> level), coords[:, 1] + 1)
        start, stop = columns.offsets[level], columns.offsets[level + 1]
        assert np.array_equal(columns.heights[start:stop].reshape(tiles, tiles), expected)
    assert columns.heights[columns.offsets[octree.depth]] == coords[:, 1].max() + 1
