"""Tests for DEM terrain: exact columns on analytic heightmaps, watertightness, void filling,
the readers against the facts in data/README.md, colours, seeded asset scattering, recipes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import tifffile

from voxfield.errors import DataNotFoundError, SceneFormatError, SceneTooLargeError, VoxfieldError
from voxfield.scene.terrain import (
    RECIPES,
    AssetGroup,
    ColorRamp,
    Heightmap,
    downsample_scene,
    fill_voids,
    load_heightmap,
    place_assets,
    poisson_disk,
    recipe_scene,
    resample,
    terrain_columns,
    terrain_scene,
)
from voxfield.scene.voxel_scene import VoxelScene

TRUNK = (0.30, 0.15, 0.05)
LEAF = (0.05, 0.50, 0.10)


def column_ranges(scene: VoxelScene, f: int):
    """Per-column (min y, max y, count) of a scene's voxels, from the coords alone."""
    c = scene.coords
    key = c[:, 2] * f + c[:, 0]
    lo = np.full(f * f, np.iinfo(np.int64).max)
    hi = np.full(f * f, np.iinfo(np.int64).min)
    np.minimum.at(lo, key, c[:, 1])
    np.maximum.at(hi, key, c[:, 1])
    count = np.bincount(key, minlength=f * f)
    return lo.reshape(f, f), hi.reshape(f, f), count.reshape(f, f)


def tree(height: int = 6, crown: int = 1) -> VoxelScene:
    """A procedural tree: a 1×1 trunk and a (2·crown+1)² square crown on top."""
    trunk = [(0, y, 0) for y in range(height)]
    leaves = [
        (x, y, z)
        for y in range(height, height + 2)
        for x in range(-crown, crown + 1)
        for z in range(-crown, crown + 1)
    ]
    coords = np.array(trunk + leaves) + [crown, 0, crown]
    color = np.array([TRUNK] * len(trunk) + [LEAF] * len(leaves))
    return VoxelScene(coords, color, name="tree")


def hills(f: int = 64, seed: int = 0, amplitude: float = 6.0) -> Heightmap:
    """Smooth random hills in metres with 1 m spacing (true scale: 1 m = 1 voxel)."""
    rng = np.random.default_rng(seed)
    from scipy import ndimage

    z = ndimage.gaussian_filter(rng.standard_normal((f, f)), 6, mode="wrap")
    z = amplitude * (z - z.min()) / (z.max() - z.min())
    return Heightmap(z, spacing=(1.0, 1.0), name="hills")


# --------------------------------------------------------------------------------------------
# Analytic heightmaps give exact columns


def test_plane_gives_flat_slab_of_fill_depth_plus_one():
    scene = terrain_scene(Heightmap(np.full((8, 8), 123.0), spacing=(1, 1)), 8, fill_depth=4)
    expected = {(x, y, z) for x in range(8) for z in range(8) for y in range(5)}
    assert len(scene) == 8 * 8 * 5
    assert set(map(tuple, scene.coords.tolist())) == expected


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


def test_fill_voids_stays_within_the_rim_and_is_smooth():
    hm = hills(48, seed=1, amplitude=100.0)
    elev = hm.elevation.copy()
    yy, xx = np.mgrid[:48, :48]
    hole = (yy - 20) ** 2 + (xx - 25) ** 2 < 8**2
    elev[hole] = np.nan
    filled = fill_voids(elev)
    assert not np.isnan(filled).any()
    assert np.array_equal(filled[~hole], elev[~hole])
    from scipy import ndimage

    rim = ndimage.binary_dilation(hole, np.ones((3, 3), bool)) & ~hole
    assert elev[rim].min() - 1e-9 <= filled[hole].min()
    assert filled[hole].max() <= elev[rim].max() + 1e-9
    # Smoothing leaves no nearest-fill terraces: more distinct values than rim samples.
    assert len(np.unique(np.round(filled[hole], 6))) > rim.sum()


def test_terrain_from_heightmap_with_voids_has_no_holes():
    elev = np.full((16, 16), 10.0)
    elev[4:9, 4:9] = np.nan
    scene = terrain_scene(Heightmap(elev, spacing=(1, 1)), 16, fill_depth=1)
    lo, hi, count = column_ranges(scene, 16)
    assert (count == 2).all() and (hi == 1).all()


