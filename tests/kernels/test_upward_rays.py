"""Rising rays over the column-top pyramid get exactly the octree's any-hit answer."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from random_scenes import (
    hollow_shell_terrain,
    octree_and_columns,
    overhanging_terrain,
    pillar_field,
    random_scene,
    rising_rays,
)
from voxfield.kernels.traversal import new_scratch, occluded
from voxfield.kernels.upward_rays import (
    BLOCKED,
    CLEAR,
    UNDECIDED,
    clears_horizon,
    parallel_rays_clear,
    rising_ray_query,
)
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.column_tops import column_tops, gap_open, no_column_tops, tops_ahead
from voxfield.svo.horizons import horizon_slopes, no_horizon_slopes


@njit
def _answers(o, d, tmax, inner, depth, columns, out, t_clear):
    """Per ray: the pyramid's verdict, the octree over the whole ray, the octree from the
    hand-over time on, and the cells the pyramid visited; each walk starts at its ray's
    ``t_clear`` (0: at its origin)."""
    for k in range(o.shape[0]):
        verdict, t, cells = rising_ray_query(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1],
                                             d[k, 2], tmax[k], columns, t_clear[k])
        whole, _ = occluded(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], 0.0,
                            tmax[k], inner, depth, new_scratch(depth))
        rest = whole
        if verdict == UNDECIDED:
            rest, _ = occluded(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2], t,
                               tmax[k], inner, depth, new_scratch(depth))
        out[k, 0] = verdict
        out[k, 1] = 1 if whole else 0
        out[k, 2] = 1 if rest else 0
        out[k, 3] = cells


def _verdicts(octree, voxels, columns):
    """The pyramid's verdicts on rising rays (``rising_rays``) with a mix of stops, checked
    against the octree's answers."""
    origins, directions = rising_rays(voxels, 1500, seed=len(voxels))
    rng = np.random.default_rng(1)
    # The bake stops rays at the top of the voxels; others run on, or stop anywhere.
    top = voxels[:, 1].max() + 1.0
    tmax = np.where(rng.random(len(origins)) < 0.5,
                    (top - origins[:, 1]) / directions[:, 1],
                    rng.choice([math.inf, 2.0, 7.5], len(origins)))
    out = np.empty((len(origins), 4), np.int64)
    _answers(origins, directions, tmax, octree.inner_nodes, octree.depth, columns, out,
             np.zeros(len(origins)))
    verdict, whole, rest = out[:, 0], out[:, 1], out[:, 2]
    assert np.all(whole[verdict == CLEAR] == 0)
    assert np.all(whole[verdict == BLOCKED] == 1)
    assert np.array_equal(rest[verdict == UNDECIDED], whole[verdict == UNDECIDED])
    return verdict


def test_rising_rays_get_the_octree_answer_in_scenes_with_overhangs_and_caves():
    for scene in (overhanging_terrain(seed=0), overhanging_terrain(seed=5, size=37),
                  random_scene(seed=6, n=900, size=17), hollow_shell_terrain(seed=3)):
        verdict = _verdicts(*octree_and_columns(scene))
        assert set(verdict.tolist()) == {CLEAR, BLOCKED, UNDECIDED}


def test_rays_under_the_runs_cross_the_gaps_in_the_pyramid():
    """Inside a hollow shell and under ledges, rays that stay in the gap every column of an
    area leaves are settled by the walk: fewer go to the octree than with no gaps known,
    and the answers are still the octree's."""
    for seed in (3, 8):
        octree, voxels, columns = octree_and_columns(hollow_shell_terrain(seed=seed))
        no_gaps = columns._replace(gap_floor=np.full_like(columns.gap_floor, gap_open(columns)),
                                   gap_ceiling=np.zeros_like(columns.gap_ceiling))
        with_gaps = _verdicts(octree, voxels, columns)
        without = _verdicts(octree, voxels, no_gaps)
        assert (with_gaps == UNDECIDED).sum() < 0.8 * (without == UNDECIDED).sum()
        assert np.all(with_gaps[without != UNDECIDED] == without[without != UNDECIDED])


