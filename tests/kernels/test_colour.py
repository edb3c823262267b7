"""Colour storage: kernels read 8-bit sRGB and float32 channels alike."""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.colour import (
    SRGB8_TO_LINEAR,
    decode_channel,
    from_srgb8,
    node_rgb,
    srgb_decode,
    to_srgb8,
)


@njit
def _read(colors, node):
    return node_rgb(colors, node)


def test_every_8_bit_code_survives_a_decode_encode_round_trip():
    codes = np.arange(256, dtype=np.uint8)
    assert np.array_equal(to_srgb8(from_srgb8(codes)), codes)
    # The table is the loaders' decoding of k / 255.
    assert np.array_equal(SRGB8_TO_LINEAR, srgb_decode(np.arange(256) / 255.0))


def test_kernels_read_both_storages_as_linear_rgb():
    linear = np.array([[0.0, 0.5, 1.0], [0.2, 0.04, 0.7]], np.float32)
    codes = to_srgb8(linear)
    for stored in (linear, codes):
        got = np.array(_read(stored, 1))
        assert np.array_equal(got.astype(np.float32), decode_channel(stored)[1])
    assert np.allclose(_read(codes, 1), linear[1], atol=4e-3)  # one 8-bit step at most