# --------------------------------------------------------------------------------------------
# Resampling


def test_resample_keeps_constants_and_ramps():
    assert np.allclose(resample(np.full((5, 7), 3.5), (40, 33)), 3.5)
    ramp = np.tile(np.arange(20, dtype=float), (20, 1))
    up = resample(ramp, (20, 80))
    # Output column j samples input position (j + 0.5) / 4 - 0.5; cubic is exact on ramps
    # away from the clamped borders.
    pos = (np.arange(80) + 0.5) / 4 - 0.5
    inner = (pos > 2) & (pos < 17)
    assert np.allclose(up[:, inner], pos[inner])


def test_resample_shrinking_is_antialiased():
    checker = (np.indices((64, 64)).sum(axis=0) % 2).astype(float)
    small = resample(checker, (8, 8))
    assert np.allclose(small, 0.5, atol=0.02)


# --------------------------------------------------------------------------------------------
# Errors


@pytest.mark.parametrize("footprint", [1, 0, 16385, 2.5, True])
def test_bad_footprint_is_rejected(footprint):
    with pytest.raises(VoxfieldError, match="footprint"):
        terrain_scene(np.zeros((4, 4)), footprint)


@pytest.mark.parametrize("array", [np.zeros(5), np.zeros((3, 3, 3)), np.zeros((1, 9))])
def test_bad_arrays_are_rejected(array):
    with pytest.raises(SceneFormatError):
        Heightmap(array)


def test_all_void_dem_is_rejected():
    with pytest.raises(SceneFormatError, match="void"):
        Heightmap(np.full((4, 4), np.nan))


def test_bad_parameters_are_rejected():
    hm = Heightmap(np.zeros((4, 4)))
    with pytest.raises(VoxfieldError, match="fill_depth"):
        terrain_columns(hm, 4, fill_depth=-1)
    with pytest.raises(VoxfieldError, match="vertical_scale"):
        terrain_columns(hm, 4, vertical_scale=0)
    with pytest.raises(VoxfieldError, match="max_height"):
        terrain_columns(hm, 4, max_height=4)
    with pytest.raises(VoxfieldError, match="no room"):
        terrain_scene(hm, 4, assets=[tree(height=6)])
    with pytest.raises(VoxfieldError, match="recipe"):
        recipe_scene("tundra", 64)


def test_file_errors(tmp_path):
    with pytest.raises(DataNotFoundError):
        load_heightmap(tmp_path / "missing.hgt")
    bad = tmp_path / "N40W074.hgt"
    bad.write_bytes(b"\0" * 1000)
    with pytest.raises(SceneFormatError, match="1,000 bytes"):
        load_heightmap(bad)
    other = tmp_path / "dem.xyz"
    other.write_text("1 2 3")
    with pytest.raises(SceneFormatError, match="unknown DEM format"):
        load_heightmap(other)
    two = tmp_path / "two.npz"
    np.savez(two, a=np.zeros((3, 3)), b=np.ones((3, 3)))
    with pytest.raises(SceneFormatError, match="exactly one 2-D array"):
        load_heightmap(two)
    rgb = tmp_path / "rgb.tif"
    tifffile.imwrite(rgb, np.zeros((4, 4, 3), np.uint8), photometric="rgb")
    with pytest.raises(SceneFormatError, match="one band"):
        load_heightmap(rgb)
    garbage = tmp_path / "garbage.tif"
    garbage.write_bytes(b"not a tiff at all")
    with pytest.raises(SceneFormatError):
        load_heightmap(garbage)


# --------------------------------------------------------------------------------------------
# Readers on hand-made files


def test_hgt_reader_on_a_written_tile(tmp_path):
    raw = (np.arange(1201 * 1201) % 500 - 100).astype(">i2").reshape(1201, 1201)
    raw[10, 20] = -32768
    path = tmp_path / "S12E034.hgt"
    raw.tofile(path)
    hm = load_heightmap(path)
    assert hm.shape == (1201, 1201) and hm.voids == 1 and np.isnan(hm.elevation[10, 20])
    assert hm.elevation[0, 1] == raw[0, 1]
    # South-west corner −12°, 34°: the first row is the northern edge at −11°.
    assert hm.geo.y0 == -11 and hm.geo.x0 == 34 and hm.geo.dx == pytest.approx(1 / 1200)
    assert hm.spacing[0] == pytest.approx(92.66, abs=0.01)  # 3″ of latitude


