"""``parallel.run_in_bands``: every row once, in order, in bands of whole tiles that hold
enough rays to be worth a kernel call; ``threads_for``: small jobs on one thread."""

import pytest

from voxfield import parallel
from voxfield.errors import VoxfieldError
from voxfield.parallel import (
    BAND_RAYS,
    MIN_PARALLEL_RAYS,
    band_rows,
    run_in_bands,
    thread_count,
    threads_for,
)
from voxfield.render import orbit_camera, ray_query, render_lod, render_reference
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree


def _bands(height: int, granule: int, rays_per_row: int) -> list[slice]:
    seen = []
    run_in_bands(height, seen.append, label="test", threads=1, progress=False,
                 granule=granule, rays_per_row=rays_per_row)
    return seen


@pytest.mark.parametrize("height", [1, 7, 8, 100, 512, 4096])
@pytest.mark.parametrize("granule", [1, 8])
@pytest.mark.parametrize("rays_per_row", [0, 1, 512, 512 * 16, BAND_RAYS * 2])
def test_every_row_once_in_order_in_whole_tiles(height, granule, rays_per_row):
    bands = _bands(height, granule, rays_per_row)
    assert bands[0] == slice(0, 0)  # the kernel loads outside the timing
    rows = [r for band in bands[1:] for r in range(band.start, band.stop)]
    assert rows == list(range(height))
    for band in bands[1:-1]:
        assert (band.stop - band.start) % granule == 0


def test_timed_bands_start_small_and_follow_the_cost_of_a_row(monkeypatch):
    # a row costs 0.1 s until row 64, then 0.01 s: bands of about half a second follow it,
    # whole granules, every row once, never more than the untimed band
    clock = [0.0]
    monkeypatch.setattr(parallel.time, "perf_counter", lambda: clock[0])
    seen = []

    def band(rows):
        seen.append(rows)
        clock[0] += sum(0.1 if r < 64 else 0.01 for r in range(rows.start, rows.stop))

    run_in_bands(512, band, label="test", threads=1, progress=False, granule=4,
                 seconds_per_band=0.5)
    sizes = [b.stop - b.start for b in seen[1:]]
    assert sizes[0] == 4 and all(s % 4 == 0 for s in sizes)
    assert [r for b in seen[1:] for r in range(b.start, b.stop)] == list(range(512))
    slow = [s for b, s in zip(seen[1:], sizes, strict=True) if b.stop <= 64]
    assert slow[1:] == [4] * (len(slow) - 1)  # 0.4 s for 4 rows: the 0.5 s rounds down
    assert max(sizes) == band_rows(512, 4)  # cheap rows: capped at the untimed band


def test_a_small_image_is_one_call_and_a_large_one_is_cut_by_rays():
    # 512² at one ray a pixel: 2^18 rays, a quarter of a band's worth.
    assert len(_bands(512, 8, 512)) - 1 == 1
    # 16 rays a pixel: 2^22 rays, four bands of 2^20.
    bands = _bands(512, 8, 512 * 16)[1:]
    assert len(bands) == 4
    assert all((b.stop - b.start) * 512 * 16 >= BAND_RAYS for b in bands)


def test_without_a_ray_count_bands_are_a_sixteenth_of_the_image():
    assert band_rows(512, 8) == 32
    assert band_rows(4096, 8) == 64
    assert band_rows(20, 8) == 8
    # A row that alone exceeds the budget keeps the sixteenth.
    assert band_rows(512, 8, BAND_RAYS * 4) == 32


def test_a_job_below_the_parallel_size_runs_on_one_thread():
    assert threads_for(MIN_PARALLEL_RAYS - 1, None) == 1
    assert threads_for(MIN_PARALLEL_RAYS - 1, 2) == 1
    assert threads_for(0, None) == 1
    assert threads_for(MIN_PARALLEL_RAYS, None) is None  # every thread, as before
    assert threads_for(MIN_PARALLEL_RAYS, 2) == 2


@pytest.mark.parametrize("rays", [1, MIN_PARALLEL_RAYS])
@pytest.mark.parametrize("threads", [0, -1, 1.5, "2", True])
def test_an_impossible_thread_count_is_refused_whatever_the_job(rays, threads):
    with pytest.raises(VoxfieldError, match="thread count must be an integer"):
        threads_for(rays, threads)
    with pytest.raises(VoxfieldError, match="thread count must be an integer"):
        with thread_count(threads):
            pass


@pytest.mark.parametrize("size, one_thread", [(8, True), (64, False)])
def test_renders_and_queries_of_few_rays_launch_their_kernels_on_one_thread(
        monkeypatch, size, one_thread):
    octree = build_octree(pillars(16))
    camera = orbit_camera(*octree.voxel_bounds, size=size)
    origins, dirs = camera.rays()
    counts = []  # the thread counts set for kernels (none: every thread, the default)
    monkeypatch.setattr(parallel, "use_threads_in_this_thread", counts.append)
    render_reference(octree, camera, side=1)
    render_lod(octree, camera, lod=1)
    ray_query.trace(octree, origins, dirs)
    if one_thread:  # 64 rays each
        assert counts and set(counts) == {1}
    else:  # 4,096 rays each
        assert counts == []
