"""The named terrain recipes build (``voxfield.scene.terrain.recipes``)."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.metrics import psnr
from voxfield.render.camera import preset_camera
from voxfield.render.primary import render_lod, render_reference
from voxfield.scene.terrain.recipes import RECIPES, recipe_layout, recipe_scene
from voxfield.svo.streamed_build import build_octree_streamed

# --------------------------------------------------------------------------------------------
# Recipes and scale


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_recipes_build_small(name, shared_data):
    scene = recipe_scene(name, footprint=128, data_root=shared_data)
    lo, hi = scene.bounds
    assert lo.min() >= 0 and hi.max() <= 128
    assert len(scene) >= 128 * 128 * 2
    assert RECIPES[name].description


# --------------------------------------------------------------------------------------------
# The EA thesis's colour regime


SMOOTH = ("desert-smooth", "forest-smooth", "mountain-smooth", "biomes-smooth")


def _column_step(layout) -> float:
    """Mean colour change between neighbouring columns' surfaces."""
    s = layout.surface
    return float((np.abs(np.diff(s, axis=0)).mean() + np.abs(np.diff(s, axis=1)).mean()) / 2)


@pytest.mark.parametrize("name", SMOOTH)
def test_thesis_regime_recipes_hold_its_voxels_per_column_and_smooth_colour(name, shared_data):
    smooth = recipe_layout(name, footprint=256, data_root=shared_data)
    hard = recipe_layout(name.removesuffix("-smooth"), footprint=256, data_root=shared_data)
    assert 3.5 <= smooth.voxel_count / 256**2 <= 6.7  # EA Table 4.1's range
    assert _column_step(smooth) < 0.5 * _column_step(hard)
    # Buried voxels carry their column's surface colour.
    scene = recipe_layout(name, footprint=64, data_root=shared_data, assets=None).scene()
    tops = {}
    for (x, y, z), c in zip(scene.coords.tolist(), scene.color, strict=True):
        if (x, z) not in tops or y > tops[(x, z)][0]:
            tops[(x, z)] = (y, c)
    expected = np.array([tops[(x, z)][1] for x, _, z in scene.coords.tolist()])
    np.testing.assert_array_equal(scene.color, expected)


def test_thesis_regime_coarse_renders_are_closer_to_the_reference(shared_data):
    """The published trend: smooth colour makes the cheap LOD renders far more faithful."""
    scores = {}
    for name in ("mountain", "mountain-smooth"):
        octree = build_octree_streamed(recipe_layout(name, footprint=128, data_root=shared_data))
        lo, hi = octree.voxel_bounds
        camera = preset_camera("top", lo, hi, size=64)
        reference = render_reference(octree, camera, side=4)
        scores[name] = psnr(reference.image, render_lod(octree, camera, lod=1).image)
    assert scores["mountain-smooth"] > scores["mountain"] + 3.0


def test_a_missing_data_folder_is_named_with_the_variable_that_moves_it(tmp_path, monkeypatch,
                                                                        capsys):
    """The message told command-line users to "pass data_root", a Python parameter."""
    from voxfield.cli import main

    monkeypatch.setenv("VOXFIELD_DATA", str(tmp_path / "nowhere"))
    assert main(["info", "terrain:desert", "--footprint", "16"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"voxfield: error: {tmp_path / 'nowhere'}")
    assert "point VOXFIELD_DATA at it" in err and "data_root" not in err