def test_geotiff_reader_nodata_and_position(tmp_path):
    data = np.arange(20, dtype=np.int16).reshape(4, 5)
    data[1, 1] = -500
    data[2, 2] = -32768
    path = tmp_path / "dem.tif"
    tifffile.imwrite(
        path,
        data,
        extratags=[
            (33550, 12, 3, (0.5, 0.25, 0.0)),
            (33922, 12, 6, (0, 0, 0, 10.0, 50.0, 0)),
            (42113, 2, 0, "-500"),
        ],
    )
    hm = load_heightmap(path)
    assert hm.voids == 2 and np.isnan(hm.elevation[1, 1]) and np.isnan(hm.elevation[2, 2])
    assert hm.elevation[3, 4] == 19
    # Pixel-is-area tie point at the corner: the first sample centre is half a pixel inside.
    assert (hm.geo.x0, hm.geo.y0) == pytest.approx((10.25, 49.875))


def test_npz_reader_with_spacing(tmp_path):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=np.arange(12.0).reshape(3, 4), spacing=30.0)
    hm = load_heightmap(path)
    assert hm.shape == (3, 4) and hm.spacing == (30.0, 30.0)


# --------------------------------------------------------------------------------------------
# Readers on the real DEMs (facts from data/README.md)


def test_srtm_tile_facts(shared_data):
    hm = load_heightmap(shared_data / "terrain" / "N40W074.hgt")
    assert hm.shape == (1201, 1201)
    assert hm.voids == 1051
    assert np.nanmin(hm.elevation) == -42 and np.nanmax(hm.elevation) == 179
    # 72% sea (SRTM stores the sea as 0 m).
    assert np.mean(hm.elevation == 0) == pytest.approx(0.72, abs=0.02)


def test_srtm30_geotiff_facts(shared_data):
    hm = load_heightmap(shared_data / "terrain" / "dem_srtm30.tif")
    assert hm.shape == (300, 300)
    assert hm.geo.dx == pytest.approx(30 / 3600)
    assert hm.spacing[0] == pytest.approx(926.6, abs=0.5)  # 30″ of latitude


def test_jacksboro_sample_facts_and_orientation():
    from matplotlib import cbook

    hm = load_heightmap("jacksboro")
    assert hm.shape == (344, 403)
    assert np.nanmin(hm.elevation) == 236 and np.nanmax(hm.elevation) == 1076
    # Rows already run north to south (matplotlib plots it with origin="upper"): unchanged.
    raw = cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"]
    assert np.array_equal(hm.elevation, raw)
    assert hm.geo.y0 == pytest.approx(36.7329 - 0.0004, abs=1e-3)
    assert hm.spacing[0] == pytest.approx(92.7, abs=0.5)  # ~90 m, 3″


def test_topobathy_sample_is_flipped_north_up():
    from matplotlib import cbook

    hm = load_heightmap("topobathy")
    raw = cbook.get_sample_data("topobathy.npz")
    assert hm.shape == (91, 120)
    assert np.nanmin(hm.elevation) == -1437 and np.nanmax(hm.elevation) == 2205
    assert raw["latitude"][0] < raw["latitude"][-1]  # stored south first...
    assert np.array_equal(hm.elevation[0], raw["topo"][-1])  # ...so row 0 is the last row
    assert hm.geo.y0 == pytest.approx(float(raw["latitude"].max()))


# --------------------------------------------------------------------------------------------
# Colours


def test_ramp_colours_are_deterministic_in_range_and_banded():
    hm = hills(64, seed=2, amplitude=30.0)
    ramp = ColorRamp(jitter=0.0, noise=0.0, snow_line=0.7, rock_slope=100.0, snow_max_slope=100.0)
    a = terrain_scene(hm, 64, ramp=ramp, seed=5, fill_depth=1)
    b = terrain_scene(hm, 64, ramp=ramp, seed=5, fill_depth=1)
    assert np.array_equal(a.color, b.color) and np.array_equal(a.coords, b.coords)
    assert a.color.min() >= 0 and a.color.max() <= 1
    lo, hi, _ = column_ranges(a, 64)
    top_voxel = {tuple(c): i for i, c in enumerate(a.coords.tolist())}
    peak = np.unravel_index(np.argmax(hi), hi.shape)
    snow = np.asarray(ColorRamp().snow) ** 2.2
    idx = top_voxel[(peak[1], int(hi[peak]), peak[0])]
    assert np.allclose(a.color[idx], snow, atol=0.03)
    # Voxels under the top are darker.
    under = top_voxel[(peak[1], int(hi[peak]) - 1, peak[0])]
    assert a.color[under].sum() < a.color[idx].sum()


