"""DEMs with many voids or infinite heights: filled with a note naming the file and the share
filled, refused where no sample is a height (``voxfield.scene.terrain.dem._checked_heights``)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import tifffile

from voxfield.cli import main
from voxfield.errors import SceneFormatError
from voxfield.scene.terrain.columns import terrain_columns
from voxfield.scene.terrain.dem import VOIDS_NOTED, load_heightmap
from voxfield.scene.terrain.resample import fill_voids


def ramp(n: int = 32) -> np.ndarray:
    return np.add.outer(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))


def test_a_mostly_void_dem_is_filled_with_a_note_of_the_share(tmp_path):
    """It was filled flat from a few heights without a word."""
    heights = np.full((32, 32), np.nan)
    heights[:3, :3] = ramp(3)
    path = tmp_path / "mostly_void.npy"
    np.save(path, heights)
    voids = int(np.isnan(heights).sum())
    share = voids / heights.size
    with pytest.warns(UserWarning, match=re.escape(
            f"{path}: {voids:,} of its {heights.size:,} samples ({100 * share:.3g}%) have no "
            f"height ({voids:,} no-data voids); they were filled in smoothly from the 9 that "
            "do")):
        hm = load_heightmap(path)
    assert hm.voids == voids  # still filled as before, in the columns
    cols = terrain_columns(hm, 8)
    assert np.isfinite(cols.elevation).all()


def test_infinite_heights_are_noted_and_filled_like_voids(tmp_path):
    heights = ramp()
    heights[4, 5], heights[6, 7] = np.inf, -np.inf
    heights[10, 10] = np.nan
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=heights)
    with pytest.warns(UserWarning, match=re.escape(
            f"{path}: 3 of its 1,024 samples (0.293%) have no height (1 no-data void, "
            "2 infinite); they were filled in smoothly from the 1,021 that do")):
        hm = load_heightmap(path)
    assert np.isnan(hm.elevation[[4, 6, 10], [5, 7, 10]]).all() and hm.voids == 3
    np.testing.assert_array_equal(terrain_columns(hm, 32).elevation,
                                  fill_voids(np.where(np.isfinite(heights), heights, np.nan)))


def test_a_geotiff_s_infinities_are_noted_unless_its_tag_names_them_no_data(tmp_path):
    heights = ramp(8).astype(np.float32)
    heights[2, 3] = np.inf
    plain, tagged = tmp_path / "plain.tif", tmp_path / "tagged.tif"
    tifffile.imwrite(plain, heights)
    tifffile.imwrite(tagged, heights, extratags=[(42113, 2, 0, "inf")])
    with pytest.warns(UserWarning, match=r"have no height \(1 infinite\)"):
        assert load_heightmap(plain).voids == 1
    with pytest.warns(UserWarning, match=r"have no height \(1 no-data void\)"):
        assert load_heightmap(tagged).voids == 1


def test_a_few_voids_are_filled_without_a_note(tmp_path):
    """An SRTM tile holds a few (N40W074: 0.07%): filled as ever, unremarked."""
    heights = ramp()
    heights[3, 4] = np.nan
    assert 1 / heights.size <= VOIDS_NOTED
    path = tmp_path / "few.npy"
    np.save(path, heights)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hm = load_heightmap(path)
    assert hm.voids == 1
    assert terrain_columns(hm, 32).elevation[3, 4] == pytest.approx(3 + 4)  # between 6 and 8


@pytest.mark.parametrize("fill, words", [(np.inf, "64 infinite"),
                                         (np.nan, "64 no-data voids")])
def test_a_dem_without_one_finite_height_is_refused_naming_the_file(tmp_path, fill, words):
    path = tmp_path / "none.npy"
    np.save(path, np.full((8, 8), fill))
    with pytest.raises(SceneFormatError, match=re.escape(
            f"{path}: none of its 64 samples is a height ({words}); nothing to build")):
        load_heightmap(path)


@pytest.mark.filterwarnings("default::UserWarning")  # the CLI prints it as a note
def test_the_command_line_notes_a_mostly_void_dem(tmp_path, capsys):
    heights = np.full((16, 16), np.nan)
    heights[0, :2] = (1.0, 2.0)
    path = tmp_path / "holes.npy"
    np.save(path, heights)
    assert main(["info", str(path), "--footprint", "16"]) == 0
    assert capsys.readouterr().err.startswith(
        f"voxfield: note: {path}: 254 of its 256 samples (99.2%) have no height")
