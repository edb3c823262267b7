"""``kernels.scheduling.interleaved``: a permutation whose even split deals items in turn."""

import numba
import numpy as np
import pytest
from numba import njit, prange

from voxfield.kernels.scheduling import interleaved, interleaved_run, run_count


def _order(n: int, parts: int) -> np.ndarray:
    return np.array([interleaved(k, n, parts) for k in range(n)], np.int64)


@pytest.mark.parametrize("parts", [1, 2, 3, 4, 7])
@pytest.mark.parametrize("n", [0, 1, 2, 5, 8, 63, 64, 65, 1000])
def test_every_item_once(n, parts):
    assert np.array_equal(np.sort(_order(n, parts)), np.arange(n))


@pytest.mark.parametrize("parts", [2, 3, 4, 7])
@pytest.mark.parametrize("n", [7, 64, 65, 1001])
def test_each_run_of_an_even_split_is_one_residue_class_in_order(n, parts):
    """``np.array_split``'s runs (the longer ones first, as ``prange`` splits a range) each
    hold one residue class modulo ``parts``, ascending: every thread's share spans the range."""
    order = _order(n, parts)
    runs = np.array_split(np.arange(n), parts)
    for residue, run in enumerate(runs):
        items = order[run]
        assert np.all(items % parts == residue)
        assert np.all(np.diff(items) == parts)


def test_one_part_keeps_the_order():
    assert np.array_equal(_order(50, 1), np.arange(50))
    assert np.array_equal(_order(50, 0), np.arange(50))


@njit(parallel=True)
def _visit(n: int, parts: int, out: np.ndarray) -> None:
    for k in prange(n):
        out[interleaved(k, n, parts)] += 1


def test_inside_prange_with_an_unsigned_index():
    """A ``prange`` index mixed with signed counts once made Numba type the item as a float;
    the loop must compile and visit each item exactly once."""
    out = np.zeros(1000, np.int64)
    _visit(1000, numba.get_num_threads(), out)
    assert np.all(out == 1)


@pytest.mark.parametrize("parts", [1, 2, 3])
@pytest.mark.parametrize(("n", "size"), [(0, 4), (1, 4), (63, 64), (64, 64), (65, 64), (1000, 16)])
def test_runs_cover_every_item_once_in_whole_runs(n, size, parts):
    seen = np.zeros(n, np.int64)
    for k in range(run_count(n, size)):
        first, last = interleaved_run(k, n, size, parts)
        assert first % size == 0 and 0 < last - first <= size
        seen[first:last] += 1
    assert np.all(seen == 1)