def test_sea_level_makes_flat_water():
    elev = np.tile(np.linspace(-50, 50, 32), (32, 1))
    scene = terrain_scene(Heightmap(elev, spacing=(1, 1)), 32, sea_level=0.0, fill_depth=1)
    _, hi, _ = column_ranges(scene, 32)
    cols = terrain_columns(Heightmap(elev, spacing=(1, 1)), 32, sea_level=0.0, fill_depth=1)
    assert cols.water[:, :15].all() and not cols.water[:, 17:].any()
    assert len(np.unique(hi[:, :15])) == 1  # one sea surface
    top_colors = {tuple(c): col for c, col in zip(scene.coords.tolist(), scene.color, strict=True)}
    water = top_colors[(2, int(hi[0, 2]), 0)]
    assert water[2] > water[0]  # blue, not sand


def test_colours_from_a_stretched_image(tmp_path):
    img = np.zeros((10, 20, 3), np.uint8)
    img[:, :10] = (255, 0, 0)
    img[:, 10:] = (0, 0, 255)
    path = tmp_path / "colors.png"
    from PIL import Image

    Image.fromarray(img).save(path)
    scene = terrain_scene(
        Heightmap(np.zeros((8, 8)), spacing=(1, 1)), 16, colors=path, fill_depth=0
    )
    by_x = {x: scene.color[scene.coords[:, 0] == x] for x in (0, 15)}
    assert np.allclose(by_x[0], (1, 0, 0), atol=1e-6)
    assert np.allclose(by_x[15], (0, 0, 1), atol=1e-6)


def test_colours_from_shaded_relief_are_placed_by_position(shared_data):
    f = 128
    dem = shared_data / "terrain" / "dem_srtm30.tif"
    image = shared_data / "terrain" / "shadedrelief_srtm3.tif"
    hm = load_heightmap(dem)
    scene = terrain_scene(hm, f, colors=image, fill_depth=0, ramp=ColorRamp(noise=0, jitter=0))
    assert scene.color.min() >= 0 and scene.color.max() <= 1
    cols = terrain_columns(hm, f, fill_depth=0)
    top = {}
    order = np.lexsort((scene.coords[:, 1], scene.coords[:, 2] * f + scene.coords[:, 0]))
    for i in order:  # last (highest) voxel per column wins
        top[(int(scene.coords[i, 2]), int(scene.coords[i, 0]))] = scene.color[i]
    grid = np.array([[top[(z, x)] for x in range(f)] for z in range(f)])
    # The image covers latitudes 34.47–36.44°; the DEM reaches 36.96°: its northern strip
    # (about the first fifth of the rows) is outside the image and falls back to the ramp.
    south = np.zeros((f, f), bool)
    south[int(0.3 * f) :] = True
    sea = south & (cols.elevation <= 0)
    land = south & (cols.elevation > 1000)
    assert sea.sum() > 50 and land.sum() > 50
    sea_rgb, land_rgb = grid[sea].mean(axis=0), grid[land].mean(axis=0)
    assert sea_rgb[2] > sea_rgb[0] + 0.2  # the image's sea is cyan
    assert land_rgb[0] > land_rgb[2]  # its land is tan, green, white: never blue-dominant
    assert np.abs(sea_rgb - land_rgb).sum() > 0.3


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
    from dataclasses import replace

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


# --------------------------------------------------------------------------------------------
# Recipes and scale


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_recipes_build_small(name, shared_data):
    scene = recipe_scene(name, footprint=128, data_root=shared_data)
    lo, hi = scene.bounds
    assert lo.min() >= 0 and hi.max() <= 128
    assert len(scene) >= 128 * 128 * 2
    assert RECIPES[name].description


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


def test_voxel_budget_guard():
    with pytest.raises(SceneTooLargeError, match="max_voxels"):
        terrain_scene(np.zeros((8, 8)), 64, max_voxels=1000)
