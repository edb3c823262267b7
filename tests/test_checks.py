"""The library's argument checks: what they accept, what they refuse, and in what words."""

from __future__ import annotations

import math

import numpy as np
import pytest

from voxfield.checks import (
    MAX_SEED,
    integer_in,
    is_integer,
    is_real,
    ray_arrays,
    real_number,
    seed_value,
)
from voxfield.errors import VoxfieldError


@pytest.mark.parametrize("value", [0, 3, 7, np.int64(5), np.uint8(7), np.int32(0)])
def test_integers_in_range_come_back_as_python_ints(value):
    got = integer_in(value, "count", 0, 7)
    assert got == int(value) and type(got) is int


@pytest.mark.parametrize("value", [True, False, 2.0, 2.5, np.float64(3.0), "3", None, [3]])
def test_anything_but_an_integer_is_refused(value):
    with pytest.raises(VoxfieldError, match=r"^count must be an integer in 0\.\.7, got "):
        integer_in(value, "count", 0, 7)


@pytest.mark.parametrize(("value", "low", "high"), [(-1, 0, 7), (8, 0, 7), (0, 1, None)])
def test_integers_outside_the_range_are_refused(value, low, high):
    limits = f"≥ {low}" if high is None else f"in {low}..{high}"
    with pytest.raises(VoxfieldError, match=f"must be an integer {limits}, got {value}$"):
        integer_in(value, "count", low, high)


def test_no_upper_end_takes_any_large_integer():
    assert integer_in(10**30, "count", 1) == 10**30


@pytest.mark.parametrize("value", [0, -2.5, 1e300, np.float32(0.25), np.int16(3)])
def test_real_numbers_come_back_as_floats(value):
    got = real_number(value, "scale")
    assert got == float(value) and type(got) is float


@pytest.mark.parametrize("value", [True, "1", None, 1j])
def test_non_numbers_are_refused(value):
    with pytest.raises(VoxfieldError, match="^scale must be a number, got "):
        real_number(value, "scale")


def test_nan_is_always_refused_and_infinity_only_where_asked():
    for finite in (True, False):
        with pytest.raises(VoxfieldError, match="scale must be a"):
            real_number(math.nan, "scale", finite=finite)
    with pytest.raises(VoxfieldError, match="finite number"):
        real_number(math.inf, "scale")
    assert real_number(-math.inf, "scale", finite=False) == -math.inf


def test_seeds_are_32_bit_words():
    assert seed_value(0) == 0 and seed_value(MAX_SEED) == MAX_SEED == 2**32 - 1
    for bad in (-1, MAX_SEED + 1, 1.0):
        with pytest.raises(VoxfieldError, match="seed must be an integer in 0..4294967295"):
            seed_value(bad)


def test_rays_come_back_as_contiguous_float64_arrays():
    o, d = ray_arrays([[0, 1, 2]], np.asfortranarray(np.array([[1, 0, 0]], np.int32)))
    for a in (o, d):
        assert a.dtype == np.float64 and a.flags.c_contiguous and a.shape == (1, 3)
    assert d.tolist() == [[1.0, 0.0, 0.0]]
    # A tiny direction is a direction: the traversal flushes what it cannot invert.
    assert ray_arrays([[0, 0, 0]], [[1e-200, 0, 0]])[1][0, 0] == 1e-200


@pytest.mark.parametrize(("origins", "directions", "message"), [
    ([[0, 0, 0]], [[0, 0, 0]], "zero vector"),
    ([[0, 0, math.inf]], [[1, 0, 0]], "NaN or infinity"),
    ([[0, 0, 0]], [[math.nan, 1, 0]], "NaN or infinity"),
    ([[0, 0]], [[1, 0]], "N×3"),
    ([[0, 0, 0], [1, 1, 1]], [[1, 0, 0]], "N×3"),
    # NumPy's own words (a ValueError about converting "a"), or a ComplexWarning and the
    # imaginary parts dropped, before.
    ([["a", "b", "c"]], [[1, 0, 0]], "real numbers, got <U1"),
    ([[0, 0, 1j]], [[1, 0, 0]], "real numbers, got complex128"),
    ([[0, 0, 0], [1, 1]], [[1, 0, 0], [0, 1, 0]], "rows of three numbers"),
])
def test_bad_rays_are_refused(origins, directions, message):
    with pytest.raises(VoxfieldError, match=message):
        ray_arrays(origins, directions)


def test_the_predicates_tell_bools_from_numbers():
    assert all(is_integer(v) for v in (0, -3, np.int8(1), np.uint64(2**63)))
    assert not any(is_integer(v) for v in (True, np.bool_(True), 1.0, "1", None))
    assert all(is_real(v) for v in (0, 1.5, math.nan, -math.inf, np.float16(2), np.int32(1)))
    assert not any(is_real(v) for v in (False, np.bool_(False), "1.5", None, 1j))


def test_read_only_rays_reach_the_kernels_as_the_same_type():
    """A read-only array is another type to Numba: the ray query compiled its kernel again
    for one (seconds on a first call). The checked rays are writable copies of such arrays,
    and writable float64 rays pass through uncopied."""
    from voxfield.kernels.ray_batch import trace_rays
    from voxfield.render.ray_query import trace
    from voxfield.svo.open import open_octree

    rng = np.random.default_rng(2)
    origins, dirs = rng.uniform(-5.0, 40.0, (50, 3)), rng.normal(size=(50, 3))
    o, d = ray_arrays(origins, dirs)
    assert o is origins and d is dirs
    octree = open_octree("builtin:sphere")
    first = trace(octree, origins, dirs)
    compiled = len(trace_rays.signatures)
    origins.flags.writeable = dirs.flags.writeable = False
    o, d = ray_arrays(origins, dirs)
    assert o.flags.writeable and d.flags.writeable
    again = trace(octree, origins, dirs)
    assert len(trace_rays.signatures) == compiled
    np.testing.assert_array_equal(again.node, first.node)
