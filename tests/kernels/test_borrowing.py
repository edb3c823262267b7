"""``kernels.borrowing``: helpers compiled without reference counting borrow their caller's
arrays, refuse to allocate, and the per-ray loops of every hot kernel are such helpers."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from numba.core.errors import TypingError

from voxfield.kernels import primary, ray_batch, sun_bake, surface_approach, upward_rays
from voxfield.kernels.borrowing import borrowing


@borrowing
def _scale_into(values, factor, out):
    for i in range(values.shape[0]):
        out[i] = values[i] * factor


@borrowing
def _allocates(n):
    return np.zeros(n).sum()


def test_a_borrowing_helper_works_on_its_callers_arrays_and_keeps_no_reference():
    values = np.arange(5.0)
    out = np.zeros(5)
    before = sys.getrefcount(values), sys.getrefcount(out)
    for _ in range(3):
        _scale_into(values, 2.0, out)
    assert np.array_equal(out, 2.0 * values)
    assert (sys.getrefcount(values), sys.getrefcount(out)) == before


def test_a_borrowing_helper_that_allocates_fails_to_compile_rather_than_leak():
    with pytest.raises(TypingError):
        _allocates(3)


@pytest.mark.parametrize("helper", [
    upward_rays.rising_ray_query,
    surface_approach.approach_surface,
    surface_approach.top_node_hit,
    sun_bake.sky_visibility,
    sun_bake.trace_shadow_queue,
    sun_bake.bake_block,
    primary.trace_chunk_over_columns,
    primary.trace_chunk_per_ray,
    ray_batch.trace_ray_chunk,
    ray_batch.occlude_ray_chunk,
], ids=lambda f: f.py_func.__name__)
def test_the_per_ray_loops_of_the_hot_kernels_borrow(helper):
    # With counting, every call updates the shared arrays' headers from every thread: the
    # walks lost 9-25 % to it (``kernels.borrowing``).
    assert helper.targetoptions.get("_nrt") is False
