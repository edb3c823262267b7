"""Level kernels: parent averages equal NumPy's ``add.reduceat`` to the bit; child corners
equal the octant arithmetic; the lighting bake's lit colours equal the NumPy formula."""

import numpy as np
import pytest

from voxfield.kernels.colour import decode_channel, to_srgb8
from voxfield.kernels.octree_levels import average_children, child_corners
from voxfield.kernels.sun_bake import lit_colours


def _runs(rng, parents):
    counts = rng.integers(1, 9, parents)
    return np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64), int(counts.sum())


def test_parent_means_equal_reduceat_bit_for_bit():
    rng = np.random.default_rng(3)
    starts, children = _runs(rng, 100_000)
    # Magnitudes 60 decades apart: float64 sums then depend on their order.
    values = (rng.random((children, 6)) * 10.0 ** rng.integers(-30, 30, (children, 6))
              ).astype(np.float32)
    out = np.empty((1, len(starts), 6), np.float32)
    average_children(starts, values[None], np.zeros(0), False, out, np.zeros(0))
    out = out[0]
    counts = np.diff(np.append(starts, children))
    want = (np.add.reduceat(values, starts, axis=0, dtype=np.float64)
            / counts[:, None]).astype(np.float32)
    assert np.array_equal(out.view(np.uint32), want.view(np.uint32))


@pytest.mark.parametrize("weight_type", [np.float64, np.float32])
def test_weighted_parent_means_and_weight_sums(weight_type):
    """Two channels of a block share the weights, float32 ones read as their float64
    widening."""
    rng = np.random.default_rng(4)
    starts, children = _runs(rng, 100_000)
    block = (rng.random((2, children, 3)) * 10.0 ** rng.integers(-30, 30, (2, children, 3))
             ).astype(np.float32)
    weights = (rng.random(children) * (rng.random(children) < 0.5)).astype(weight_type)
    out = np.empty((2, len(starts), 3), np.float32)
    sums = np.empty(len(starts))
    average_children(starts, block, weights, True, out, sums)
    counts = np.diff(np.append(starts, children))
    wide = weights.astype(np.float64)
    want_sums = np.add.reduceat(wide, starts)
    assert np.array_equal(sums, want_sums)
    seen = want_sums > 0
    assert (~seen).any() and seen.any()  # both rules were exercised
    for values, got in zip(block, out, strict=True):
        plain = np.add.reduceat(values, starts, axis=0, dtype=np.float64) / counts[:, None]
        weighted = np.add.reduceat(values * wide[:, None], starts, axis=0, dtype=np.float64)
        plain[seen] = weighted[seen] / want_sums[seen, None]
        assert np.array_equal(got, plain.astype(np.float32))


def test_child_corners_follow_the_octant_bits():
    masks = np.array([0b10000001, 0b00000110], np.uint8)
    parents = np.array([[0, 0, 0], [3, 1, 2]], np.int64)
    out = np.empty((4, 3), np.int64)
    child_corners(masks, parents, out)
    assert out.tolist() == [[0, 0, 0], [1, 1, 1], [7, 2, 4], [6, 3, 4]]


@pytest.mark.parametrize("storage", ["float32", "srgb8"])
def test_lit_colours_equal_the_per_sun_formula(storage):
    """Whatever the albedo's storage, the kernel decodes it as ``decode_channel`` does, and
    writes into strided rows (the voxel rows of a channel block) as into an array."""
    rng = np.random.default_rng(5)
    n, suns = 1000, 3
    stored = rng.random((n, 3)).astype(np.float32)
    if storage == "srgb8":
        stored = to_srgb8(stored)
    albedo = decode_channel(stored)
    direct = rng.random((suns, n)).astype(np.float32)
    sky = rng.random(n).astype(np.float32)
    irradiance, sky_colour = rng.random((suns, 3)), rng.random((suns, 3))
    block = np.full((suns, n + 7, 3), np.nan, np.float32)
    lit_colours(stored, direct, sky, irradiance, sky_colour, block[:, 5:5 + n])
    assert np.isnan(block[:, :5]).all() and np.isnan(block[:, 5 + n:]).all()
    for k in range(suns):
        light = np.outer(direct[k], irradiance[k]) + np.outer(sky, sky_colour[k])
        want = (albedo.astype(np.float64) * light).astype(np.float32)
        assert np.array_equal(block[k, 5:5 + n], want)
