"""Terrain columns: exact columns on analytic heightmaps, watertight fill, voids, bad
parameters, crop fit and the thesis scale (``voxfield.scene.terrain.columns``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from terrain_helpers import column_ranges, tree

from voxfield.errors import VoxfieldError
from voxfield.scene.loaders import SceneOptions, load_scene
from voxfield.scene.terrain.columns import terrain_columns
from voxfield.scene.terrain.dem import Heightmap
from voxfield.scene.terrain.layout import terrain_scene
from voxfield.scene.terrain.recipes import recipe_scene

# --------------------------------------------------------------------------------------------
# Analytic heightmaps give exact columns


def test_plane_gives_flat_slab_of_fill_depth_plus_one():
    scene = terrain_scene(Heightmap(np.full((8, 8), 123.0), spacing=(1, 1)), 8, fill_depth=4)
    expected = {(x, y, z) for x in range(8) for z in range(8) for y in range(5)}
    assert len(scene) == 8 * 8 * 5
    assert set(map(tuple, scene.coords.tolist())) == expected


@pytest.mark.parametrize("height", [1e20, -3e250, 1e300])
@pytest.mark.parametrize("spacing", [(1, 1), None])
def test_a_plane_at_any_height_is_flat_after_resampling(height, spacing):
    """Resampled 16 → 64, a constant map at 1e20 m took its cubic weights' round-off
    (1e4 m) for relief and built hills of it."""
    scene = terrain_scene(Heightmap(np.full((16, 16), height), spacing=spacing), 64,
                          fill_depth=4)
    assert len(scene) == 64 * 64 * 5
    assert set(np.unique(scene.coords[:, 1]).tolist()) == set(range(5))


def test_ramp_gives_exact_columns():
    # Height = x // 2 metres at 1 m spacing and true scale: column x's top is x // 2 voxels
    # above column 0's; with fill_depth 4 each column is filled 4 below its top (its lower
    # neighbour's top is at most 1 below), and the lowest voxel sits at y = 0. The relief
    # (7 + 4 voxels) fits the 16³ cube, so no cap applies.
    x = np.arange(16)
    elev = np.tile(x // 2, (16, 1)).astype(float)
    scene = terrain_scene(Heightmap(elev, spacing=(1, 1)), 16, fill_depth=4)
    expected = {(i, y, z) for i in x for z in range(16) for y in range(i // 2, i // 2 + 5)}
    assert set(map(tuple, scene.coords.tolist())) == expected
    assert len(scene) == len(expected)


def test_stair_without_fill_depth_reaches_down_to_lower_neighbour():
    x = np.arange(16)
    tops = 3 * np.minimum(x, 4)  # steps of 3 voxels, then a plateau at 12
    cols = terrain_columns(
        Heightmap(np.tile(tops, (16, 1)).astype(float), spacing=(1, 1)), 16, fill_depth=0
    )
    assert (cols.top == tops).all()
    left = np.r_[tops[0], tops[:-1]]
    right = np.r_[tops[1:], tops[-1]]
    assert (cols.bottom == np.minimum(tops, np.minimum(left, right))).all()


def test_vertical_scale_multiplies_true_scale():
    x = np.arange(16)
    elev = np.tile(x // 4, (16, 1)).astype(float)
    cols = terrain_columns(Heightmap(elev, spacing=(2.0, 2.0)), 16, vertical_scale=4.0)
    # 2 m per voxel horizontally → 0.5 voxel per metre, ×4 → 2 voxels per metre of height.
    assert cols.voxels_per_metre == pytest.approx(2.0)
    assert (cols.top - cols.top[:, :1] == 2 * (x // 4)).all()


def test_max_height_caps_relief_and_scene_stays_in_cube():
    elev = np.tile(np.arange(32, dtype=float), (32, 1)) * 1000.0  # absurdly steep
    hm = Heightmap(elev, spacing=(1, 1))
    cols = terrain_columns(hm, 32, fill_depth=2)
    assert cols.top.max() <= 31
    scene = terrain_scene(hm, 32, fill_depth=2, max_height=20)
    assert scene.bounds[1][1] <= 21


def test_a_relief_scaled_down_to_fit_is_marked():
    steep = Heightmap(np.tile(np.arange(32, dtype=float), (32, 1)) * 1000.0, spacing=(1, 1))
    assert terrain_columns(steep, 32, fill_depth=2).scale_capped
    gentle = Heightmap(np.tile(np.arange(32, dtype=float), (32, 1)) / 2.0, spacing=(1, 1))
    assert not terrain_columns(gentle, 32, fill_depth=2).scale_capped


@pytest.mark.parametrize("scale, capped", [(None, False), (2.0, False), (8.0, True)])
def test_a_vertical_scale_asked_for_but_cut_to_fit_is_a_note(tmp_path, scale, capped):
    """Without spacing the relief spans a quarter of the footprint times the scale: 16 of
    a 32-voxel cube at 2, 64 at 8, cut to fit. Only a scale someone asked for gets a note:
    the default's relief is the DEM's own business."""
    path = tmp_path / "ramp.npy"
    np.save(path, np.tile(np.linspace(0.0, 500.0, 32), (32, 1)))
    options = SceneOptions(terrain_footprint=32, vertical_scale=scale)
    if capped:
        with pytest.warns(UserWarning, match="vertical scale of 8 would raise the relief above "
                                             "the 32³ cube; it was scaled down to fit"):
            scene = load_scene(str(path), options)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            scene = load_scene(str(path), options)
    assert scene.bounds[1][1] <= 32


@pytest.mark.parametrize("scale, flat", [(1e-300, True), (1e-3, True), (0.1, False),
                                         (None, False)])
def test_a_relief_scaled_to_under_a_voxel_is_a_note(tmp_path, scale, flat):
    """Without spacing a 500 m ramp spans 8 voxels of a 32-voxel cube times the scale: under
    half a voxel at 1e-3, and every column rounds to the same top. A vertical scale of 1e-300
    built such a flat slab without a word; 0.1 keeps a voxel of slope."""
    path = tmp_path / "ramp.npy"
    np.save(path, np.tile(np.linspace(0.0, 500.0, 32), (32, 1)))
    cols = terrain_columns(Heightmap(np.load(path)), 32, vertical_scale=scale or 1.0)
    assert cols.flattened == flat and cols.relief_metres == 500.0
    assert (np.ptp(cols.top) == 0) == flat
    options = SceneOptions(terrain_footprint=32, vertical_scale=scale)
    if flat:
        with pytest.warns(UserWarning, match=rf"ramp: its relief of 500 m is less than a voxel "
                                             rf"tall at a vertical scale of {scale:g} "):
            load_scene(str(path), options)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            load_scene(str(path), options)
    # A DEM with no relief is flat by its own making: no note.
    assert not terrain_columns(Heightmap(np.full((32, 32), 7.0)), 32).flattened


def test_a_dem_stretched_out_of_shape_says_so_and_crop_keeps_its_proportions(tmp_path):
    # 24 rows by 48 columns of unknown spacing: square columns stretch it 2× north to south
    path = tmp_path / "wide.npy"
    np.save(path, np.add.outer(np.arange(24.0), np.arange(48.0)))
    with pytest.warns(UserWarning, match=r"48 × 24 samples .* stretched 2.00× north to south"):
        stretched = load_scene(str(path), SceneOptions(terrain_footprint=32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # asked for either way: no note
        cropped = load_scene(str(path), SceneOptions(terrain_footprint=32, dem_fit="crop"))
        again = load_scene(str(path), SceneOptions(terrain_footprint=32, dem_fit="stretch"))
    assert np.array_equal(again.coords, stretched.coords)
    # heights rise one a sample both ways: stretched, they climb twice as fast east as
    # south; the centred 24 × 24 crop climbs alike both ways
    def climb(scene):
        top = np.full((32, 32), -1)
        np.maximum.at(top, (scene.coords[:, 0], scene.coords[:, 2]), scene.coords[:, 1])
        return top[-1, 0] - top[0, 0], top[0, -1] - top[0, 0]  # east, south

    east, south = climb(stretched)
    assert east == pytest.approx(2 * south, abs=1)
    east, south = climb(cropped)
    assert east == pytest.approx(south, abs=1)
    with pytest.raises(VoxfieldError, match="--dem-fit applies to DEM files"):
        load_scene("terrain:mountain", SceneOptions(terrain_footprint=64, dem_fit="crop"))


def test_unknown_spacing_spans_a_quarter_of_the_footprint():
    elev = np.tile(np.linspace(0, 5000, 64), (64, 1))
    cols = terrain_columns(Heightmap(elev), 64, fill_depth=0)
    assert cols.top.max() - cols.top.min() == 16
    assert cols.metres_per_voxel is None


# --------------------------------------------------------------------------------------------
# Watertightness


@pytest.mark.parametrize("fill_depth", [0, 1, 4])
def test_steep_surface_is_watertight(fill_depth):
    rng = np.random.default_rng(3)
    f = 64
    elev = rng.uniform(0, 40, size=(f, f))  # uncorrelated: cliffs of up to 40 voxels, uncapped
    scene = terrain_scene(Heightmap(elev, spacing=(1, 1)), f, fill_depth=fill_depth)
    lo, hi, count = column_ranges(scene, f)
    assert (count == hi - lo + 1).all(), "every column is one contiguous run"
    assert (hi - lo >= fill_depth).all()
    # Each column's run overlaps or touches each 4-neighbour's: no gap to see through.
    for axis in (0, 1):
        a_lo, b_lo = np.moveaxis(lo, axis, 0)[:-1], np.moveaxis(lo, axis, 0)[1:]
        a_hi, b_hi = np.moveaxis(hi, axis, 0)[:-1], np.moveaxis(hi, axis, 0)[1:]
        assert (a_lo <= b_hi + 1).all() and (b_lo <= a_hi + 1).all()
    # And the surface really is steep (the test would be vacuous otherwise).
    assert np.abs(np.diff(hi, axis=1)).max() > 30


# --------------------------------------------------------------------------------------------
# Voids


def test_terrain_from_heightmap_with_voids_has_no_holes():
    elev = np.full((16, 16), 10.0)
    elev[4:9, 4:9] = np.nan
    scene = terrain_scene(Heightmap(elev, spacing=(1, 1)), 16, fill_depth=1)
    lo, hi, count = column_ranges(scene, 16)
    assert (count == 2).all() and (hi == 1).all()


# --------------------------------------------------------------------------------------------
# Errors


@pytest.mark.parametrize("footprint", [1, 0, 16385, 2.5, True])
def test_bad_footprint_is_rejected(footprint):
    with pytest.raises(VoxfieldError, match="footprint"):
        terrain_scene(np.zeros((4, 4)), footprint)


def test_bad_parameters_are_rejected():
    hm = Heightmap(np.zeros((4, 4)))
    with pytest.raises(VoxfieldError, match="fill_depth"):
        terrain_columns(hm, 4, fill_depth=-1)
    with pytest.raises(VoxfieldError, match="vertical_scale"):
        terrain_columns(hm, 4, vertical_scale=0)
    with pytest.raises(VoxfieldError, match="max_height"):
        terrain_columns(hm, 4, max_height=4)
    with pytest.raises(VoxfieldError, match="footprint 4 is too small for this terrain"):
        terrain_scene(hm, 4, assets=[tree(height=6)])
    with pytest.raises(VoxfieldError, match="no room"):  # a cap the caller chose
        terrain_columns(hm, 8, max_height=3, fill_depth=4)
    with pytest.raises(VoxfieldError, match="recipe"):
        recipe_scene("tundra", 64)


# --------------------------------------------------------------------------------------------
# Scale and fit


def test_2048_footprint_reaches_the_thesis_scale():
    """Every column holds at least fill_depth + 1 voxels: ≥ 21M voxels at 2048² (EA: ~20M)."""
    scene = terrain_scene("jacksboro", 2048, fill_depth=4)
    assert 2048 * 2048 * 5 <= len(scene) <= 25_000_000
    assert scene.extent[0] == scene.extent[2] == 2048 and scene.extent[1] < 2048


def test_crop_fit_uses_the_centred_square_window():
    elev = np.tile(np.arange(20, dtype=float), (10, 1))  # 10 rows × 20 columns, 1 m spacing
    cols = terrain_columns(Heightmap(elev, spacing=(1, 1)), 10, fit="crop", fill_depth=0)
    assert np.array_equal(cols.elevation[0], np.arange(5, 15))
    wide = terrain_columns(Heightmap(elev, spacing=(1, 1)), 10, fill_depth=0)
    assert wide.metres_per_voxel == (1.0, 2.0)  # stretched: 2 m of ground per voxel in x


def test_ground_laid_out_in_bands_equals_one_go(monkeypatch, shared_data):
    """``TerrainLayout.scene`` lays the ground out in bands of rows (so Ctrl-C is heard);
    the voxels, their order and colours are those of a single pass."""
    from voxfield.scene.terrain import layout

    monkeypatch.setattr(layout, "GROUND_BAND_ROWS", 10**6)
    whole = recipe_scene("mountain", footprint=48, seed=2)
    monkeypatch.setattr(layout, "GROUND_BAND_ROWS", 5)  # uneven: 48 = 9 × 5 + 3
    banded = recipe_scene("mountain", footprint=48, seed=2)
    np.testing.assert_array_equal(banded.coords, whole.coords)
    np.testing.assert_array_equal(banded.color, whole.color)
    assert len(whole) > 48 * 48


@pytest.mark.parametrize(("fill_depth", "reserve"), [(4, 0), (3, 1), (0, 0)])
def test_a_footprint_too_small_for_the_fill_says_the_smallest_that_fits(fill_depth, reserve):
    """``--footprint 2`` (within its 2.. range) said "leaves 1 voxels of height after 0
    reserved for assets, less than fill_depth 4". The smallest footprint that fits is the
    fill, the voxels kept for assets and the surface voxel: it builds, one less is refused
    by that number."""
    hm = Heightmap(np.arange(64, dtype=float).reshape(8, 8), spacing=(1, 1))
    smallest = fill_depth + reserve + 1
    cols = terrain_columns(hm, max(smallest, 2), fill_depth=fill_depth, reserve=reserve)
    assert cols.footprint == max(smallest, 2)
    if smallest > 2:
        with pytest.raises(VoxfieldError, match=f"^footprint {smallest - 1} is too small for "
                           f"this terrain: it needs at least {smallest} columns a side"):
            terrain_columns(hm, smallest - 1, fill_depth=fill_depth, reserve=reserve)
