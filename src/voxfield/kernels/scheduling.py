"""Dealing a parallel loop's items out to the threads in turn.

Numba's ``prange`` gives each thread one contiguous run of the iterations, whatever
``numba.set_parallel_chunksize`` says (with the OpenMP layer a loop whose first half costs
all the work takes as long on two threads as on one). Where the cost varies over the items
(an image whose upper rows are sky, a terrain with its mountains on one side) one thread
then idles while the other finishes. A loop that maps its ``prange`` index through
``interleaved`` hands thread ``t`` of ``parts`` the items ``t, t + parts, t + 2·parts, ...``
instead: each thread's share samples the whole range, so the threads finish together, and
neighbouring items still run side by side on the two threads, sharing the cache.

Which thread runs an item never changes what the item computes: results stay the same for
any thread count.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def interleaved(k: int, n: int, parts: int) -> int:
    """The ``k``-th of ``0..n-1`` in the order ``0, parts, 2·parts, ..., 1, 1 + parts, ...``
    (a permutation of ``0..n-1``): an even split of ``0..n-1`` into ``parts`` runs, as
    ``prange`` makes it, gives each run one residue class modulo ``parts``."""
    # One integer type throughout: a ``prange`` index may be unsigned, and Numba widens a
    # mix of signed and unsigned integers to float.
    rank = np.int64(k)
    n = np.int64(n)
    parts = np.int64(parts)
    if parts <= 1:
        return rank
    residue = np.int64(0)
    while True:
        count = (n - residue + parts - 1) // parts  # items ≡ residue (mod parts)
        if rank < count:
            return rank * parts + residue
        rank -= count
        residue += 1


@njit(cache=True, nogil=True)
def run_count(n: int, size: int) -> int:
    """How many runs of ``size`` items cover ``n`` items: the length of the ``prange`` whose
    iterations ``interleaved_run`` maps to runs."""
    return (n + size - 1) // size


@njit(cache=True, nogil=True)
def interleaved_run(k: int, n: int, size: int, parts: int) -> tuple[int, int]:
    """Items ``first..last-1`` of the ``k``-th iteration of a ``prange`` over the
    ``run_count(n, size)`` runs of ``size`` items, the runs dealt to ``parts`` threads in
    turn (``interleaved``)."""
    first = interleaved(k, run_count(n, size), parts) * size
    return first, min(n, first + size)
