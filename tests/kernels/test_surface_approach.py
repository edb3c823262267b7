"""Closest-hit rays through the column-top pyramid get exactly the octree's hits."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from random_scenes import (
    any_rays,
    flat_ground,
    hollow_shell_terrain,
    octree_and_columns,
    overhanging_terrain,
    random_scene,
)
from voxfield.kernels.surface_approach import (
    HANDED_OVER,
    MISSED,
    approach_surface,
    top_node_hit,
    trace_over_columns,
    walk_over_columns,
    walk_primary_over_columns,
)
from voxfield.kernels.traversal import new_scratch, trace_ray
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.column_tops import (
    GAP_OPEN,
    cell_records,
    column_tops,
    gap_open,
    no_column_tops,
)

#: How a ray ended in the walk: missed, settled by the pyramid (a column's top run, a cell's
#: top node), or finished by the octree.
_MISSED, _TOP_NODE, _OCTREE = 0, 1, 2


@njit
def _hits(o, d, tmin, tmax, inner, depth, stop_level, columns, out, times, ends):
    """Per ray: the octree's hit over the whole ray (fresh scratch) and the pyramid's (one
    scratch for all rays, as a render thread keeps), and how the walk ended."""
    scratch = new_scratch(depth)
    for k in range(o.shape[0]):
        a = trace_ray(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], tmin[k], tmax[k],
                      inner, depth, stop_level, 0.0, 0.0, new_scratch(depth))
        b = trace_over_columns(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], tmin[k],
                               tmax[k], inner, depth, stop_level, scratch, columns)
        out[k, 0] = a[0]
        out[k, 1] = a[1]
        out[k, 2] = a[3]
        out[k, 3] = b[0]
        out[k, 4] = b[1]
        out[k, 5] = b[3]
        out[k, 6] = b[4]
        out[k, 7] = a[4]
        times[k, 0] = a[2]
        times[k, 1] = b[2]
        finest = depth - min(stop_level, depth)
        verdict, t, _, cx, cz = approach_surface(
            o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], tmin[k], tmax[k], finest,
            finest + 2 if tmin[k] > 0.0 else depth, columns)
        ends[k] = _MISSED if verdict == MISSED else _OCTREE
        if verdict == HANDED_OVER and cx >= 0:
            y, _, _ = top_node_hit(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                   tmin[k], t, tmax[k], cx, cz, finest, columns)
            if y >= 0:
                ends[k] = _TOP_NODE


def _compare(octree, columns, origins, directions, tmin, tmax, stop_level):
    n = len(origins)
    out = np.zeros((n, 8), np.int64)
    times = np.zeros((n, 2))
    ends = np.zeros(n, np.int64)
    _hits(origins, directions, tmin, tmax, octree.inner_nodes, octree.depth, stop_level,
          columns, out, times, ends)
    return out, times, ends


def test_hits_are_the_octree_hits_at_every_fixed_level():
    """Node, level, entry face and time bit for bit, at LOD 0 and coarser, whatever the ray,
    its start bound and its end, with one scratch carried from ray to ray."""
    seen_ends = np.zeros((3, 3), np.int64)
    for scene in (overhanging_terrain(seed=1), overhanging_terrain(seed=7, size=37),
                  random_scene(seed=8, n=900, size=19), hollow_shell_terrain(seed=4)):
        octree, voxels, columns = octree_and_columns(scene)
        origins, directions = any_rays(voxels, 800, seed=len(voxels))
        rng = np.random.default_rng(3)
        n = len(origins)
        # Start bounds as a beam gives them (often before the hit, sometimes past it), and
        # ends short of the scene or open.
        tmin = np.where(rng.random(n) < 0.5, 0.0, rng.uniform(0.0, 30.0, n))
        tmax = np.where(rng.random(n) < 0.7, math.inf, tmin + rng.uniform(0.0, 30.0, n))
        for lod in (0, 1, 2):
            out, times, ends = _compare(octree, columns, origins, directions, tmin, tmax,
                                        octree.depth - lod)
            np.testing.assert_array_equal(out[:, 3:6], out[:, 0:3])
            assert np.array_equal(times[:, 1], times[:, 0])  # inf for misses, bit for bit
            assert (out[:, 0] >= 0).sum() > n // 4  # plenty of hits and misses
            assert (out[:, 0] < 0).sum() > n // 10
            seen_ends[lod] += np.bincount(ends, minlength=3)
    assert np.all(seen_ends > 100), seen_ends  # the walk ends all three ways at every level


@njit
def _primary_walks(o, d, tmin, depth, stop_level, columns, general, primary):
    for k in range(o.shape[0]):
        a = walk_over_columns(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], tmin[k],
                              math.inf, depth, stop_level, columns)
        b = walk_primary_over_columns(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                      tmin[k], depth, stop_level, columns)
        general[k, 0], general[k, 1], general[k, 2], general[k, 3] = a[0], a[1], a[2], a[3]
        general[k, 4], general[k, 5], general[k, 6], general[k, 7] = a[4], a[5], a[6], a[7]
        primary[k, 0], primary[k, 1], primary[k, 2], primary[k, 3] = b[0], b[1], b[2], b[3]
        primary[k, 4], primary[k, 5], primary[k, 6], primary[k, 7] = b[4], b[5], b[6], b[7]


def test_the_renderers_walk_is_the_general_walk():
    """The primary batches' walk (the LOD-0 walk compiled into them) ends every ray as
    ``walk_over_columns`` does: verdict, hand-over time, cells, cell, settled height, hit
    time and face, bit for bit, from the camera and from start bounds, at LOD 0 and above."""
    octree, voxels, columns = octree_and_columns(overhanging_terrain(seed=5))
    origins, directions = any_rays(voxels, 500, seed=11)
    n = len(origins)
    tmin = np.where(np.random.default_rng(2).random(n) < 0.5, 0.0, 3.0)
    settled = 0
    for lod in (0, 1):
        general = np.zeros((n, 8))
        primary = np.zeros((n, 8))
        _primary_walks(origins, directions, tmin, octree.depth, octree.depth - lod, columns,
                       general, primary)
        assert np.array_equal(general, primary)
        settled += int(np.count_nonzero(general[:, 5] >= 0))
    assert settled > n // 4  # the pyramid settles many rays, and the rest walk too


def widened(columns):
    """The pyramid with int32 heights, as worlds over 32,767 voxels high keep them."""
    assert columns.tops.dtype == np.int16
    open16 = gap_open(columns)

    def wide(heights):
        return np.where(heights == open16, GAP_OPEN, heights).astype(np.int32)

    return columns._replace(tops=wide(columns.tops), run_bottom=wide(columns.run_bottom),
                            gap_floor=wide(columns.gap_floor),
                            gap_ceiling=wide(columns.gap_ceiling), floors=wide(columns.floors),
                            cell_records=cell_records(wide(columns.tops),
                                                      wide(columns.gap_floor),
                                                      wide(columns.gap_ceiling)))


def test_int16_and_int32_heights_walk_alike():
    """The kernels read either height type (int16 below 32,767 voxels high): the same hits,
    times, steps and endings, through the gaps of a hollow shell too."""
    for scene in (overhanging_terrain(seed=5), hollow_shell_terrain(seed=6)):
        octree, voxels, columns = octree_and_columns(scene)
        origins, directions = any_rays(voxels, 400, seed=11)
        n = len(origins)
        tmin = np.where(np.arange(n) % 2 == 0, 0.0, 3.0)
        tmax = np.full(n, math.inf)
        for lod in (0, 1):
            narrow = _compare(octree, columns, origins, directions, tmin, tmax,
                              octree.depth - lod)
            wide = _compare(octree, widened(columns), origins, directions, tmin, tmax,
                            octree.depth - lod)
            for a, b in zip(narrow, wide, strict=True):
                np.testing.assert_array_equal(a, b)
            assert np.any(narrow[2] == _TOP_NODE) and np.any(narrow[2] == _OCTREE)


def test_no_pyramid_is_the_octree_alone():
    octree = build_octree(overhanging_terrain(seed=2))
    voxels = octree.node_coords(octree.depth)
    origins, directions = any_rays(voxels, 200, seed=1)
    n = len(origins)
    out, times, _ = _compare(octree, no_column_tops(), origins, directions, np.zeros(n),
                             np.full(n, math.inf), octree.depth)
    np.testing.assert_array_equal(out[:, 3:7], out[:, [0, 1, 2, 7]])  # steps too
    assert np.array_equal(times[:, 1], times[:, 0])


def test_rays_onto_ground_end_in_the_pyramid_without_the_octree():
    """Rays from high above onto a flat 64² field skip the air in the pyramid and land on a
    column's top voxel: no octree walk, one step for the voxel after the cells."""
    x, z = np.meshgrid(np.arange(64), np.arange(64), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, np.int64), z.ravel()], axis=1)
    octree = build_octree(VoxelScene(coords, np.full((x.size, 3), 0.5), name="ground"))
    columns = column_tops(octree.node_coords(octree.depth))
    rng = np.random.default_rng(0)
    n = 500
    origins = np.column_stack([rng.uniform(8, 56, n), np.full(n, 60.0), rng.uniform(8, 56, n)])
    directions = np.column_stack([rng.uniform(-0.1, 0.1, n), -np.ones(n),
                                  rng.uniform(-0.1, 0.1, n)])
    out, times, ends = _compare(octree, columns, origins, directions, np.zeros(n),
                                np.full(n, math.inf), octree.depth)
    np.testing.assert_array_equal(out[:, 3:6], out[:, 0:3])
    hit = out[:, 0] >= 0
    assert hit.all() and np.all(ends == _TOP_NODE)
    assert np.all(out[:, 5] == 3)  # entered through the top face (+y)


