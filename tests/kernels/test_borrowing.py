"""``kernels.borrowing``: helpers compiled without reference counting borrow their caller's
arrays, refuse to allocate, and the per-ray loops of every hot kernel are such helpers."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from voxfield.kernels import (
    cone_walk,
    error_aware,
    lane_walk,
    primary,
    ray_batch,
    rising_lanes,
    sun_bake,
    surface_approach,
    upward_rays,
)
from voxfield.kernels.borrowing import borrowing


@njit(nogil=True)
def _scaled(values, factor, out, i):
    out[i] = values[i] * factor
    return out[i]


def _scale(values, factor, out):
    total = 0.0
    for i in range(values.shape[0]):
        total += _scaled(values, factor, out, i)
    return total


# The same function compiled both ways.
_scale_borrowed = borrowing(_scale, cache=False)
_scale_counted = njit(nogil=True)(_scale)


@borrowing(cache=False)
def _allocates(n):
    return np.zeros(n).sum()


def _reference_count_calls(function) -> int:
    llvm = "\n".join(function.inspect_llvm().values())
    return sum(line.count("@NRT_incref") + line.count("@NRT_decref")
               for line in llvm.splitlines() if "call" in line)


def test_a_borrowing_helper_works_on_its_callers_arrays_without_counting_references():
    values = np.arange(5.0)
    out = np.zeros(5)
    assert _scale_borrowed(values, 2.0, out) == _scale_counted(values, 2.0, out) == 20.0
    assert np.array_equal(out, 2.0 * values)
    assert _reference_count_calls(_scale_counted) > 0  # what plain njit does
    assert _reference_count_calls(_scale_borrowed) == 0


def test_a_borrowing_helper_that_allocates_fails_to_compile_rather_than_leak():
    with pytest.raises(TypingError):
        _allocates(3)


@pytest.mark.parametrize("helper", [
    upward_rays.rising_ray_query,
    surface_approach.walk_to_surface,
    surface_approach.walk_to_voxels,
    surface_approach.finish_in_octree,
    cone_walk.walk_cone_over_columns,
    cone_walk.trace_cone_over_columns,
    primary.trace_chunk_cone_over_columns,
    primary.trace_cone_batch,
    lane_walk.walk_to_voxels_in_lanes,
    lane_walk.walk_to_nodes_in_lanes,
    lane_walk.walk_queue_in_lanes,
    rising_lanes.walk_rising_rays,
    rising_lanes.walk_rising_in_lanes,
    sun_bake.draw_sky_rays,
    sun_bake.trace_sky_queue,
    sun_bake.trace_shadow_queue,
    sun_bake.bake_block,
    primary.trace_chunk_over_columns,
    primary.trace_chunk_per_ray,
    primary.hit_ray_batch,
    ray_batch.trace_ray_chunk,
    ray_batch.trace_run_in_lanes,
    ray_batch.occlude_ray_chunk,
    ray_batch.occlude_run_in_lanes,
    error_aware.trace_pixel_chunk,
    error_aware.trace_records,
    error_aware.record_batch,
    error_aware.refine_records,
    error_aware.add_chunk_samples,
], ids=lambda f: f.py_func.__name__)
def test_the_per_ray_loops_of_the_hot_kernels_borrow(helper):
    # With counting, every call updates the shared arrays' headers from every thread: the
    # walks lost 9-25 % to it (``kernels.borrowing``).
    assert helper.targetoptions.get("_nrt") is False
