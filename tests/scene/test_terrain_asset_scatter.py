"""Seeded asset scattering: Poisson-disk sites, placement rules, models on the ground,
headroom and model downsampling (``voxfield.scene.terrain.asset_scatter``)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from terrain_helpers import LEAF, TRUNK, column_ranges, hills, tree

from voxfield.scene.terrain.asset_scatter import (
    AssetGroup,
    downsample_scene,
    place_assets,
    poisson_disk,
)
from voxfield.scene.terrain.columns import terrain_columns
from voxfield.scene.terrain.dem import Heightmap, load_heightmap
from voxfield.scene.terrain.layout import terrain_scene
from voxfield.scene.voxel_scene import VoxelScene

# --------------------------------------------------------------------------------------------
# Asset scattering


def test_poisson_disk_respects_spacing_and_is_seeded():
    pts = poisson_disk(200, 10.0, np.random.default_rng(1))
    again = poisson_disk(200, 10.0, np.random.default_rng(1))
    assert np.array_equal(pts, again)
    assert ((pts >= 0) & (pts < 200)).all()
    d = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 10.0
    # Nearly packed: a maximal disk packing holds roughly 0.5–0.7 / r² points per unit area.
    assert len(pts) > 0.45 * 200**2 / 100


def test_scattered_trees_stand_one_voxel_above_the_surface():
    hm = hills(96, seed=4, amplitude=12.0)
    f = 96
    assets = [tree(6, 1), tree(9, 2)]
    kwargs = dict(fill_depth=2, assets=assets, asset_density=0.8, seed=7)
    scene = terrain_scene(hm, f, **kwargs)
    assert np.array_equal(scene.coords, terrain_scene(hm, f, **kwargs).coords)
    assert not np.array_equal(scene.coords, terrain_scene(hm, f, **{**kwargs, "seed": 8}).coords)
    assert len(scene.dedupe()) == len(scene)

    trunk = np.all(np.isclose(scene.color, TRUNK), axis=1)
    leaf = np.all(np.isclose(scene.color, LEAF), axis=1)
    ground = ~trunk & ~leaf
    assert trunk.sum() > 0
    g_lo, g_hi, _ = column_ranges(scene.subset(ground), f)
    positions = {tuple(c) for c in scene.coords[trunk].tolist()}
    bases = [c for c in positions if (c[0], c[1] - 1, c[2]) not in positions]
    assert len(bases) >= 10
    for x, y, z in bases:
        assert y == g_hi[z, x] + 1
    # No tree voxel is buried in the ground.
    t = scene.coords[~ground]
    assert (t[:, 1] > g_hi[t[:, 2], t[:, 0]]).all()


def test_placements_follow_the_rules():
    hm = hills(128, seed=5, amplitude=40.0)
    cols = terrain_columns(hm, 128, fill_depth=1, sea_level=8.0, reserve=12)
    group = AssetGroup([tree(6, 1)], density=1.0, spacing=6.0, max_slope=0.5, rotate=True)
    placed = place_assets(cols, group, np.random.default_rng(0))
    assert len(placed) > 20
    assert (cols.slope[placed.z, placed.x] <= 0.5).all()
    assert not cols.water[placed.z, placed.x].any()
    assert (placed.y == cols.top[placed.z, placed.x] + 1).all()
    assert len(np.unique(placed.turns)) > 1
    d = np.hypot(placed.x[:, None] - placed.x, placed.z[:, None] - placed.z)
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 6.0 - math.sqrt(2)  # sites ≥ 6 apart, floored to their columns
    sparse = place_assets(cols, replace_density(group, 0.2), np.random.default_rng(0))
    assert len(sparse) < len(placed)


def replace_density(group: AssetGroup, density: float) -> AssetGroup:
    return replace(group, density=density)


def test_terrain_leaves_headroom_for_assets():
    elev = np.tile(np.arange(32, dtype=float), (32, 1)) * 100.0
    scene = terrain_scene(
        Heightmap(elev, spacing=(1, 1)), 32, fill_depth=1, assets=[tree(6, 1)], asset_density=1
    )
    assert scene.bounds[1][1] <= 32


def test_downsample_scene_averages_blocks():
    coords = np.array(
        [[x, y, z] for x in range(2) for y in range(2) for z in range(2)] + [[5, 0, 0]]
    )
    color = np.zeros((9, 3))
    color[:8, 0] = np.linspace(0, 1, 8)
    color[8] = (0, 1, 0)
    small = downsample_scene(VoxelScene(coords, color), 2)
    assert len(small) == 2
    i = int(np.flatnonzero((small.coords == [0, 0, 0]).all(axis=1))[0])
    assert small.color[i, 0] == pytest.approx(0.5)
    assert small.coords.tolist()[1 - i] == [2, 0, 0]


def test_scatters_real_vox_models(shared_data):
    vox = pytest.importorskip("voxfield.scene.vox")
    pine = downsample_scene(vox.load_vox(shared_data / "vox" / "PineFluffy.vox"), 8).normalized()
    rock = downsample_scene(vox.load_vox(shared_data / "vox" / "nature.vox"), 10).normalized()
    hm = load_heightmap("jacksboro")
    kwargs = dict(fill_depth=1, assets=[pine, rock], asset_density=0.5, seed=3)
    scene = terrain_scene(hm, 256, **kwargs)
    again = terrain_scene(hm, 256, **kwargs)
    assert np.array_equal(scene.coords, again.coords) and np.array_equal(scene.color, again.color)
    plain = terrain_scene(hm, 256, fill_depth=1, max_height=255 - pine.extent[1])
    assert len(scene) > len(plain) + 10 * len(pine) // 2
    pine_colours = {tuple(c) for c in np.round(pine.color, 5).tolist()}
    extra = {tuple(c) for c in np.round(scene.color[len(plain) :], 5).tolist()}
    assert pine_colours & extra
    assert scene.bounds[1].max() <= 256
