"""The named terrain recipes build (``voxfield.scene.terrain.recipes``)."""

from __future__ import annotations

import pytest

from voxfield.scene.terrain.recipes import RECIPES, recipe_scene

# --------------------------------------------------------------------------------------------
# Recipes and scale


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_recipes_build_small(name, shared_data):
    scene = recipe_scene(name, footprint=128, data_root=shared_data)
    lo, hi = scene.bounds
    assert lo.min() >= 0 and hi.max() <= 128
    assert len(scene) >= 128 * 128 * 2
    assert RECIPES[name].description