def test_ray_queries_through_the_pyramid_are_the_octree_hits():
    """``ray_query.trace(columns=True)`` starts each walk at the finest level, as rays that
    leave a surface do: the same hits from voxel faces, from above and from anywhere."""
    from voxfield.render.ray_query import trace

    octree = build_octree(overhanging_terrain(seed=9, size=33))
    voxels = octree.node_coords(octree.depth)
    origins, directions = any_rays(voxels, 600, seed=2)
    rng = np.random.default_rng(5)
    faces = voxels[rng.integers(0, len(voxels), 600)] + np.array([0.5, 1.0, 0.5])
    up = rng.normal(size=(600, 3))
    up[:, 1] = np.abs(up[:, 1])
    origins, directions = np.concatenate([origins, faces]), np.concatenate([directions, up])
    for lod in (0, 1, 2):
        for tmin in (0.0, 1.5):
            walked = trace(octree, origins, directions, lod=lod, tmin=tmin, columns=True)
            alone = trace(octree, origins, directions, lod=lod, tmin=tmin)
            for name in ("node", "level", "normal_code"):
                assert np.array_equal(getattr(walked, name), getattr(alone, name)), name
            assert np.array_equal(walked.t, alone.t)
            assert np.any(walked.steps != alone.steps)  # the walk was taken


