"""Colour storage: kernels read 8-bit sRGB and float32 channels alike."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit

from voxfield.kernels.bundles import octree_view
from voxfield.kernels.colour import (
    FLOAT32,
    RGB9E5,
    RGB9E5_MAX,
    SRGB8,
    SRGB8_THRESHOLDS,
    SRGB8_TO_LINEAR,
    decode_channel,
    encode_channel,
    from_rgb9e5,
    from_srgb8,
    node_rgb,
    srgb8_by_formula,
    srgb_decode,
    storage_of,
    stored_bytes,
    stored_colours,
    to_rgb9e5,
    to_srgb8,
)
from voxfield.kernels.facing_colour import NO_FACING


@njit
def _read(colors, node):
    return node_rgb(colors, node)


def test_every_8_bit_code_survives_a_decode_encode_round_trip():
    codes = np.arange(256, dtype=np.uint8)
    assert np.array_equal(to_srgb8(from_srgb8(codes)), codes)
    # The table is the loaders' decoding of k / 255.
    assert np.array_equal(SRGB8_TO_LINEAR, srgb_decode(np.arange(256) / 255.0))


def test_the_table_encoder_gives_the_formulas_codes_around_every_threshold():
    # 200 float32 steps either side of each code's first value, random values over [0, 1.5]
    # and the special values: the table must count exactly where the formula rounds.
    bits = SRGB8_THRESHOLDS.view(np.int32)[:, None] + np.arange(-200, 201)
    near = bits.ravel().view(np.float32)
    rng = np.random.default_rng(5)
    values = np.concatenate([near, rng.random(200_000, dtype=np.float32) * np.float32(1.5),
                             np.array([0.0, -0.0, -1.0, 1.0, np.inf, -np.inf], np.float32)])
    assert np.array_equal(to_srgb8(values), srgb8_by_formula(values))
    assert to_srgb8(np.array([np.nan], np.float32))[0] == 0
    # Shapes survive, and the codes step up by one at each threshold.
    grid = to_srgb8(SRGB8_THRESHOLDS.reshape(15, 17))
    assert grid.shape == (15, 17) and np.array_equal(grid.ravel(), np.arange(1, 256))


def test_kernels_read_both_storages_as_linear_rgb():
    linear = np.array([[0.0, 0.5, 1.0], [0.2, 0.04, 0.7]], np.float32)
    codes = to_srgb8(linear)
    for stored in (linear, codes):
        got = np.array(_read(stored, 1))
        assert np.array_equal(got.astype(np.float32), decode_channel(stored)[1])
    assert np.allclose(_read(codes, 1), linear[1], atol=4e-3)  # one 8-bit step at most


def rgb9e5_by_the_specification(rgb: np.ndarray) -> np.ndarray:
    """EXT_texture_shared_exponent's encoding, word for word, in float64 with frexp and
    ldexp: the oracle for the kernel's bit-level version."""
    c = np.where(np.isnan(rgb), 0.0, np.clip(rgb.astype(np.float64), 0.0, RGB9E5_MAX))
    largest = c.max(axis=1)
    floor_log2 = np.where(largest > 0, np.frexp(largest)[1] - 1, -16)
    exponent = np.maximum(-16, floor_log2) + 1 + 15
    round_up = np.floor(np.ldexp(largest, 24 - exponent) + 0.5) == 512
    exponent = exponent + round_up
    mantissas = np.floor(np.ldexp(c, (24 - exponent)[:, None]) + 0.5).astype(np.uint32)
    return (mantissas[:, 0] | mantissas[:, 1] << 9 | mantissas[:, 2] << 18
            | exponent.astype(np.uint32) << 27)


def hdr_colours(n: int, seed: int) -> np.ndarray:
    """Colours over every exponent, with the edge cases: zeros, a lone channel, values that
    round up to the next exponent, powers of two, the largest value and beyond, tiny and
    subnormal values, negatives, infinities and NaN."""
    rng = np.random.default_rng(seed)
    colours = np.exp2(rng.uniform(-30, 17, (n, 3))) * rng.integers(0, 2, (n, 3))
    edges = [[0, 0, 0], [1, 0, 0], [0, 0, 3.5], [511.75 / 512, 0.1, 0.2],
             [2.0 ** -15 * 511.6 / 512, 0, 0], [65408, 65408, 65408], [70000, 1, 2],
             [np.inf, 0, 1], [1e-45, 2.0 ** -24, 2.0 ** -25], [-1, 0.5, -0.0],
             [np.nan, 0.25, 4], [2.0 ** 15, 2.0 ** 14, 2.0 ** -16]]
    steps = np.ldexp(1.0, rng.integers(-24, 8, n))[:, None]
    exact_halves = (rng.integers(0, 512, (n, 3)) + 0.5) * steps  # ties round up
    return np.concatenate([colours, edges, exact_halves]).astype(np.float32)


def test_rgb9e5_codes_are_the_specifications():
    colours = hdr_colours(50_000, seed=1)
    assert np.array_equal(to_rgb9e5(colours), rgb9e5_by_the_specification(colours))


def test_rgb9e5_decodes_within_a_511th_of_the_largest_channel():
    colours = np.abs(hdr_colours(50_000, seed=2))
    colours = colours[np.all(np.isfinite(colours), axis=1) & (colours.max(axis=1) <= RGB9E5_MAX)]
    back = from_rgb9e5(to_rgb9e5(colours))
    error = np.abs(back - colours).max(axis=1)
    small = colours.max(axis=1) < 2.0 ** -16  # below the format's range: absolute steps
    assert np.all(error[~small] <= colours.max(axis=1)[~small] / 511)
    assert np.all(error[small] <= 2.0 ** -25)
    # Any decoded value is a code's exact value, so it encodes to the same value again.
    assert np.array_equal(from_rgb9e5(to_rgb9e5(back)), back)


def test_kernels_read_rgb9e5_as_its_decoding():
    codes = to_rgb9e5(hdr_colours(200, seed=3))
    decoded = decode_channel(codes)
    for node in range(len(codes)):
        assert np.array_equal(np.array(_read(codes, node), np.float32), decoded[node])
    assert storage_of(codes) == RGB9E5
    assert np.array_equal(encode_channel(decoded, RGB9E5), to_rgb9e5(decoded))


def test_stored_colours_read_as_the_array_they_hold_in_one_kernel_type():
    """The render kernels take a channel as ``StoredColours`` so that one compiled kernel
    serves every storage: each storage reads as its own array does, and all three views of
    an octree have the same Numba type."""
    linear = np.random.default_rng(8).random((120, 3), dtype=np.float32)
    stored = {storage: encode_channel(linear, storage) for storage in (SRGB8, RGB9E5, FLOAT32)}
    views = {}
    for storage, array in stored.items():
        bundle = stored_colours(array)
        assert bundle.stored is array
        assert stored_bytes_of(bundle) == array.nbytes
        for node in range(len(array)):
            assert _read(bundle, node) == _read(array, node), (storage, node)
            assert node_rgb(bundle, node) == node_rgb(array, node)  # the Python fallback
        views[storage] = octree_view(np.zeros(1, np.int64), 1, array, NO_FACING)
    kinds = {numba.typeof(view) for view in views.values()}
    assert len(kinds) == 1, kinds


@njit
def stored_bytes_of(colors):
    return stored_bytes(colors)
