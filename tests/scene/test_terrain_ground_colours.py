"""Surface colours: the seeded ramp, water, images stretched or placed by position
(``voxfield.scene.terrain.ground_colours``)."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from PIL import Image
from terrain_helpers import column_ranges, hills

from voxfield.errors import SceneFormatError
from voxfield.scene.terrain.columns import terrain_columns
from voxfield.scene.terrain.dem import Heightmap, load_heightmap
from voxfield.scene.terrain.ground_colours import ColorRamp
from voxfield.scene.terrain.layout import terrain_scene

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
    Image.fromarray(img).save(path)
    scene = terrain_scene(
        Heightmap(np.zeros((8, 8)), spacing=(1, 1)), 16, colors=path, fill_depth=0
    )
    by_x = {x: scene.color[scene.coords[:, 0] == x] for x in (0, 15)}
    assert np.allclose(by_x[0], (1, 0, 0), atol=1e-6)
    assert np.allclose(by_x[15], (0, 0, 1), atol=1e-6)


def test_a_colour_tiff_cut_after_its_header_is_refused_in_plain_words(tmp_path):
    """Its IndexError escaped the reader (only tifffile's own errors were caught)."""
    tifffile.imwrite(tmp_path / "whole.tif", np.zeros((8, 8, 3), np.uint8), photometric="rgb")
    (tmp_path / "cut.tif").write_bytes((tmp_path / "whole.tif").read_bytes()[:8])
    with pytest.raises(SceneFormatError, match="cut.tif: a TIFF that holds no image"):
        terrain_scene(Heightmap(np.zeros((8, 8)), spacing=(1, 1)), 16,
                      colors=tmp_path / "cut.tif")


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
