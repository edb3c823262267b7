"""How a render's threads claim their pixels (``kernels.primary.claim_chunk``): every pixel
once, in chunks of at most one tile, and each thread's chunks in strips of ``RUN_CHUNKS``
consecutive tiles, so two threads never store into the same cache lines of a row."""

import numpy as np
import pytest
from numba import njit, prange

from voxfield.kernels.primary import PIXEL_CHUNK, RUN_CHUNKS, claim_chunk, new_chunk_sums
from voxfield.kernels.scheduling import new_run_queue


@njit(parallel=True)
def _claim_every_chunk(n: int, workers: int, claims: np.ndarray, owner: np.ndarray,
                       chunk_of: np.ndarray) -> None:
    queue = new_run_queue()
    for worker in prange(workers):
        sums, tallies, run = new_chunk_sums()
        while True:
            first, last = claim_chunk(queue, n, sums, tallies, run)
            if first == last:
                break
            for i in range(first, last):
                claims[i] += 1
                owner[i] = worker
                chunk_of[i] = first


@pytest.mark.parametrize("workers", [1, 2, 3])
@pytest.mark.parametrize("n", [0, 1, PIXEL_CHUNK, PIXEL_CHUNK * RUN_CHUNKS + 1, 262_144 + 37])
def test_every_pixel_once_in_chunks_of_a_tile_and_strips_of_one_thread(n, workers):
    claims = np.zeros(n, np.int64)
    owner = np.full(n, -1, np.int64)
    chunk_of = np.full(n, -1, np.int64)
    _claim_every_chunk(n, workers, claims, owner, chunk_of)
    assert np.all(claims == 1)
    assert np.all(chunk_of == np.arange(n) // PIXEL_CHUNK * PIXEL_CHUNK)
    strip = PIXEL_CHUNK * RUN_CHUNKS
    for first in range(0, n, strip):
        assert len(set(owner[first:first + strip])) == 1  # one thread stores a strip


def test_a_claimed_chunk_starts_from_zeroed_sums():
    sums, tallies, run = new_chunk_sums()
    sums[:] = 5.0
    tallies[:] = 5
    first, last = claim_chunk(new_run_queue(), 100, sums, tallies, run)
    assert (first, last) == (0, min(100, PIXEL_CHUNK))
    assert np.all(sums == 0.0)
    assert np.all(tallies[:, :2] == 0) and np.all(tallies[:, 2] == 127)
