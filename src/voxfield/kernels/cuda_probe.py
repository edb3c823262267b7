"""The light-field trace on CUDA: one GPU thread per ray, the CPU's own per-ray code.

The thread body is ``kernels.probe_multi.answer_ray`` (the cage walk, the marchers, the hit's
colour probe and its bilinear read), plain ``@njit`` code that Numba compiles for the GPU as
device functions, so kinds, times, colours, probes and fetch counts equal the CPU's. Only
the scratch differs: per-thread local arrays instead of heap arrays.
"""

from __future__ import annotations

import functools
import sys

from numba import types

from voxfield.kernels.cuda_primary import jit_for_gpu
from voxfield.kernels.probe_multi import (
    MAX_PROBE_TRACES,
    RING_SIZE,
    LightFieldOutputs,
    ProbeField,
    RayBatch,
    TraceModes,
    answer_ray,
)

#: ``numba.cuda``, bound by ``jit_for_gpu`` when the kernel is first asked for.
cuda = None


@functools.cache
def probe_kernel():
    """The CUDA kernel, compiled on its first launch (one per process)."""
    return jit_for_gpu(sys.modules[__name__], _trace_light_field_cuda)


def _trace_light_field_cuda(
    marcher, eps_mode, ordering, fallback, params, positions, enabled, mips, mip_offsets,
    mip_sizes, normals, radiance, radiance_bordered, distance_bordered, resolution,
    grid_origin, grid_spacing, grid_counts, origins, dirs, tmin, tmax, tolerance,
    out_kind, out_t, out_radiance, out_normal, out_distance, out_probe, out_tried,
    out_fetches, out_steps,
):
    """Ray ``cuda.grid(1)`` as ``kernels.probe_multi.trace_light_field_rays`` answers it.
    (A launch passes flat arrays; the bundles ``answer_ray`` takes are built here.)"""
    i = cuda.grid(1)
    if i >= origins.shape[0]:
        return
    scratch = (cuda.local.array(8, types.int64), cuda.local.array(8, types.int64),
               cuda.local.array(MAX_PROBE_TRACES, types.int64),
               cuda.local.array(MAX_PROBE_TRACES, types.float64),
               cuda.local.array(RING_SIZE, types.int64),
               cuda.local.array(RING_SIZE, types.float64))
    field = ProbeField(positions, enabled, mips, mip_offsets, mip_sizes, normals, radiance,
                       radiance_bordered, distance_bordered, resolution, grid_origin,
                       grid_spacing, grid_counts)
    out = LightFieldOutputs(out_kind, out_t, out_radiance, out_normal, out_distance,
                            out_probe, out_tried, out_fetches, out_steps)
    answer_ray(i, TraceModes(marcher, eps_mode, ordering, fallback, params), field,
               RayBatch(origins, dirs, tmin, tmax), out, tolerance, scratch)
