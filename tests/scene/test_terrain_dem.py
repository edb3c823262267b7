"""Heightmaps and DEM readers: bad arrays, file errors, the readers on hand-made files and
on the real DEMs against the facts in data/README.md (``voxfield.scene.terrain.dem``)."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from matplotlib import cbook

from voxfield.errors import DataNotFoundError, SceneFormatError
from voxfield.scene.terrain.columns import terrain_columns
from voxfield.scene.terrain.dem import Heightmap, load_heightmap


@pytest.mark.parametrize("array", [np.zeros(5), np.zeros((3, 3, 3)), np.zeros((1, 9))])
def test_bad_arrays_are_rejected(array):
    with pytest.raises(SceneFormatError):
        Heightmap(array)


def test_all_void_dem_is_rejected():
    with pytest.raises(SceneFormatError, match="void"):
        Heightmap(np.full((4, 4), np.nan))


def test_file_errors(tmp_path):
    with pytest.raises(DataNotFoundError):
        load_heightmap(tmp_path / "missing.hgt")
    for empty in ("", "  "):  # ``dem:`` with no name once read as the current folder
        with pytest.raises(DataNotFoundError, match="no DEM named"):
            load_heightmap(empty)
    with pytest.raises(SceneFormatError, match="a folder, not a DEM file"):
        load_heightmap(tmp_path)
    for name, data, words in (("garbage.npy", b"x", "damaged, or another kind of file"),
                              ("empty.npy", b"", "the file is empty")):
        (tmp_path / name).write_bytes(data)  # NumPy itself would blame pickled data
        with pytest.raises(SceneFormatError, match=f"not a readable .npy array .*{words}"):
            load_heightmap(tmp_path / name)
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


def _tiff_bytes(tmp_path) -> bytes:
    tifffile.imwrite(tmp_path / "whole.tif", (np.arange(4096) % 97).reshape(64, 64)
                     .astype(np.int16))
    return (tmp_path / "whole.tif").read_bytes()


def test_a_damaged_tiff_is_refused_in_plain_words(tmp_path):
    """tifffile's own words named its internals ("IndexError: index 0 out of range(0)" for
    a file cut after its header)."""
    data = _tiff_bytes(tmp_path)
    with tifffile.TiffFile(tmp_path / "whole.tif") as tif:
        compression = tif.pages[0].tags["Compression"].valueoffset
    unknown = bytearray(data)
    unknown[compression:compression + 2] = (40000).to_bytes(2, "little")  # no such code
    cases = {
        "header.tif": (data[:8], "holds no image \\(damaged or cut short\\)$"),
        "cut.tif": (data[:len(data) // 2], "cannot be read: the file is damaged or cut short$"),
        "words.tif": (b"hello, not a tiff", "not a TIFF file \\(it does not begin with a TIFF"),
        "unknown.tif": (bytes(unknown), "compression code 40000 is none this reader knows$"),
    }
    for name, (content, words) in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(SceneFormatError, match=f"{name}: .*{words}") as caught:
            load_heightmap(tmp_path / name)
        assert "Error" not in str(caught.value)


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
    # NASA's download names the tile first and its product after: same position
    for name in ("S12E034.SRTMGL3.hgt", "s12e034_v2.hgt"):
        path = path.rename(tmp_path / name)
        assert load_heightmap(path).geo == hm.geo
    path = path.rename(tmp_path / "S12E0345.hgt")
    assert load_heightmap(path).geo is None
    # A position off the globe was refused for its ground spacing, far from why.
    for name in ("N99W999.hgt", "N90E000.hgt", "S12E180.hgt"):
        path = path.rename(tmp_path / name)
        with pytest.raises(SceneFormatError, match=rf"the name places the tile's south-west "
                                                   rf"corner at {name[:-4]}, outside the globe"):
            load_heightmap(path)
    assert load_heightmap(path.rename(tmp_path / "S90W180.hgt")).geo.y0 == -89


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
    with pytest.warns(UserWarning, match="2 of its 20 samples"):  # tiny: 10% voids
        hm = load_heightmap(path)
    assert hm.voids == 2 and np.isnan(hm.elevation[1, 1]) and np.isnan(hm.elevation[2, 2])
    assert hm.elevation[3, 4] == 19
    # Pixel-is-area tie point at the corner: the first sample centre is half a pixel inside.
    assert (hm.geo.x0, hm.geo.y0) == pytest.approx((10.25, 49.875))


def test_nodata_is_compared_in_the_band_s_type(tmp_path):
    # GDAL writes float32 no-data with printf's six digits: "-3.40282e+38" is not the float64
    # of float32's lowest value, but it is that value once rounded to float32, as GDAL
    # compares it.
    data = np.linspace(0.0, 630.0, 20, dtype=np.float32).reshape(4, 5)
    data[0, 0] = data[3, 4] = np.finfo(np.float32).min
    path = tmp_path / "dem.tif"
    tifffile.imwrite(path, data, extratags=[(42113, 2, 0, "-3.40282e+38")])
    with pytest.warns(UserWarning, match="2 of its 20 samples"):  # tiny: 10% voids
        hm = load_heightmap(path)
    assert hm.voids == 2 and np.isnan(hm.elevation[0, 0]) and np.isnan(hm.elevation[3, 4])
    assert np.nanmax(hm.elevation) == pytest.approx(data[3, 3])


@pytest.mark.parametrize("dtype, compression, predictor", [
    (np.int16, "lzw", "horizontal"), (np.float32, "lzw", "floatingpoint"),
    (np.float32, "deflate", "floatingpoint"), (np.float64, "zstd", None),
])
def test_compressed_geotiffs_as_gdal_writes_them(tmp_path, dtype, compression, predictor):
    # LZW and DEFLATE with floating-point prediction are GDAL's usual DEM compression
    data = (np.add.outer(np.arange(32.0), np.arange(24.0)) * 7.5).astype(dtype)
    path = tmp_path / "dem.tif"
    tifffile.imwrite(path, data, compression=compression, predictor=predictor)
    np.testing.assert_array_equal(load_heightmap(path).elevation, data.astype(np.float64))


def test_minus_9999_is_a_depth_where_the_tag_names_another_void(tmp_path):
    data = np.full((4, 4), -9999, np.int16)
    data[0, :] = -4000
    data[3, 3] = -1
    tagged, untagged = tmp_path / "bathymetry.tif", tmp_path / "plain.tif"
    tifffile.imwrite(tagged, data, extratags=[(42113, 2, 0, "-1")])
    tifffile.imwrite(untagged, data)
    with pytest.warns(UserWarning, match="1 of its 16 samples"):
        hm = load_heightmap(tagged)
    assert hm.voids == 1 and np.nanmin(hm.elevation) == -9999
    with pytest.warns(UserWarning, match="11 of its 16 samples"):
        plain = load_heightmap(untagged)
    assert plain.voids == 11  # no tag: GDAL's habit, -9999, is void


def test_a_model_transformation_gives_the_spacing(tmp_path):
    # ModelTransformationTag instead of scale and tie point: 30 m pixels, north up
    matrix = (30.0, 0, 0, 500000.0, 0, -30.0, 0, 4100000.0, 0, 0, 0, 0, 0, 0, 0, 1.0)
    path = tmp_path / "dem.tif"
    tifffile.imwrite(path, np.arange(64, dtype=np.int16).reshape(8, 8), extratags=[
        (34264, 12, 16, matrix), (34735, 3, 8, (1, 1, 0, 1, 1024, 0, 1, 1))])
    hm = load_heightmap(path)
    assert (hm.geo.dx, hm.geo.dy, hm.geo.geographic) == (30.0, 30.0, False)
    assert (hm.geo.x0, hm.geo.y0) == pytest.approx((500015.0, 4099985.0))
    rotated = tmp_path / "rotated.tif"
    tifffile.imwrite(rotated, np.arange(64, dtype=np.int16).reshape(8, 8), extratags=[
        (34264, 12, 16, (21.2, 21.2, 0, 0, -21.2, 21.2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1.0))])
    with pytest.warns(UserWarning, match="rotates its grid"):
        assert load_heightmap(rotated).geo is None


def test_a_damaged_pixel_scale_is_ignored_with_a_note(tmp_path):
    """A zeroed byte can turn the pixel scale into 1e-309: the terrain's metres per voxel
    then divided by zero. The georeference is dropped with a note instead."""
    path = tmp_path / "dem.tif"
    tifffile.imwrite(path, np.arange(64, dtype=np.int16).reshape(8, 8), extratags=[
        (33550, 12, 3, (3.5e-309, 3.8e-309, 0.0)),
        (33922, 12, 6, (0, 0, 0, 137.4, 36.9, 0)),
    ])
    with pytest.warns(UserWarning, match="implausible GeoTIFF pixel scale"):
        hm = load_heightmap(path)
    assert hm.geo is None
    cols = terrain_columns(hm, 8)
    assert cols.top.shape == (8, 8)


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
    hm = load_heightmap("jacksboro")
    assert hm.shape == (344, 403)
    assert np.nanmin(hm.elevation) == 236 and np.nanmax(hm.elevation) == 1076
    # Rows already run north to south (matplotlib plots it with origin="upper"): unchanged.
    raw = cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"]
    assert np.array_equal(hm.elevation, raw)
    assert hm.geo.y0 == pytest.approx(36.7329 - 0.0004, abs=1e-3)
    assert hm.spacing[0] == pytest.approx(92.7, abs=0.5)  # ~90 m, 3″


def test_topobathy_sample_is_flipped_north_up():
    hm = load_heightmap("topobathy")
    raw = cbook.get_sample_data("topobathy.npz")
    assert hm.shape == (91, 120)
    assert np.nanmin(hm.elevation) == -1437 and np.nanmax(hm.elevation) == 2205
    assert raw["latitude"][0] < raw["latitude"][-1]  # stored south first...
    assert np.array_equal(hm.elevation[0], raw["topo"][-1])  # ...so row 0 is the last row
    assert hm.geo.y0 == pytest.approx(float(raw["latitude"].max()))
