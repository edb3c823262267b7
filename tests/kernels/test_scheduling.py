"""``kernels.scheduling``: ``interleaved``, a permutation whose even split deals items in
turn, and ``claim_run``, a queue the threads take runs from as they are free."""

import numba
import numpy as np
import pytest
from numba import njit, prange

from voxfield.kernels.scheduling import (
    claim_items,
    claim_run,
    interleaved,
    interleaved_run,
    new_run_queue,
    run_count,
)


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


def test_claims_come_in_order_from_zero():
    queue = new_run_queue()
    assert [claim_run(queue) for _ in range(5)] == [0, 1, 2, 3, 4]


@njit(parallel=True)
def _claim_all(runs: int, workers: int, quitter: int, claimed: np.ndarray,
               taker: np.ndarray) -> None:
    """Workers claim runs until none is left; worker ``quitter`` stops after its first."""
    queue = new_run_queue()
    for worker in prange(workers):
        while True:
            k = claim_run(queue)
            if k >= runs:
                break
            claimed[k] += 1
            taker[k] = worker
            if worker == quitter:
                break


@pytest.mark.parametrize("workers", [1, 2, 3, 8])
@pytest.mark.parametrize("runs", [0, 1, 7, 1000])
def test_parallel_workers_claim_every_run_once(runs, workers):
    claimed = np.zeros(runs, np.int64)
    taker = np.full(runs, -1, np.int64)
    _claim_all(runs, workers, -1, claimed, taker)
    assert np.all(claimed == 1)


def test_runs_a_worker_leaves_go_to_the_others():
    """No run belongs to a thread in advance: a worker that stops early (a thread the machine
    slows down) leaves the rest of the work to the others, where a fixed deal loses its share."""
    runs = 1000
    claimed = np.zeros(runs, np.int64)
    taker = np.full(runs, -1, np.int64)
    _claim_all(runs, 4, 0, claimed, taker)
    assert np.all(claimed == 1)
    assert np.count_nonzero(taker == 0) <= 1


def test_claimed_items_come_in_whole_runs_and_end_empty():
    queue = new_run_queue()
    assert [claim_items(queue, 10, 4) for _ in range(4)] == [(0, 4), (4, 8), (8, 10), (10, 10)]
