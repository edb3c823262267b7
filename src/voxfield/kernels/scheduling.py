"""Sharing a parallel loop's items out among the threads: dealt in turn, or claimed.

Numba's ``prange`` gives each thread one contiguous run of the iterations, whatever
``numba.set_parallel_chunksize`` says (with the OpenMP layer a loop whose first half costs
all the work takes as long on two threads as on one). Where the cost varies over the items
(an image whose upper rows are sky, a terrain with its mountains on one side) one thread
then idles while the other finishes. A loop that maps its ``prange`` index through
``interleaved`` hands thread ``t`` of ``parts`` the items ``t, t + parts, t + 2·parts, ...``
instead: each thread's share samples the whole range, so the threads finish together, and
neighbouring items still run side by side on the two threads, sharing the cache.

A loop whose threads each claim runs from a shared queue (``claim_run``) instead shares
the work as the threads are free: a thread that the machine slows down (another process on
its core) leaves its runs to the others. Renders take their pixel chunks that way.

Which thread runs an item never changes what the item computes: results stay the same for
any thread count.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic, overload


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


@njit(cache=True, nogil=True)
def new_run_queue() -> np.ndarray:
    """A queue of runs for ``claim_run``: the next unclaimed run, from 0."""
    return np.zeros(1, np.int64)


def fetch_add(counter: np.ndarray, amount: int) -> int:
    """``counter[0] += amount``, giving the value before: in one atomic step in compiled code
    (``_atomic_fetch_add``); this plain form serves runs with the JIT off."""
    before = int(counter[0])
    counter[0] += amount
    return before


@intrinsic
def _atomic_fetch_add(typingctx, counter, amount):
    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0]).data
        return builder.atomic_rmw("add", data, args[1], "monotonic")

    return types.int64(counter, types.int64), codegen


@overload(fetch_add)
def _compiled_fetch_add(counter, amount):
    return lambda counter, amount: _atomic_fetch_add(counter, amount)


@njit(cache=True, nogil=True)
def claim_run(queue: np.ndarray) -> int:
    """The next run of ``queue`` (``new_run_queue``) nobody has claimed, for this thread
    alone: threads that claim runs until they pass the last share the work as they are
    free, one run at a time, so a thread slowed by the machine (another process on its
    core) leaves its runs to the others instead of holding up the loop's end, which a fixed
    deal (``interleaved``) cannot do."""
    return fetch_add(queue, np.int64(1))


@njit(cache=True, nogil=True)
def claim_items(queue: np.ndarray, n: int, size: int) -> tuple[int, int]:
    """Items ``first..last-1`` of the next unclaimed run of ``size`` of the ``n`` items
    (``claim_run``); ``first == last`` once none is left."""
    first = min(claim_run(queue) * size, n)
    return first, min(n, first + size)
