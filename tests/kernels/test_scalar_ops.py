"""The scalar operations Numba lowers directly compute what their plain Python bodies do."""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.scalar_ops import face_time, fmax, fmin


@njit(cache=True)
def _extremes(a, b, small_ints, unsigned):
    out = np.empty((len(a), 6))
    for i in range(len(a)):
        out[i, 0] = fmax(a[i], b[i])
        out[i, 1] = fmin(a[i], b[i])
        out[i, 2] = fmax(np.float32(a[i]), b[i])  # float32 against float64
        out[i, 3] = fmin(a[i], small_ints[i])  # float against int
        out[i, 4] = fmax(small_ints[i], unsigned[i])  # signed against unsigned: as float
        out[i, 5] = fmin(unsigned[i], unsigned[i - 1])  # unsigned, compared unsigned
    return out


def _as_float32(x):
    with np.errstate(over="ignore"):
        return np.float32(x)


def test_fmax_and_fmin_compiled_agree_with_their_python_bodies():
    rng = np.random.default_rng(7)
    a = np.concatenate([rng.normal(size=200) * 1e3, [0.0, -0.0, 1e300, -1e300, 2.5, 2.5]])
    b = np.concatenate([rng.normal(size=200) * 1e3, [-0.0, 0.0, -1e300, 1e300, 2.5, -2.5]])
    small_ints = rng.integers(-1000, 1000, len(a))
    unsigned = rng.integers(0, 2**63, len(a), dtype=np.uint64) * np.uint64(2)  # above 2**63
    compiled = _extremes(a, b, small_ints, unsigned)
    for i in range(len(a)):  # (±1e300 as float32 is ±inf, compiled and here alike)
        expected = [fmax(a[i], b[i]), fmin(a[i], b[i]),
                    fmax(float(_as_float32(a[i])), b[i]), fmin(a[i], small_ints[i]),
                    fmax(float(small_ints[i]), float(unsigned[i])),
                    fmin(int(unsigned[i]), int(unsigned[i - 1]))]
        np.testing.assert_array_equal(compiled[i], np.array(expected, dtype=np.float64))
    # the plain select keeps the builtin's choice between equal sides: the second one
    assert np.signbit(compiled[len(a) - 6, 0]) and not np.signbit(compiled[len(a) - 5, 0])


@njit(cache=True)
def _crossings(planes64, planes32, uplanes, o, o32, inv):
    out = np.empty((len(o), 4))
    for i in range(len(o)):
        out[i, 0] = face_time(planes64[i], o[i], inv[i])
        out[i, 1] = face_time(planes32[i], o[i], inv[i])
        out[i, 2] = face_time(uplanes[i], o[i], inv[i])
        out[i, 3] = face_time(planes64[i], o32[i], inv[i])  # a float32 origin, widened
    return out


def test_face_time_compiled_is_the_contracts_float64_formula_bit_for_bit():
    rng = np.random.default_rng(11)
    n = 500
    planes64 = rng.integers(-(2**40), 2**40, n)
    planes32 = rng.integers(-(2**31), 2**31 - 1, n).astype(np.int32)
    uplanes = rng.integers(0, 2**62, n, dtype=np.uint64) * np.uint64(3)  # some above 2**63
    o = rng.normal(size=n) * 1e6
    o32 = o.astype(np.float32)
    inv = 1.0 / rng.normal(size=n)
    compiled = _crossings(planes64, planes32, uplanes, o, o32, inv)
    expected = np.stack([
        (planes64.astype(np.float64) - o) * inv,
        (planes32.astype(np.float64) - o) * inv,
        (uplanes.astype(np.float64) - o) * inv,
        (planes64.astype(np.float64) - o32.astype(np.float64)) * inv,
    ], axis=1)
    np.testing.assert_array_equal(compiled, expected)
    python = [face_time(int(p), x, v)
              for p, x, v in zip(planes64[:5], o[:5], inv[:5], strict=True)]
    assert python == list(expected[:5, 0])
