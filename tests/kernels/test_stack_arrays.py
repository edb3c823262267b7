"""Stack matrices: arrays in the compiled caller's frame, for loops the compiler vectorises."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from voxfield.kernels.stack_arrays import stack_matrix


@njit
def _filled(out):
    scratch = stack_matrix(3, 5, np.int64)
    for i in range(3):
        for j in range(5):
            scratch[i, j] = i * 5 + j
    for j in range(5):
        out[j] = scratch[0, j] + scratch[1, j] + scratch[2, j]
    return scratch.shape[0], scratch.shape[1], scratch.strides[0], scratch.strides[1]


def test_a_stack_matrix_is_a_c_ordered_array_of_its_shape():
    out = np.zeros(5, np.int64)
    assert _filled(out) == (3, 5, 40, 8)
    np.testing.assert_array_equal(out, np.arange(15).reshape(3, 5).sum(axis=0))


@njit
def _nested_sums(depth, out):
    """Each call's matrix is its own: a call that recurses finds its values unchanged."""
    mine = stack_matrix(1, 4, np.float64)
    for j in range(4):
        mine[0, j] = depth + j * 0.5
    if depth > 0:
        _nested_sums(depth - 1, out)
    for j in range(4):
        out[depth, j] = mine[0, j]


def test_every_call_has_its_own_matrix():
    out = np.zeros((4, 4))
    _nested_sums(3, out)
    np.testing.assert_array_equal(out, np.arange(4)[:, None] + np.arange(4)[None, :] * 0.5)


@njit
def _sized_at_run_time(rows):
    return stack_matrix(rows, 2, np.int64).shape[0]


def test_a_size_known_only_at_run_time_is_refused():
    with pytest.raises(TypingError):
        _sized_at_run_time(3)
