"""Counter pictures: one colour per LOD, black for misses, steps scaled by their 99th percentile."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps

from voxfield.render.counter_maps import lod_map, steps_heatmap
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