def test_on_a_solid_height_field_every_ray_from_the_ground_up_is_settled_by_columns():
    """Columns filled from the bottom to their top are one run each, so a rising ray that
    dips below a column's top meets its voxels: no ray from on or above the ground needs
    the octree, and the answers are still the octree's."""
    rng = np.random.default_rng(7)
    size = 40
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    height = 1 + np.round(4 + 3 * np.sin(x / 5.0) * np.cos(z / 7.0) + rng.random(x.shape))
    voxels = np.array([(i, y, k) for i in range(size) for k in range(size)
                       for y in range(int(height[i, k]))])
    octree = build_octree(VoxelScene(voxels, np.full((len(voxels), 3), 0.5)))
    voxels = octree.node_coords(octree.depth)
    columns = column_tops(voxels)
    n = 4000
    cells = rng.integers(0, size, (n, 2))
    origins = np.stack([cells[:, 0] + rng.random(n),
                        height[cells[:, 0], cells[:, 1]] + 3 * rng.random(n),
                        cells[:, 1] + rng.random(n)], axis=1)
    origins[::2, 1] = height[cells[::2, 0], cells[::2, 1]]  # exactly on the top face
    directions = rng.normal(size=(n, 3))
    directions[:, 1] = np.abs(directions[:, 1]) * rng.choice([0.1, 1.0], n) + 1e-6
    out = np.empty((n, 4), np.int64)
    _answers(origins, directions, np.full(n, math.inf), octree.inner_nodes, octree.depth,
             columns, out, np.zeros(n))
    assert not np.any(out[:, 0] == UNDECIDED)
    assert np.array_equal(out[:, 0] == BLOCKED, out[:, 1] == 1)
    assert 0.1 < (out[:, 0] == BLOCKED).mean() < 0.9


def test_without_a_pyramid_or_a_rise_rays_go_to_the_octree_from_their_start():
    scene = overhanging_terrain(seed=2, size=12)
    octree = build_octree(scene)
    columns = column_tops(octree.node_coords(octree.depth))
    assert rising_ray_query(3.5, 20.0, 3.5, 0.0, 1.0, 0.0, math.inf, columns)[0] == CLEAR
    assert rising_ray_query(3.5, 20.0, 3.5, 0.0, 1.0, 0.0, math.inf,
                            no_column_tops()) == (UNDECIDED, 0.0, 0)
    assert rising_ray_query(3.5, 20.0, 3.5, 1.0, 1e-12, 0.0, math.inf,
                            columns) == (UNDECIDED, 0.0, 0)


@njit
def _parallel_answers(corners, d, ahead_offsets, columns, tops_ahead, inner, depth, y_top,
                      out, out_t):
    """Per corner: ``parallel_rays_clear``'s answer and steps, then how many of the rays
    from the points ``corner + offset`` (one row of offsets per corner) the octree finds
    blocked in what the walk calls clear: up to the top of the voxels when it settles the
    corner, else up to its ``t_clear`` (in ``out_t``)."""
    scratch = new_scratch(depth)
    for k in range(corners.shape[0]):
        ox, oy, oz = corners[k, 0], corners[k, 1], corners[k, 2]
        clear, steps, t_clear = parallel_rays_clear(ox, oy, oz, d[k, 0], d[k, 1], d[k, 2],
                                                    (y_top - oy) / d[k, 1], columns,
                                                    tops_ahead[k])
        blocked = 0
        for s in range(ahead_offsets.shape[1]):
            px = ox + ahead_offsets[k, s, 0]
            py = oy + ahead_offsets[k, s, 1]
            pz = oz + ahead_offsets[k, s, 2]
            tmax = (y_top - py) / d[k, 1]
            hit, _ = occluded(px, py, pz, d[k, 0], d[k, 1], d[k, 2], 0.0,
                              tmax if clear else min(t_clear, tmax), inner, depth, scratch)
            blocked += 1 if hit else 0
        out[k, 0] = 1 if clear else 0
        out[k, 1] = steps
        out[k, 2] = blocked
        out_t[k] = t_clear


