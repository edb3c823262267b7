"""Counter pictures: one colour per LOD, black for misses, steps scaled by their 99th
percentile; the written maps keep every pixel and carry their colour bars."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib import colormaps

from voxfield.render.counter_maps import (
    LEGEND_MIN_HEIGHT,
    LEGEND_WIDTH,
    lod_colours,
    lod_figure,
    lod_map,
    rays_figure,
    rays_map,
    steps_figure,
    steps_heatmap,
    steps_norm,
    steps_scale,
)
from voxfield.render.result import RenderResult


def _result(lod, steps):
    h, w = lod.shape
    z = np.zeros((h, w), np.float32)
    return RenderResult(np.zeros((h, w, 3), np.float32), z, np.zeros((h, w, 3), np.float32),
                        np.ones((h, w), np.int32), (lod >= 0).astype(np.int32),
                        steps.astype(np.int64), lod.astype(np.int8))


def test_lod_map_gives_each_lod_its_colour_and_misses_black():
    lod = np.array([[0, 1, 2, -1]])
    rgb = lod_map(_result(lod, np.ones((1, 4))), depth=2)
    viridis = colormaps["viridis"]
    assert np.allclose(rgb[0, 0], viridis(1.0)[:3])
    assert np.allclose(rgb[0, 1], viridis(0.5)[:3])
    assert np.allclose(rgb[0, 2], viridis(0.0)[:3])
    assert np.all(rgb[0, 3] == 0)


def test_steps_heatmap_is_monotone_in_steps():
    steps = np.arange(100).reshape(10, 10)
    rgb = steps_heatmap(_result(np.zeros((10, 10), int), steps))
    brightness = rgb.sum(axis=-1).ravel()
    assert np.all(np.diff(brightness[:99]) >= -1e-9)
    assert np.allclose(rgb[0, 0], colormaps["magma"](0.0)[:3])


def test_a_cheap_pixel_stands_apart_from_an_empty_one():
    """On a linear scale a coarse LOD's few steps beside refined pixels' hundreds drew as
    black as the background: the log scale puts a hundredth of the top a third of the way
    up, and every tenfold step the same distance further."""
    steps = np.zeros((10, 100), int)
    steps[0, :] = 600
    steps[1, 0], steps[1, 1], steps[1, 2] = 6, 60, 1
    result = _result(np.zeros((10, 100), int), steps)
    top = steps_scale(result)
    scale = steps_norm(result)
    assert scale(top / 100) > 0.3 and scale(0) == 0.0 and scale(top) == 1.0
    assert scale(60) - scale(6) == pytest.approx(scale(600) - scale(60), abs=0.02)
    rgb = steps_heatmap(result)
    assert rgb[1, 0].sum() > rgb[2, 0].sum() + 0.15  # 6 steps against none


def _has_colour(pixels: np.ndarray, colour) -> bool:
    return bool(np.any(np.all(np.abs(pixels - np.asarray(colour)) <= 2.5 / 255, axis=-1)))


def test_the_written_lod_map_keeps_every_pixel_and_shows_each_lod_in_its_bar():
    rng = np.random.default_rng(3)
    lod = rng.integers(-1, 3, (40, 50))  # LODs 0..2 of a depth-5 octree, and misses
    result = _result(lod, np.ones((40, 50)))
    figure = lod_figure(result, depth=5)
    assert figure.shape == (LEGEND_MIN_HEIGHT, 50 + LEGEND_WIDTH, 3)
    assert np.abs(figure[:40, :50] - lod_map(result, 5)).max() <= 1 / 255 + 1e-9
    assert np.all(figure[40:, :50] == 1.0)  # white below the map
    bar = figure[:, 50:]
    for colour in lod_colours(5):  # every LOD the octree has, not only those drawn
        assert _has_colour(bar, colour)


def test_the_written_steps_map_keeps_every_pixel_and_spans_its_scale():
    steps = np.arange(200 * 300).reshape(200, 300) % 97
    result = _result(np.zeros((200, 300), int), steps)
    figure = steps_figure(result)
    assert figure.shape == (200, 300 + LEGEND_WIDTH, 3)
    assert np.abs(figure[:, :300] - steps_heatmap(result)).max() <= 1 / 255 + 1e-9
    bar = figure[:, 300:]
    assert _has_colour(bar, colormaps["magma"](0.0)[:3])
    assert _has_colour(bar, colormaps["magma"](0.95)[:3])  # (its top pixel rounds down)
    assert steps_scale(result) == np.percentile(steps[steps > 0], 99)


def test_the_written_rays_map_gives_each_count_its_band():
    rays = np.array([[1, 4, 16, 21], [1, 1, 4, 5]])  # an error-aware render's counts
    result = _result(np.zeros((2, 4), int), np.ones((2, 4)))
    result.ray_count = rays.astype(np.int32)
    rgb, top = rays_map(result)
    assert top == 21
    assert np.allclose(rgb[0, 0], colormaps["viridis"](1 / 21)[:3])
    assert np.allclose(rgb[0, 3], colormaps["viridis"](1.0)[:3])
    figure = rays_figure(result)
    assert np.abs(figure[:2, :4] - rgb).max() <= 1 / 255 + 1e-9
    bar = figure[:, 4:]
    for count in (0, 1, 4, 5, 16, 21):  # a band per count, those not drawn included
        assert _has_colour(bar, colormaps["viridis"](count / 21)[:3])
