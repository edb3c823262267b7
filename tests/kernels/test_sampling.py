"""Kensler CMJ sampling: its stratification properties, determinism, and seed sensitivity."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.kernels.sampling import (
    cmj_sample,
    cmj_sample_in,
    cmj_strata,
    divide,
    permute,
    rand_float,
    subpixel,
)


@pytest.mark.parametrize("length", [1, 2, 3, 4, 7, 16, 33])
def test_permute_is_a_permutation(length):
    for pattern in (0, 1, 12345, 0xDEADBEEF):
        values = [permute(i, length, pattern) for i in range(length)]
        assert sorted(values) == list(range(length))


def test_rand_float_is_in_unit_interval_and_roughly_uniform():
    values = np.array([rand_float(i, 77) for i in range(20000)])
    assert values.min() >= 0.0 and values.max() < 1.0
    counts, _ = np.histogram(values, bins=10, range=(0, 1))
    assert counts.min() > 1700 and counts.max() < 2300


@pytest.mark.parametrize(("m", "n"), [(4, 4), (2, 2), (3, 5)])
def test_cmj_is_multi_jittered(m, n):
    """Each sample lies in its own m×n cell, its own of m·n columns and of m·n rows."""
    for pattern in (1, 99, 2024):
        pts = np.array([cmj_sample(s, m, n, pattern) for s in range(m * n)])
        assert np.all((pts >= 0) & (pts < 1))
        cells = {(int(x * m), int(y * n)) for x, y in pts}
        assert len(cells) == m * n
        assert len({int(x * m * n) for x, _ in pts}) == m * n
        assert len({int(y * m * n) for _, y in pts}) == m * n


def test_patterns_are_deterministic_and_depend_on_seed_and_pixel():
    a = [subpixel(10, s, 4, seed=3) for s in range(16)]
    assert a == [subpixel(10, s, 4, seed=3) for s in range(16)]
    assert a != [subpixel(10, s, 4, seed=4) for s in range(16)]
    assert a != [subpixel(11, s, 4, seed=3) for s in range(16)]
    assert subpixel(5, 0, 1, seed=9) == (0.5, 0.5)


def test_python_and_numba_versions_agree():
    jit = [cmj_sample(s, 4, 4, 4242) for s in range(16)]
    py = [cmj_sample.py_func(s, 4, 4, 4242) for s in range(16)]
    assert jit == py


def test_strata_tables_give_the_same_samples_as_permuting_per_sample():
    for m, n, pattern in ((1, 1, 7), (2, 3, 12345), (4, 4, 0xDEADBEEF), (5, 7, 99), (32, 33, 3)):
        column = np.empty(m, np.int64)
        row = np.empty(n, np.int64)
        cmj_strata(m, n, pattern, column, row)
        for s in range(m * n):
            assert cmj_sample_in(s, s % m, s // m, m, n, pattern, column, row) == \
                cmj_sample(s, m, n, pattern)


def test_divide_gives_the_bits_of_a_true_division():
    """The multiply by an exact reciprocal stands in for ``/`` only where it is exact: for
    powers of two, and (by division) for every other count, whatever the value."""
    rng = np.random.default_rng(5)
    values = np.concatenate([rng.random(2000) * 4096.0, rng.random(200) * 1e-300,
                             [0.0, 1.0, 2.0**-1070, 1e308]])
    for n in (1, 2, 3, 4, 5, 7, 16, 512, 640, 1 << 20, 1000003):
        for v in values:
            assert divide(float(v), n) == float(v) / n
