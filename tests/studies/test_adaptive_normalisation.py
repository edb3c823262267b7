"""One variance normalisation across scenes (EA §5.1.2): its defining properties."""

from __future__ import annotations

import json

import numpy as np
import pytest

from voxfield.cli.main import main
from voxfield.errors import VoxfieldError
from voxfield.render.adaptive import normalisation_across
from voxfield.render.result import RenderResult


def flat_result(image: np.ndarray) -> RenderResult:
    h, w = image.shape[:2]
    result = RenderResult.allocate(h, w)
    result.image[...] = image
    result.hit_count[...] = 1
    return result


def two_halves(left: float, right: float) -> RenderResult:
    image = np.full((8, 8, 3), left, np.float32)
    image[:, 4:] = right
    return flat_result(image)


def test_the_constant_is_the_largest_window_variance_of_all_scenes():
    # A 3×3 window across a luminance step d holds 3 and 6 pixels (or 6 and 3): its sum of
    # squared differences from the mean is 9·(1/3)(2/3)·d² = 2·d².
    low, high = two_halves(0.2, 0.3), two_halves(0.1, 0.5)
    assert normalisation_across([low]) == pytest.approx(2 * 0.1**2, rel=1e-5)
    assert normalisation_across([low, high]) == pytest.approx(2 * 0.4**2, rel=1e-5)
    assert 0 < normalisation_across([low, high], quantile=0.9) < normalisation_across([low, high])


def test_flat_or_empty_first_passes_are_refused():
    with pytest.raises(VoxfieldError, match="no variance"):
        normalisation_across([two_halves(0.3, 0.3)])
    with pytest.raises(VoxfieldError, match="quantile"):
        normalisation_across([two_halves(0.1, 0.5)], quantile=0.0)


def test_a_quantile_that_lands_on_flat_windows_is_refused_with_the_least_that_works():
    # Six of the eight columns of 3×3 windows see no step: 75 % of the SSDs are 0, and a
    # constant of 0 would divide every variance by zero.
    with pytest.raises(VoxfieldError, match=r"75\.0 % .* flat; use a quantile above 0\.750"):
        normalisation_across([two_halves(0.1, 0.5)], quantile=0.5)
    assert normalisation_across([two_halves(0.1, 0.5)], quantile=0.8) > 0


def test_the_command_finds_one_constant_for_several_scenes(tmp_path, capsys):
    out = tmp_path / "norm"
    assert main(["study", "normalisation", "builtin:pillars", "builtin:menger", "--size", "32",
                 "--out", str(out)]) == 0
    report = json.loads((out / "results.json").read_text())
    assert [r["scene"] for r in report["scenes"]] == ["builtin:pillars", "builtin:menger"]
    assert report["normalisation"] == pytest.approx(max(r["max_ssd"] for r in report["scenes"]))
    assert f"{report['normalisation']:.5g}" in capsys.readouterr().out
    assert main(["--quiet", "render", "builtin:pillars", "--renderer", "adaptive", "--size",
                 "16", "--variance-normalisation", str(report["normalisation"]),
                 "--out", str(tmp_path / "a.png")]) == 0
