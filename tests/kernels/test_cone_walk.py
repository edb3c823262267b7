"""Cone-LOD rays walked over the column-top pyramid end where the octree alone ends them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from random_scenes import (
    any_rays,
    flat_ground,
    hollow_shell_terrain,
    octree_and_columns,
    overhanging_terrain,
    pillar_field,
    random_scene,
)
from voxfield.kernels.cone_walk import (
    MISSED_ALL,
    cone_level,
    trace_cone_over_columns,
    walk_cone_over_columns,
)
from voxfield.kernels.traversal import new_scratch, trace_ray


@njit
def _both(rays, depth, inner_nodes, columns, radius, spread, walked, alone, ends):
    scratch = new_scratch(depth)
    for k in range(rays.shape[0]):
        ox, oy, oz, dx, dy, dz, tmin = (rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3],
                                        rays[k, 4], rays[k, 5], rays[k, 6])
        node, level, t, normal, steps = trace_cone_over_columns(
            ox, oy, oz, dx, dy, dz, tmin, inner_nodes, depth, radius, spread, scratch,
            columns)
        walked[k, 0], walked[k, 1], walked[k, 3], walked[k, 4] = node, level, normal, steps
        walked[k, 2] = t
        node, level, t, normal, steps = trace_ray(ox, oy, oz, dx, dy, dz, tmin, math.inf,
                                                  inner_nodes, depth, depth, radius, spread,
                                                  scratch)
        alone[k, 0], alone[k, 1], alone[k, 3], alone[k, 4] = node, level, normal, steps
        alone[k, 2] = t
        _, cells, cx, _, _ = walk_cone_over_columns(ox, oy, oz, dx, dy, dz, tmin, radius,
                                                    spread, depth, columns)
        ends[k, 0] = cx
        ends[k, 1] = cells


def _walk_both(rays, octree, columns, radius, spread):
    """``_both``'s rows for ``rays``: ``(walked, alone, ends)``."""
    walked = np.zeros((len(rays), 5))
    alone = np.zeros((len(rays), 5))
    ends = np.zeros((len(rays), 2), np.int64)
    _both(rays, octree.depth, octree.inner_nodes, columns, radius, spread, walked, alone,
          ends)
    return walked, alone, ends


def _rays(voxels, n, seed):
    """``any_rays``, from their origin or from a start bound part of the way along."""
    origins, directions = any_rays(voxels, n, seed=seed)
    rng = np.random.default_rng(seed)
    tmin = np.where(rng.random(len(origins)) < 0.5, 0.0, rng.uniform(0.0, 30.0, len(origins)))
    return np.column_stack([origins, directions, tmin])


@pytest.mark.parametrize("scene", [
    overhanging_terrain(seed=3, size=45), hollow_shell_terrain(seed=2, size=37),
    random_scene(seed=5, n=900, size=21), pillar_field(seed=6, size=50),
], ids=lambda scene: scene.name)
@pytest.mark.parametrize("radius, spread", [(0.4, 0.15), (0.0, 0.3), (1.5, 0.08)])
def test_cone_rays_over_the_pyramid_are_the_octrees(scene, radius, spread):
    """Node, level, hit time and entry face of every ray, bit for bit, for cones that take
    voxels near the start and nodes of side 2 to 8 further on; the walk lands rays on
    cell tops, hands others to the octree and ends some past the footprint itself."""
    octree, voxels, columns = octree_and_columns(scene)
    rays = _rays(voxels, 600, seed=len(voxels))
    n = len(rays)
    walked, alone, ends = _walk_both(rays, octree, columns, radius, spread)
    np.testing.assert_array_equal(walked[:, [0, 1, 3]], alone[:, [0, 1, 3]])
    assert np.array_equal(walked[:, 2], alone[:, 2])  # bit for bit, infinities too
    hits = alone[:, 0] >= 0
    assert hits.sum() > n // 4 and (~hits).sum() > n // 20
    assert (alone[hits, 1] < octree.depth).sum() > n // 40  # coarser nodes taken too
    assert (ends[:, 0] >= 0).sum() > n // 10 and (ends[:, 0] == MISSED_ALL).sum() > 0
    assert ends[:, 1].max() > 4


def test_the_cone_level_is_the_traversals_own_test():
    """The largest side ``2^level`` with ``side <= radius + spread·t``: a node at the
    boundary is taken, one a hair over it is not."""
    assert cone_level(0.0, 0.5, 0.1, 10) == 0
    assert cone_level(10.0, 0.0, 0.2, 10) == 1  # cone 2: side 2 taken, 4 not
    assert cone_level(np.nextafter(10.0, 0.0), 0.0, 0.2, 10) == 0
    assert cone_level(-5.0, 4.0, 1.0, 10) == 2  # behind the eye the cone is its radius
    assert cone_level(1e9, 0.0, 1.0, 6) == 6  # never past the root


def test_cone_rays_from_the_camera_begin_at_the_level_of_their_height():
    """A cone ray from the camera (``tmin`` 0) begins its walk at the level of its height
    over the ground below it, as a fixed-level walk does (``surface_approach.BY_HEIGHT``):
    steeply down onto a flat 64² field from 0.5 voxels above, a cone that takes voxels
    visits two cells, where from the top it would go down all seven levels; from higher up
    it begins higher, and every ray ends where the octree alone ends it, bit for bit."""
    from voxfield.kernels.surface_approach import NEAR_START_LEVELS

    octree, _, columns = octree_and_columns(flat_ground())
    levels = columns.level_width.shape[0]
    radius, spread = 0.4, 0.002  # voxels all the way down from 40 voxels up
    direction = np.array([0.25, -1.0, 0.125]) / np.linalg.norm([0.25, -1.0, 0.125])
    cells = {}
    for height in (0.5, 8.0, 40.0):
        starts = [(ox, 1.0 + height, oz) for ox, oz in ((10.5, 20.5), (33.25, 47.75),
                                                        (40.5, 2.5))]
        rays = np.array([[*start, *direction, 0.0] for start in starts])
        walked, alone, ends = _walk_both(rays, octree, columns, radius, spread)
        np.testing.assert_array_equal(walked[:, :4], alone[:, :4])
        assert (walked[:, 1] == octree.depth).all() and (walked[:, 3] == 3).all()
        assert (ends[:, 0] >= 0).all()  # every one lands on its cell's top voxel
        cells[height] = ends[:, 1].max()
    assert cells[0.5] == NEAR_START_LEVELS + 1 < levels
    assert cells[0.5] < cells[8.0] < cells[40.0]


def test_vertical_rays_of_a_cone_with_no_spread_land_on_the_nodes_it_takes():
    """An orthographic camera's cone has no spread: as wide where a vertical ray would leave
    its column (never) as anywhere. Straight down onto a flat 64² field, a cone that takes
    nodes of side 2 walks to their level and lands on the cell's top node (the walk's cells
    and one step), where the octree alone ends it."""
    octree, _, columns = octree_and_columns(flat_ground())
    starts = [(10.5, 20.0, 20.5), (33.25, 5.0, 47.75), (40.5, 60.0, 2.5)]
    rays = np.array([[*start, 0.0, -1.0, 0.0, tmin] for start in starts for tmin in (0.0, 3.0)])
    walked, alone, ends = _walk_both(rays, octree, columns, 2.5, 0.0)
    np.testing.assert_array_equal(walked[:, :4], alone[:, :4])
    assert (walked[:, 1] == octree.depth - 1).all()  # nodes of side 2
    assert (walked[:, 4] == ends[:, 1] + 1).all()  # landed: the cells, then one step
