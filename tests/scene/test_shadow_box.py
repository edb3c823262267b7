"""The shadow-ray test scene (EA §3.2.2, fig. 3.4): geometry facts checked on the voxels."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.scene.builtin import builtin_scene
from voxfield.scene.shadow_box import (
    BOX_SIZE,
    LIGHT_SIZE,
    shadow_box,
    shadow_box_layout,
)
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def scene():
    return shadow_box(128)


@pytest.fixture(scope="module")
def layout():
    return shadow_box_layout(128)


def _occupancy(scene) -> np.ndarray:
    lo, hi = scene.bounds
    grid = np.zeros(tuple(hi - lo), bool)
    grid[tuple((scene.coords - lo).T)] = True
    return grid


def test_box_is_32_cubed_and_stands_on_the_floor(scene, layout):
    box = scene.coords[:, 1] >= layout.floor_top
    lo, hi = scene.coords[box].min(axis=0), scene.coords[box].max(axis=0) + 1
    assert (hi - lo).tolist() == [BOX_SIZE] * 3
    assert lo.tolist() == list(layout.box_min)
    floor = scene.coords[~box]
    assert floor[:, 1].max() + 1 == layout.floor_top
    assert len(floor) == 128 * 128 * layout.floor_top  # a full slab, wider than the box


def test_grid_gaps_are_single_voxels_between_one_voxel_bars(scene, layout):
    occupied = _occupancy(scene)
    x0, y0, _ = layout.box_min
    front = occupied[x0:x0 + BOX_SIZE, y0:y0 + BOX_SIZE, layout.grid_z]
    gaps = np.argwhere(~front)
    assert len(gaps) == 15 * 15
    # Every gap is surrounded by bars on all four sides and the diagonals: width 1.
    for gx, gy in gaps:
        around = front[gx - 1:gx + 2, gy - 1:gy + 2].copy()
        around[1, 1] = True
        assert around.all()
    # Bars between gaps are one voxel wide: gaps sit two voxels apart.
    assert set(np.unique(np.diff(np.unique(gaps[:, 0])))) == {2}
    # The grid is the only opening: the other walls are closed.
    inner = occupied[x0:x0 + BOX_SIZE, y0:y0 + BOX_SIZE, layout.box_min[2]:layout.grid_z]
    assert inner[0].all() and inner[-1].all() and inner[:, 0].all() and inner[:, -1].all()
    assert inner[:, :, 0].all()


def test_grid_closes_one_lod_coarser(scene):
    """Fig. 3.4b: at LOD 1 every 2×2 cell of the grid holds a bar, so the grid is a plane."""
    layout = shadow_box_layout(128)
    octree = build_octree(scene)
    cells = octree.lod_voxels(1)
    x0, y0, _ = layout.box_min
    front = cells[cells[:, 2] == layout.grid_z - 1]  # LOD-1 cells are aligned to even z
    inside = front[(front[:, 0] >= x0) & (front[:, 0] < x0 + BOX_SIZE)
                   & (front[:, 1] >= y0) & (front[:, 1] < y0 + BOX_SIZE)]
    assert len(inside) == (BOX_SIZE // 2) ** 2


def test_emitter_is_at_the_back_facing_the_grid(scene, layout):
    lit = scene.emission.max(axis=1) > 0
    assert lit.sum() == LIGHT_SIZE**2
    light = scene.coords[lit]
    assert (light[:, 2] == layout.light_min[2]).all()
    assert light[:, 2].min() < layout.box_min[2] + 2  # in the back wall
    occupied = _occupancy(scene)
    # Only the face towards the grid is open: behind the light is the back wall's outer layer.
    assert not occupied[tuple((light + [0, 0, 1]).T)].any()
    assert occupied[tuple((light - [0, 0, 1]).T)].all()


def test_registered_as_builtin():
    scene = builtin_scene("shadowbox")
    assert scene.name == "shadowbox"
    assert scene.emission is not None


@pytest.mark.parametrize("size", [32, 100, 0])
def test_bad_floor_size(size):
    with pytest.raises(VoxfieldError, match="floor size"):
        shadow_box(size)
