"""``kernels.memory_hints.prefetch``: compiles to LLVM's prefetch for 1-D arrays of any
element type, changes no result, and refuses what it cannot address."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from voxfield.kernels.memory_hints import prefetch


@njit
def _gather_ahead(values, order, ahead):
    total = 0.0
    for k in range(order.shape[0]):
        if k + ahead < order.shape[0]:
            prefetch(values, order[k + ahead])
        total += values[order[k]]
    return total


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.float32, np.uint8])
def test_a_prefetched_gather_reads_what_a_plain_one_reads(dtype):
    rng = np.random.default_rng(3)
    values = rng.integers(0, 100, 10_000).astype(dtype)
    order = rng.permutation(10_000)
    want = float(np.sum(values[order].astype(np.float64)))
    assert _gather_ahead(values, order, 8) == want
    assert "llvm.prefetch" in next(iter(_gather_ahead.inspect_llvm().values()))


@njit
def _prefetch_2d(values):
    prefetch(values, 0)


def test_prefetch_takes_only_a_1d_array_and_an_integer_index():
    with pytest.raises(TypingError):
        _prefetch_2d(np.zeros((2, 2)))


def test_in_plain_python_a_prefetch_does_nothing():
    # NUMBA_DISABLE_JIT and the CUDA simulator run the kernels as Python.
    values = np.arange(4)
    assert prefetch(values, 2) is None
    assert _gather_ahead.py_func(values.astype(float), np.array([3, 1, 0, 2]), 1) == 6.0