@njit
def _walks(o, d, tmin, finest, start_level, columns, patience, ends, times, cells):
    for k in range(o.shape[0]):
        verdict, t, steps, cx, cz = approach_surface(
            o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], tmin[k], math.inf, finest,
            start_level, columns, patience)
        ends[k, 0] = verdict
        ends[k, 1] = cx
        ends[k, 2] = cz
        times[k] = t
        cells[k] = steps


def test_climb_patience_changes_the_route_not_the_answer():
    """However many cells a walk skips before it climbs (``CLIMB_PATIENCE``), it hands every
    ray over at the same time in the same cell, or misses it alike: a cell it skips whole
    holds no cell of a finer level it could not skip. Only the cells it visits differ."""
    from voxfield.kernels.surface_approach import CLIMB_PATIENCE

    for scene in (overhanging_terrain(seed=3, size=41), hollow_shell_terrain(seed=2)):
        octree, voxels, columns = octree_and_columns(scene)
        origins, directions = any_rays(voxels, 600, seed=4)
        n = len(origins)
        tmin = np.random.default_rng(6).uniform(0.0, 20.0, n)
        for finest in (0, 1):
            walks = []
            for patience in (0, 1, CLIMB_PATIENCE, 64):
                ends = np.zeros((n, 3), np.int64)
                times = np.zeros(n)
                cells = np.zeros(n, np.int64)
                _walks(origins, directions, tmin, finest, finest + 2, columns, patience, ends,
                       times, cells)
                walks.append((ends, times, cells))
            eager = walks[0]
            handed_over = eager[0][:, 0] == HANDED_OVER  # (a miss's time is where it gave up)
            for ends, times, _ in walks[1:]:
                np.testing.assert_array_equal(ends, eager[0])
                assert np.array_equal(times[handed_over], eager[1][handed_over])
            assert np.any(walks[-1][2] != eager[2])  # patience took other routes
            assert np.any(eager[0][:, 0] == HANDED_OVER) and np.any(eager[0][:, 0] == MISSED)


def test_rays_from_the_camera_begin_at_the_level_of_their_height():
    """A ray from the camera (``tmin`` 0) begins its walk at the level of its height over the
    ground below it, one level above the sampled one at least: straight down onto a flat 64²
    field from 0.5 voxels above, it visits two cells and lands, where from the top it
    would go down all seven levels; from higher up it begins higher, and every ray lands
    on the same voxel as from the octree alone."""
    from voxfield.kernels.surface_approach import NEAR_START_LEVELS

    octree, _, columns = octree_and_columns(flat_ground())
    levels = columns.level_width.shape[0]
    cells = {}
    for height in (0.5, 8.0, 40.0):
        visited = []
        for ox, oz in ((10.5, 20.5), (33.25, 47.75), (60.5, 2.5)):
            verdict, _, walked, cx, cz, y, t, normal = walk_over_columns(
                ox, 1.0 + height, oz, 0.0, -1.0, 0.0, 0.0, math.inf, octree.depth,
                octree.depth, columns)
            assert (cx, cz, y, normal) == (int(ox), int(oz), 0, 3) and t == height
            visited.append(walked)
        cells[height] = max(visited)
    assert cells[0.5] == NEAR_START_LEVELS + 1 < levels
    assert cells[0.5] < cells[8.0] < cells[40.0] <= levels
