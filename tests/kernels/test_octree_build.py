"""The build's flat-array loops (``kernels.octree_build``) against NumPy and brute force."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.kernels.octree_build import (
    child_means,
    group_parents,
    has_repeats,
    morton_codes,
    sort_codes,
)
from voxfield.svo import morton_encode


@pytest.mark.parametrize("code_bits", [1, 12, 13, 24, 39, 63])
def test_radix_sort_orders_as_a_stable_argsort(code_bits):
    rng = np.random.default_rng(code_bits)
    codes = rng.integers(0, 2**code_bits, 5000, dtype=np.uint64)
    codes[::7] = codes[3]  # repeats: their input order must survive
    keys, order = sort_codes(codes, code_bits)
    expected = np.argsort(codes, kind="stable")
    assert np.array_equal(order, expected)
    assert np.array_equal(keys, codes[expected])


def test_radix_sort_of_nothing_one_code_and_codes_sharing_a_digit():
    for codes in (np.zeros(0, np.uint64), np.array([5], np.uint64),
                  np.array([3 << 20, 1 << 20, 2 << 20], np.uint64)):  # low digits all 0
        keys, order = sort_codes(codes, 24)
        assert np.array_equal(order, np.argsort(codes, kind="stable"))
        assert np.array_equal(keys, np.sort(codes))


def test_repeats_are_found_between_neighbours_only():
    assert not has_repeats(np.array([1, 2, 5], np.uint64))
    assert has_repeats(np.array([1, 2, 2, 5], np.uint64))
    assert not has_repeats(np.zeros(0, np.uint64))


def test_codes_relative_to_an_origin_are_the_codes_of_the_shifted_corners():
    rng = np.random.default_rng(0)
    origin = np.array([-40, 7, 1000])
    coords = origin + rng.integers(0, 2**20, (500, 3))
    assert np.array_equal(morton_codes(coords, origin), morton_encode(coords - origin))


def test_parents_group_their_children_as_numpy_would():
    rng = np.random.default_rng(1)
    codes = np.unique(rng.integers(0, 4096, 1500).astype(np.uint64))
    solid = rng.random(len(codes)) < 0.9
    parent_codes, starts, masks, parent_solid = group_parents(codes, solid)
    above = codes >> np.uint64(3)
    expected_starts = np.flatnonzero(np.r_[True, above[1:] != above[:-1]])
    assert np.array_equal(starts, expected_starts)
    assert np.array_equal(parent_codes, above[expected_starts])
    bits = (1 << (codes & np.uint64(7)).astype(np.int64)).astype(np.uint8)
    assert np.array_equal(masks, np.bitwise_or.reduceat(bits, expected_starts))
    counts = np.diff(np.r_[expected_starts, len(codes)])
    assert np.array_equal(parent_solid,
                          (counts == 8) & np.logical_and.reduceat(solid, expected_starts))


@pytest.mark.parametrize("children", range(1, 9))
def test_child_means_are_numpys_reduceat_means_to_the_bit(children):
    # Exponents 60 decades apart: float64 sums then depend on their order, so only
    # NumPy's own order gives the same float32 means.
    rng = np.random.default_rng(children)
    parents = 20000
    values = (rng.standard_normal((parents * children, 3))
              * 10.0 ** rng.integers(-30, 30, (parents * children, 3))).astype(np.float32)
    values[:children] = -0.0  # a parent of negative zeros keeps its sign
    starts = np.arange(parents) * children
    expected = (np.add.reduceat(values, starts, axis=0, dtype=np.float64)
                / children).astype(np.float32)
    got = child_means(starts, values)
    assert got.dtype == np.float32
    assert np.array_equal(got.view(np.int32), expected.view(np.int32))
