"""Thread count and banded scheduling shared by every kernel driver (renders, bakes, probe
queries): results never depend on the thread count, so these only decide speed."""

from __future__ import annotations

import contextlib
import time

import numba

from voxfield.checks import integer_in
from voxfield.progress import progress_bar

#: Fewest rays (pixels times their samples, or queries) a job spreads over more than one
#: thread. A parallel region's threads meet at its end, so a region waits for a thread that
#: another process holds off its core: serial bakes of 16×16 probes took 1.5-7 ms a probe
#: two at a time on two cores, and 41-139 ms beside a third busy process, against 0.8-0.9
#: and 0.8-2.9 ms on one thread each. Alone on a quiet machine two threads bake 8×8 probes
#: no faster (0.51 against 0.49 ms), 16×16 ones 1.1× as fast (0.70 against 0.79 ms) and
#: 32×32 ones 1.25× (0.99 against 1.25 ms): one thread below about a thousand rays costs
#: little there and keeps small jobs from stalling beside others.
MIN_PARALLEL_RAYS = 1024


def threads_for(rays: int, threads: int | None) -> int | None:
    """The thread count for a job of ``rays`` rays: one below ``MIN_PARALLEL_RAYS``, else
    ``threads`` (None: all). Results do not depend on it."""
    threads = _checked_threads(threads)
    return 1 if rays < MIN_PARALLEL_RAYS else threads


def _checked_threads(threads) -> int | None:
    return None if threads is None else integer_in(threads, "thread count", 1)


@contextlib.contextmanager
def thread_count(threads: int | None):
    """Run kernels on ``threads`` threads (None: all); results do not depend on it."""
    threads = _checked_threads(threads)
    if threads is None:
        yield
        return
    previous = numba.get_num_threads()
    use_threads_in_this_thread(threads)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def use_threads_in_this_thread(threads: int | None) -> None:
    """From now on, kernels this Python thread launches run on ``threads`` threads (None:
    leave Numba's default). Numba's count is per Python thread, and a worker thread that
    launched its kernels on every core paid for it: a parallel region started from a thread
    other than the main one took 70 µs to launch on two cores, against 1 µs on one thread,
    which made a bake of small probes on two worker threads 2.6× slower than serial."""
    if threads is not None:
        numba.set_num_threads(min(int(threads), numba.config.NUMBA_NUM_THREADS))


#: Rays a band holds at least when its caller says how many a row casts: each band is a
#: kernel call whose threads meet at its end, and a render of a 512² image in 16 bands took
#: 0.97-1.11× the time of one call, 1.05× typically (mountain terrain, one ray a pixel,
#: medians of alternating runs). 2^20 rays take a tenth of a second or more, often enough
#: for a progress bar and for Ctrl-C.
BAND_RAYS = 1 << 20


def band_rows(height: int, granule: int = 8, rays_per_row: int = 0) -> int:
    """Rows per band: a sixteenth of the image (8 to 64 rows), or more where that holds
    fewer than ``BAND_RAYS`` of ``rays_per_row`` rays a row (0: unknown), in whole
    multiples of ``granule``."""
    rows = max(granule, min(64, height // 16 or 1)) // granule * granule
    if rays_per_row > 0:
        wanted = min(height, -(-BAND_RAYS // rays_per_row))
        rows = max(rows, -(-wanted // granule) * granule)
    return rows


def run_in_bands(height: int, band, *, label: str, threads: int | None, progress: bool,
                 granule: int = 8, rays_per_row: int = 0,
                 seconds_per_band: float | None = None) -> float:
    """Call ``band(rows)`` over bands of rows (``band_rows``) with a progress bar; returns
    the seconds spent.

    Bands hold whole multiples of ``granule`` rows (a pixel tile's height, so tiles never
    straddle bands). An empty first band loads (or compiles) the kernel outside the timed
    region. With ``seconds_per_band`` (for work whose cost a row cannot be told in
    advance, and whose rows do not depend on how they are banded) the first band is one
    granule and each next one sized to take about that long, up to ``band_rows``: Ctrl-C,
    heard between bands, is heard that soon (a 1024² light-field march took 36 s a band).
    """
    most = band_rows(height, granule, rays_per_row)
    rows = granule if seconds_per_band else most
    options = {"total": height, "desc": label, "unit": "row", "enabled": progress}
    with thread_count(threads), progress_bar(**options) as bar:
        band(slice(0, 0))
        start = time.perf_counter()
        row0 = 0
        while row0 < height:
            row1 = min(height, row0 + rows)
            began = time.perf_counter()
            band(slice(row0, row1))
            bar.update(row1 - row0)
            if seconds_per_band:
                took = max(time.perf_counter() - began, 1e-6)
                scaled = int((row1 - row0) * seconds_per_band / took) // granule * granule
                rows = min(most, max(granule, scaled))
            row0 = row1
    return time.perf_counter() - start
