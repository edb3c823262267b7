"""The assembled terrain (``voxfield.scene.terrain.layout``): the voxel budget guard and
the voxels of column blocks against a per-column loop."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import SceneTooLargeError
from voxfield.scene.terrain.layout import terrain_layout, terrain_scene


def test_voxel_budget_guard():
    with pytest.raises(SceneTooLargeError, match="max_voxels"):
        terrain_scene(np.zeros((8, 8)), 64, max_voxels=1000)


def test_column_blocks_hold_each_columns_voxels_with_the_surface_colour_on_top():
    rng = np.random.default_rng(3)
    layout = terrain_layout(rng.random((12, 12)) * 9.0, 40, fill_depth=3)
    cols = layout.cols
    fill = layout._fill(layout.surface)
    coords, attributes = layout.column_block(8, 16, 16)
    got = {tuple(c): tuple(rgb) for c, rgb in zip(coords, attributes["color"], strict=True)}
    expected = {}
    for z in range(16, 32):
        for x in range(8, 24):
            for y in range(int(cols.bottom[z, x]), int(cols.top[z, x]) + 1):
                top = y == cols.top[z, x]
                expected[(x, y, z)] = tuple((layout.surface if top else fill)[z, x])
    assert len(coords) == len(expected) and got == expected
    # The whole scene is the blocks' voxels, in row-major column order.
    scene = layout.scene()
    inside = ((scene.coords[:, 0] >= 8) & (scene.coords[:, 0] < 24)
              & (scene.coords[:, 2] >= 16) & (scene.coords[:, 2] < 32))
    order = np.lexsort((scene.coords[inside, 1], scene.coords[inside, 0],
                        scene.coords[inside, 2]))
    assert np.array_equal(scene.coords[inside][order], coords)