def test_parallel_rays_called_clear_are_all_clear_for_the_octree():
    """A face's shadow rays settled together from its rear corner: every ray from a point
    ahead of the corner by less than one column (and no lower) is clear when the walk says
    so, including points on the corner and a hair short of one column ahead; and the walk
    does settle most corners on open ground. Where it does not, each ray is still clear up
    to where it stopped, and its own walk resumed there gives the whole ray's answer."""
    rng = np.random.default_rng(11)
    resumed = 0
    for scene in (overhanging_terrain(seed=4, size=30), hollow_shell_terrain(seed=2),
                  random_scene(seed=9, n=700, size=15)):
        octree, voxels, columns = octree_and_columns(scene)
        y_top = voxels[:, 1].max() + 1.0
        n = 600
        # Corners on the tops and sides of voxels, and anywhere around them.
        corners = voxels[rng.integers(0, len(voxels), n)].astype(np.float64)
        corners += rng.integers(0, 2, (n, 3))
        corners[n // 2:] = rng.uniform(voxels.min(axis=0) - 2, voxels.max(axis=0) + 3,
                                       (n - n // 2, 3))
        d = rng.normal(size=(n, 3))
        d[:, 1] = np.abs(d[:, 1]) * rng.choice([0.1, 0.5, 2.0], n) + 1e-3
        d[:n // 8, 0] = 0.0  # along a grid plane: ahead counts as +x
        d /= np.linalg.norm(d, axis=1)[:, None]
        step_x = np.where(d[:, 0] >= 0.0, 1, -1)
        step_z = np.where(d[:, 2] >= 0.0, 1, -1)
        ahead = {(a, b): tops_ahead(columns, a, b) for a in (1, -1) for b in (1, -1)}
        tops_of = np.stack([ahead[a, b] for a, b in zip(step_x, step_z, strict=True)])
        samples = 12
        offsets = rng.random((n, samples, 3))
        offsets[:, 0] = 0.0  # the corner itself
        offsets[:, 1, [0, 2]] = 1.0 - 1e-12  # just short of a column ahead
        offsets[:, :, 1] *= rng.choice([0.0, 1.0], (n, samples))  # often at its height
        offsets[:, :, 0] *= step_x[:, None]
        offsets[:, :, 2] *= step_z[:, None]
        out = np.empty((n, 3), np.int64)
        t_clear = np.empty(n)
        _parallel_answers(corners, d, offsets, columns, tops_of, octree.inner_nodes,
                          octree.depth, y_top, out, t_clear)
        clear = out[:, 0] == 1
        assert not np.any(out[clear, 2]), "a ray called clear is blocked"
        assert not np.any(out[~clear, 2]), "a ray is blocked before the walk's t_clear"
        assert 0.2 < clear.mean() < 1.0
        # Each ray of an unsettled corner walked on its own from the corner's t_clear (the
        # octree from where that walk leaves it) gets the whole ray's answer.
        points = (corners[:, None, :] + offsets)[~clear].reshape(-1, 3)
        rays = np.repeat(d[~clear], samples, axis=0)
        answers = np.empty((len(points), 4), np.int64)
        _answers(points, rays, (y_top - points[:, 1]) / rays[:, 1], octree.inner_nodes,
                 octree.depth, columns, answers, np.repeat(t_clear[~clear], samples))
        resumed_blocked = np.where(answers[:, 0] == UNDECIDED, answers[:, 2] == 1,
                                   answers[:, 0] == BLOCKED)
        assert np.array_equal(resumed_blocked, answers[:, 1] == 1), "a resumed walk errs"
        assert np.any(answers[:, 1] == 1)  # some rays of unsettled corners are blocked
        from_origin = np.empty_like(answers)
        _answers(points, rays, (y_top - points[:, 1]) / rays[:, 1], octree.inner_nodes,
                 octree.depth, columns, from_origin, np.zeros(len(points)))
        assert answers[:, 3].sum() < from_origin[:, 3].sum()  # the point: fewer cells
        resumed += np.count_nonzero(t_clear[~clear] > 0.0)
    assert resumed >= 50  # walks resumed past 0 often enough to tell


def test_parallel_rays_are_not_settled_without_a_pyramid_or_a_rise():
    scene = overhanging_terrain(seed=2, size=12)
    octree = build_octree(scene)
    columns = column_tops(octree.node_coords(octree.depth))
    ahead = tops_ahead(columns, 1, 1)
    assert parallel_rays_clear(3.0, 20.0, 3.0, 0.0, 1.0, 0.0, 10.0, columns, ahead)[0]
    assert parallel_rays_clear(3.0, 20.0, 3.0, 0.0, 1.0, 0.0, 10.0, no_column_tops(),
                               np.zeros(0, np.int32)) == (False, 0, 0.0)
    assert parallel_rays_clear(3.0, 20.0, 3.0, 1.0, 1e-12, 0.0, 10.0, columns,
                               ahead) == (False, 0, 0.0)


@njit
def _settled_by_horizon(o, d, columns, horizons, out):
    """Per ray: whether ``clears_horizon`` settles it."""
    for k in range(o.shape[0]):
        out[k] = clears_horizon(o[k, 0], o[k, 1], o[k, 2], d[k, 0], d[k, 1], d[k, 2],
                                columns, horizons)


def test_rays_steeper_than_their_columns_horizon_are_clear_for_the_octree():
    """Rays from faces, lattice points, grid planes and anywhere around: every one the
    horizon slope settles is clear all the way up, pillars far away included, and on open
    ground the slopes settle many."""
    for seed, scene in enumerate((pillar_field(seed=1), pillar_field(seed=4, size=70),
                                  overhanging_terrain(seed=0), hollow_shell_terrain(seed=3),
                                  random_scene(seed=6, n=900, size=17))):
        octree, voxels, columns = octree_and_columns(scene)
        origins, directions = rising_rays(voxels, 4000, seed=seed)
        settled = np.empty(len(origins), np.bool_)
        _settled_by_horizon(origins, directions, columns, horizon_slopes(columns), settled)
        out = np.empty((len(origins), 4), np.int64)
        _answers(origins, directions, np.full(len(origins), math.inf), octree.inner_nodes,
                 octree.depth, columns, out, np.zeros(len(origins)))
        hit = out[:, 1] == 1
        assert not np.any(hit[settled]), "a ray called clear is blocked"
        assert settled.sum() >= 100
        assert np.any(hit[~settled])


def test_far_pillars_keep_flat_rays_unsettled():
    """From the ground of a pillar field, a flat ray towards a pillar taller than it will be
    when it gets there is never settled; a steep one from the same place is."""
    octree, voxels, columns = octree_and_columns(pillar_field(seed=1))
    tops = columns.tops[: int(columns.level_width[0] * columns.level_depth[0])].reshape(
        int(columns.level_width[0]), int(columns.level_depth[0]))
    horizons = horizon_slopes(columns)
    starts = [(px - k, pz) for px, pz in np.argwhere(tops >= 30) for k in range(10, 20)
              if px - k >= 0 and tops[px - k, pz] == 2
              and tops[px - k: px - k + 4, pz: pz + 4].max() <= 2]
    assert starts, "no open ground before a tall pillar"
    for x, z in starts:
        start = (x + 0.5, 2.0, z + 0.5)
        assert not clears_horizon(*start, 1.0, 0.05, 0.0, columns, horizons)
        assert clears_horizon(*start, 0.01, 1.0, 0.005, columns, horizons)


def test_without_slopes_or_a_rise_the_horizon_settles_nothing():
    scene = overhanging_terrain(seed=2, size=12)
    columns = column_tops(build_octree(scene).node_coords(build_octree(scene).depth))
    horizons = horizon_slopes(columns)
    assert clears_horizon(3.5, 20.0, 3.5, 0.3, 1.0, 0.0, columns, horizons)
    assert not clears_horizon(3.5, 20.0, 3.5, 0.3, 1.0, 0.0, columns, no_horizon_slopes())
    assert not clears_horizon(3.5, 20.0, 3.5, 1.0, 1e-12, 0.0, columns, horizons)
    assert not clears_horizon(-5.5, 20.0, 3.5, 1.0, 1.0, 0.0, columns, horizons)
