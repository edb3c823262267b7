"""Which probe answers a hit's colour: the sharpest view of the point (``footprint``) or the
view most like the ray's (``parallel``), and never the back of a surface."""

from __future__ import annotations

import numpy as np
import pytest
from lf_helpers import bake_grid

from voxfield.errors import VoxfieldError
from voxfield.kernels.probe_multi import sees_front
from voxfield.lightfield import HIT, LightFieldOptions, trace_light_field
from voxfield.probes.grid import ProbeGrid
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

LOW, HIGH = 0, 1  # probe indices: y grows with the index along the grid's one long axis


def _checker(x, z):
    """The floor's colour at voxel column (x, z): squares of 4×4 voxels."""
    return np.where(((x // 4 + z // 4) % 2 == 0)[..., None], [0.9, 0.9, 0.9], [0.1, 0.2, 0.6])


@pytest.fixture(scope="module")
def checker_floor():
    """A 32×32 checker floor (top face at y = 1) and two probes over its
    middle: one 2.5 voxels above it, one 26.5 voxels above it."""
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, np.int64), z.ravel()], axis=1)
    octree = build_octree(VoxelScene(coords, _checker(coords[:, 0], coords[:, 2]).astype(
        np.float32), name="checker floor"))
    grid = ProbeGrid([16.5, 3.5, 16.5], [1.0, 24.0, 1.0], [1, 2, 1])
    return bake_grid(octree, grid, 32)


def _straight_down_rays(count: int, seed: int):
    """Vertical rays from between the probes to floor points at least a voxel away from the
    probes' column: there the high probe is the more parallel view, the low one the
    sharper."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, 2.0 * np.pi, count)
    radius = rng.uniform(1.5, 3.5, count)
    origins = np.stack([16.5 + radius * np.cos(angle), np.full(count, 15.0),
                        16.5 + radius * np.sin(angle)], axis=1)
    dirs = np.tile([0.0, -1.0, 0.0], (count, 1))
    return origins, dirs


def test_footprint_reads_the_nearest_view_and_parallel_the_most_aligned(checker_floor):
    origins, dirs = _straight_down_rays(300, seed=3)
    truth = _checker(np.floor(origins[:, 0]), np.floor(origins[:, 2]))
    error = {}
    for rule, expected in (("footprint", LOW), ("parallel", HIGH)):
        field = trace_light_field(checker_floor, origins, dirs,
                                  LightFieldOptions(colour_probe=rule))
        hit = field.kind == HIT
        assert hit.mean() > 0.95
        assert np.all(field.probe[hit] == expected), rule
        assert np.all(np.abs(field.t[hit] - 14.0) < 0.5)  # the floor's top face, 14 below
        error[rule] = np.abs(field.radiance[hit] - truth[hit]).mean()
    # 32² texels 26.5 voxels away are about three voxels wide and blur the squares' edges;
    # a few voxels away they are a fraction of a voxel. (Measured: 0.03 against 0.11.)
    assert error["footprint"] < 0.05
    assert error["footprint"] < 0.5 * error["parallel"]


def test_a_point_is_seen_from_the_front_only():
    toward_ray = (0.0, 1.0, 0.0)  # a floor's normal; the ray runs down
    assert sees_front(10.0, 10.4, 0.5, *toward_ray, 0.0, -1.0, 0.0)
    assert not sees_front(10.0, 10.4, 0.5, *toward_ray, 0.0, 1.0, 0.0)  # its back
    assert not sees_front(10.0, 11.0, 0.5, *toward_ray, 0.0, -1.0, 0.0)  # another surface
    assert not sees_front(10.0, 10.0, 0.5, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0)  # no stored normal
    assert not sees_front(0.0, 0.0, 0.5, *toward_ray, 0.0, -1.0, 0.0)  # the probe's centre


def test_an_unknown_colour_probe_rule_is_refused():
    with pytest.raises(VoxfieldError, match="colour probe"):
        LightFieldOptions(colour_probe="closest")
