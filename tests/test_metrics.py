"""Metrics against closed forms, histograms against hand-counted pixels, bad input refused."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.metrics import (
    MISSED,
    compare_images,
    cost_summary,
    flip,
    flip_available,
    lod_histogram,
    psnr,
    ray_distribution,
    ray_histogram,
    rmse,
    ssim,
)
from voxfield.render.result import RenderResult
from voxfield.scene.voxel_scene import linear_to_srgb


@pytest.fixture
def image():
    rng = np.random.default_rng(3)
    return (0.2 + 0.6 * rng.random((24, 32, 3))).astype(np.float32)


def test_identical_images_are_perfect(image):
    m = compare_images(image, image.copy())
    assert m["psnr"] == math.inf and m["rmse"] == 0.0 and m["ssim"] == pytest.approx(1.0)
    assert m["flip"] is None or m["flip"] == pytest.approx(0.0, abs=1e-6)


def test_constant_offset_gives_the_closed_form_psnr_and_rmse(image):
    offset = np.float32(0.05)
    test = image + offset
    mse = float(np.mean((test.astype(np.float64) - image) ** 2))  # offset² up to float32 rounding
    assert mse == pytest.approx(0.05**2, rel=1e-4)
    assert psnr(image, test) == pytest.approx(10 * math.log10(1.0 / mse), rel=1e-5)
    assert psnr(image, test) == pytest.approx(26.0206, abs=1e-3)
    assert rmse(image, test) == pytest.approx(0.05, rel=1e-4)


def test_rmse_averages_over_every_channel():
    ref = np.zeros((8, 8, 3), np.float32)
    test = ref.copy()
    test[:4, :, 0] = 0.3  # half the pixels, one channel of three
    assert rmse(ref, test) == pytest.approx(math.sqrt(0.3**2 / 6), rel=1e-6)


def test_ssim_falls_as_noise_grows(image):
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(image.shape).astype(np.float32)
    values = [ssim(image, np.clip(image + s * noise, 0, 1)) for s in (0.0, 0.01, 0.05, 0.2)]
    assert values[0] == pytest.approx(1.0)
    assert values[0] > values[1] > values[2] > values[3]
    assert values[3] < 0.8


@pytest.mark.skipif(not flip_available(), reason="flip-evaluator is not installed")
def test_flip_is_evaluated_on_srgb_encoded_images(image):
    import flip_evaluator

    test = np.clip(image * 0.8, 0, 1)
    _, expected, _ = flip_evaluator.evaluate(linear_to_srgb(image), linear_to_srgb(test), "LDR",
                                             applyMagma=False)
    assert flip(image, test) == pytest.approx(expected, rel=1e-6)
    assert 0.0 < flip(image, test) < 1.0


def test_flip_is_none_without_the_package(image, monkeypatch):
    monkeypatch.setitem(sys.modules, "flip_evaluator", None)  # import now raises ImportError
    assert not flip_available()
    assert flip(image, image) is None
    assert compare_images(image, image * 0.5)["flip"] is None


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((24, 32), np.float32), "H×W×3"),
        (np.zeros((24, 32, 4), np.float32), "H×W×3"),
        (np.zeros((24, 31, 3), np.float32), "differ in size"),
        (np.full((24, 32, 3), np.nan, np.float32), "NaN"),
        (np.full((24, 32, 3), 2.0, np.float32), "tone-map"),
        (np.zeros((0, 32, 3), np.float32), "empty"),
        (np.full((24, 32, 3), "a"), "real numbers"),
    ],
)
def test_bad_images_are_refused(image, bad, message):
    for function in (compare_images, psnr, rmse, ssim, flip):
        with pytest.raises(VoxfieldError, match=message):
            function(image, bad)


def test_images_smaller_than_the_ssim_window_are_refused_by_ssim_alone():
    """PSNR and RMSE have no window: a 1×1 or 5×5 image has them (``shadows --size 4``,
    which measures PSNR alone, rendered everything and then failed 'for SSIM')."""
    small = np.zeros((5, 5, 3), np.float32)
    for function in (compare_images, ssim):
        with pytest.raises(VoxfieldError, match="at least 7"):
            function(small, small)
    for side in (1, 5):
        reference = np.zeros((side, side, 3), np.float32)
        test = np.full((side, side, 3), 0.1, np.float32)
        assert rmse(reference, test) == pytest.approx(0.1)
        assert psnr(reference, test) == pytest.approx(20.0, abs=1e-4)  # 10 log10(1 / 0.01)


def _result(rays, hits, lod, steps=None, **maps):
    rays = np.asarray(rays, np.int32)
    h, w = rays.shape
    steps = np.full((h, w), 10, np.int64) if steps is None else np.asarray(steps, np.int64)
    return RenderResult(
        np.zeros((h, w, 3), np.float32), np.zeros((h, w), np.float32),
        np.zeros((h, w, 3), np.float32), rays, np.asarray(hits, np.int32), steps,
        np.asarray(lod, np.int8), seconds=0.5, renderer="synthetic", maps=maps,
    )


def test_error_aware_histograms_and_totals():
    # Pixels: background, 1 ray at LOD 2, 5 rays (1 discarded), 9 (2), 21 (5 discarded, all
    # 16 hit), and a 5-ray pixel where one of the four finer rays missed.
    rays = [[1, 1, 5], [9, 21, 5]]
    hits = [[0, 1, 4], [7, 16, 3]]
    lod = [[-1, 2, 1], [0, 0, 1]]
    refined = np.array([[0, 0, 1], [2, 5, 1]])
    result = _result(rays, hits, lod, refined=refined)

    assert ray_histogram(result) == {MISSED: 1, "1": 1, "4": 0, "16": 0, "other": 4}
    dist = ray_distribution(result)
    assert dist[MISSED] == 1 and dist["1"] == 1 and dist["5"] == 2 and dist["9"] == 1
    assert dist["21"] == 1 and dist["other"] == 0 and sum(dist.values()) == 6
    assert lod_histogram(result) == {MISSED: 1, "LOD 2": 1, "LOD 1": 2, "LOD 0": 2}

    cost = cost_summary(result)
    assert cost["rays"] == 42
    assert cost["rays_discarded"] == 9
    assert cost["rays_hit"] == 31 + 9  # one background miss and one edge miss not counted
    assert cost["covered_pixels"] == 5
    assert cost["rays_per_pixel"] == pytest.approx(40 / 5)
    assert cost["rays_per_pixel_all"] == pytest.approx(42 / 6)
    assert cost["traversal_steps"] == 60 and cost["steps_per_ray"] == pytest.approx(60 / 42)
    assert cost["mrays_per_second"] == pytest.approx(42 / 0.5 / 1e6)


def test_adaptive_histogram_follows_the_refinement_class():
    # Thesis Table 5.3 counts a pixel refined to 2×2 as a "4 rays" pixel (1 + 4 cast).
    classes = np.array([[-1, 0, 1, 2]], np.int8)
    result = _result([[1, 1, 5, 17]], [[0, 1, 4, 16]], [[-1, 2, 0, 0]],
                     refinement_class=classes, variance=np.zeros((1, 4)))
    assert ray_histogram(result) == {MISSED: 1, "1": 1, "4": 1, "16": 1, "other": 0}
    assert lod_histogram(result) == {MISSED: 1, "LOD 2": 1, "LOD 1": 0, "LOD 0": 2}


def test_reference_pixels_are_all_sixteen_rays_at_lod_zero():
    result = _result(np.full((3, 3), 16), np.full((3, 3), 16), np.zeros((3, 3)))
    assert ray_histogram(result) == {MISSED: 0, "1": 0, "4": 0, "16": 9, "other": 0}
    assert lod_histogram(result) == {MISSED: 0, "LOD 0": 9}
    assert cost_summary(result)["rays_per_pixel"] == 16.0


def test_malformed_results_are_refused():
    good = _result([[1, 1]], [[1, 1]], [[0, 0]])
    with pytest.raises(VoxfieldError, match="RenderResult"):
        cost_summary({"ray_count": 1})
    bad = _result([[1, 1]], [[1, 1]], [[0, 0]])
    bad.steps = np.zeros((2, 2), np.int64)
    with pytest.raises(VoxfieldError, match="steps"):
        cost_summary(bad)
    bad = _result([[1, 1]], [[1, 1]], [[0, 0]])
    bad.ray_count = np.ones((1, 2), np.float32)
    with pytest.raises(VoxfieldError, match="integer"):
        cost_summary(bad)
    bad = _result([[1, -1]], [[1, 1]], [[0, 0]])
    with pytest.raises(VoxfieldError, match="negative"):
        cost_summary(bad)
    good.maps["refined"] = np.zeros((3, 3))
    with pytest.raises(VoxfieldError, match="refined"):
        cost_summary(good)


def test_renders_compare_as_their_images():
    """What a renderer returns is what a user compares: its colour image is taken, where
    the error read "must be H×W×3 RGB, got shape ()"."""
    a = RenderResult.allocate(8, 8)
    b = RenderResult.allocate(8, 8)
    a.image[:] = 0.5
    b.image[:] = 0.25
    assert compare_images(a, b) == compare_images(a.image, b.image)
