"""Watertightness: the octree traversal against a brute-force every-box oracle.

Zero mismatches in the hit node are required, at LOD 0 and at coarser LODs (against the
LOD grid), on rays that include axis-aligned, face-grazing, edge- and corner-hitting cases.
"""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from ray_oracle import first_hits
from voxfield.errors import VoxfieldError
from voxfield.kernels.ray_batch import trace_rays
from voxfield.kernels.traversal import NO_NORMAL
from voxfield.render import ray_query
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree


def trace(octree, origins, directions, lod=0, tmin=0.0):
    hits = ray_query.trace(octree, origins, directions, lod=lod, tmin=tmin)
    return hits.node, hits.level, hits.t, hits.normal_code, hits.steps


def adversarial_rays(lo, hi, n_random, seed):
    """Generic rays plus exact axis-aligned, grazing, edge and corner cases around a box."""
    rng = np.random.default_rng(seed)
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    center = (lo + hi) / 2
    radius = np.linalg.norm(hi - lo)
    parts_o, parts_d = [], []
    # Generic: from a sphere around the scene towards random points inside it.
    u = rng.normal(size=(n_random, 3))
    o = center + radius * u / np.linalg.norm(u, axis=1)[:, None]
    d = rng.uniform(lo, hi, size=(n_random, 3)) - o
    parts_o.append(o)
    parts_d.append(d)
    # Axis-aligned, starting on integer and half-integer lattice lines outside the box.
    m = n_random // 4
    for axis in range(3):
        for sign in (-1.0, 1.0):
            o = np.round(rng.uniform(lo - 1, hi + 1, size=(m // 6, 3)) * 2) / 2
            o[:, axis] = lo[axis] - 3 if sign > 0 else hi[axis] + 3
            d = np.zeros((len(o), 3))
            d[:, axis] = sign
            parts_o.append(o)
            parts_d.append(d)
    # Grazing: one direction component exactly zero, origin exactly on a voxel face plane.
    o = rng.uniform(lo - 2, hi + 2, size=(m, 3))
    flat = rng.integers(0, 3, size=m)
    o[np.arange(m), flat] = np.round(o[np.arange(m), flat])
    d = rng.normal(size=(m, 3))
    d[np.arange(m), flat] = 0.0
    parts_o.append(o)
    parts_d.append(d)
    # Edge and corner hits: integer origins with small-integer directions pass exactly
    # through lattice edges and corners (all crossing times are exact in float64).
    o = np.round(rng.uniform(lo - 4, hi + 4, size=(m, 3)))
    d = rng.integers(-2, 3, size=(m, 3)).astype(np.float64)
    d[np.all(d == 0, axis=1)] = (1.0, 1.0, 1.0)
    parts_o.append(o)
    parts_d.append(d)
    # Diagonals through voxel corners from inside the bounds (origins in empty or full space).
    o = np.round(rng.uniform(lo, hi, size=(m, 3)))
    d = rng.choice([-1.0, 1.0], size=(m, 3))
    parts_o.append(o)
    parts_d.append(d)
    return np.concatenate(parts_o), np.concatenate(parts_d)


def assert_matches_oracle(octree, origins, directions, lod):
    node, level, t, normal, steps = trace(octree, origins, directions, lod)
    boxes = octree.lod_voxels(lod)
    expected, t_expected = first_hits(origins, directions, boxes, 2**lod)
    start = octree.level_slice(octree.depth - lod).start
    got = np.where(node >= 0, node - start, -1)
    mismatches = int((got != expected).sum())
    assert mismatches == 0, f"{mismatches} of {len(got)} rays disagree with the oracle at LOD {lod}"
    hit = got >= 0
    assert np.array_equal(t[hit], t_expected[hit])
    assert np.all(level[hit] == octree.depth - lod)
    # Normals: the axis whose slab is entered last, pointing against the ray.
    corner = boxes[got[hit]].astype(np.float64)
    o, d = origins[hit], directions[hit]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d = np.where(np.isfinite(1.0 / d), d, 0.0)  # the kernel's zero rule
        enter = np.where(d > 0, (corner - o) / d, (corner + 2**lod - o) / d)
    enter = np.where(d == 0, -np.inf, enter)
    inside = t[hit] <= 0.0
    axis = np.argmax(enter, axis=1)
    expected_code = 2 * axis + (d[np.arange(len(d)), axis] < 0)
    assert np.array_equal(normal[hit][~inside], expected_code[~inside])
    assert np.all(normal[hit][inside] == NO_NORMAL)
    return steps


def test_real_vox_scene_has_zero_mismatches_on_100k_rays(shared_data):
    from voxfield.scene.vox import load_vox

    octree = build_octree(load_vox(shared_data / "vox" / "chr_knight.vox"))
    lo, hi = octree.voxel_bounds
    origins, directions = adversarial_rays(lo, hi, 60_000, seed=1)
    assert len(origins) >= 100_000
    for lod in range(3):
        steps = assert_matches_oracle(octree, origins, directions, lod)
        assert steps.min() >= 0


def test_crop_of_a_real_monument_at_three_lods(shared_data):
    from voxfield.scene.vox import load_vox

    scene = load_vox(shared_data / "vox" / "monu1.vox")
    keep = np.all((scene.coords >= [20, 0, 20]) & (scene.coords < [52, 32, 52]), axis=1)
    octree = build_octree(scene.subset(keep))
    lo, hi = octree.voxel_bounds
    origins, directions = adversarial_rays(lo, hi, 3_000, seed=2)
    for lod in range(3):
        assert_matches_oracle(octree, origins, directions, lod)


@pytest.mark.parametrize("seed", [0, 1])
def test_random_scene_without_data(seed):
    octree = build_octree(random_scene(seed, n=500, size=16))
    lo, hi = octree.voxel_bounds
    origins, directions = adversarial_rays(lo, hi, 8_000, seed=seed)
    for lod in range(octree.depth + 1):
        assert_matches_oracle(octree, origins, directions, lod)


def test_steps_count_every_node_on_the_way_down():
    # One voxel at the far corner of a 16^3 root: a ray straight at it visits one node per level.
    scene = VoxelScene(np.array([[0, 0, 0], [15, 15, 15]]), np.ones((2, 3)))
    octree = build_octree(scene)
    node, level, t, normal, steps = trace(octree, np.array([[15.5, 15.5, 40.0]]),
                                          np.array([[0.0, 0.0, -1.0]]))
    assert level[0] == 4 and t[0] == 40.0 - 16.0 and normal[0] == 5  # +z face
    assert steps[0] == 5  # root, three inner nodes, the voxel
    # A ray missing the root visits nothing.
    *_, steps = trace(octree, np.array([[-1.0, -1.0, -1.0]]), np.array([[-1.0, 0.0, 0.0]]))
    assert steps[0] == 0


def test_ray_query_rejects_bad_rays():
    octree = build_octree(VoxelScene(np.array([[0, 0, 0]]), np.ones((1, 3))))
    with pytest.raises(VoxfieldError, match="N×3"):
        ray_query.trace(octree, np.zeros((2, 2)), np.ones((2, 2)))
    with pytest.raises(VoxfieldError, match="zero vector"):
        ray_query.trace(octree, np.zeros((1, 3)), np.zeros((1, 3)))
    # Along a direction whose components are all subnormal every hit time overflows: the
    # ray was reported as a miss. Normal components are enough.
    down = np.array([[-1e-310, -1e-320, -1e-310], [-1e-300, -1e-300, -1e-300]])
    for query in (ray_query.trace, ray_query.occluded):
        with pytest.raises(VoxfieldError, match=r"ray 0's direction \[-1e-310, -1e-320, "
                                                r"-1e-310\] is too short to measure times"):
            query(octree, np.full((2, 3), 3.0), down)
    assert ray_query.trace(octree, np.full((1, 3), 3.0), down[1:]).hit[0]
    assert ray_query.occluded(octree, np.full((1, 3), 3.0), down[1:]).blocked[0]
    with pytest.raises(VoxfieldError, match="NaN"):
        ray_query.trace(octree, np.full((1, 3), np.nan), np.ones((1, 3)))


def test_rays_starting_inside_a_voxel_hit_it_at_tmin():
    octree = build_octree(VoxelScene(np.array([[0, 0, 0], [3, 3, 3]]), np.ones((2, 3))))
    node, level, t, normal, _ = trace(octree, np.array([[0.5, 0.5, 0.5]]), np.array([[1.0, 0, 0]]))
    assert node[0] >= 0 and t[0] == 0.0 and normal[0] == NO_NORMAL


def test_denormal_direction_components_count_as_zero_and_nan_rays_miss():
    octree = build_octree(random_scene(3, n=300, size=8))
    rng = np.random.default_rng(5)
    origins = rng.uniform(-3, 11, size=(2000, 3))
    directions = rng.normal(size=(2000, 3))
    directions[::2, 1] = 1e-320  # 1 / d overflows
    assert_matches_oracle(octree, origins, directions, 0)
    n = 3
    outs = [np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n), np.empty(n, np.int64),
            np.empty(n, np.int64)]
    bad_o = np.array([[np.nan, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    bad_d = np.array([[1.0, 0.0, 0.0], [np.inf, 0.0, 0.0], [1.0, 0.0, 0.0]])
    trace_rays(bad_o, bad_d, 0.0, np.nan, octree.inner_nodes, octree.depth, octree.depth, *outs)
    assert np.all(outs[0] == -1) and np.all(outs[4] == 0)
