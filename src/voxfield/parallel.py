"""Thread count and banded scheduling shared by every kernel driver (renders, bakes, probe
queries): results never depend on the thread count, so these only decide speed."""

from __future__ import annotations

import contextlib
import time

import numba

from voxfield.errors import VoxfieldError
from voxfield.progress import progress_bar


@contextlib.contextmanager
def thread_count(threads: int | None):
    """Run kernels on ``threads`` threads (None: all); results do not depend on it."""
    if threads is None:
        yield
        return
    if threads < 1:
        raise VoxfieldError(f"thread count must be at least 1, got {threads}")
    previous = numba.get_num_threads()
    numba.set_num_threads(min(int(threads), numba.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def run_in_bands(height: int, band, *, label: str, threads: int | None, progress: bool,
                 granule: int = 8) -> float:
    """Call ``band(rows)`` over bands of rows with a progress bar; returns the seconds spent.

    Bands hold whole multiples of ``granule`` rows (a pixel tile's height, so tiles never
    straddle bands). An empty first band loads (or compiles) the kernel outside the timed
    region.
    """
    band(slice(0, 0))
    rows = max(granule, min(64, height // 16 or 1)) // granule * granule
    start = time.perf_counter()
    options = {"total": height, "desc": label, "unit": "row", "enabled": progress}
    with thread_count(threads), progress_bar(**options) as bar:
        for row0 in range(0, height, rows):
            band(slice(row0, min(height, row0 + rows)))
            bar.update(min(height, row0 + rows) - row0)
    return time.perf_counter() - start
