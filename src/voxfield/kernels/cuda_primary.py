"""The primary-ray kernel on CUDA: one GPU thread per pixel, the CPU's own per-pixel code.

Why one source: the thread body calls ``kernels.primary.trace_pixel`` (which calls
``trace_ray``, the CMJ sampler, the camera and the colour lookups) and ``store_sums``,
plain ``@njit`` functions that Numba compiles for the GPU as device functions. Hits, times,
normals, colours and step counts are therefore those of the CPU renderer, bit for bit; only
the scratch differs: per-thread local arrays instead of heap arrays.

``numba.cuda`` (the ``numba-cuda`` package on a GPU machine, Numba's own simulator under
``NUMBA_ENABLE_CUDASIM=1``) loads the first time a kernel is asked for, never on the CPU path.
"""

from __future__ import annotations

import functools
import sys

import numpy as np
from numba import types

from voxfield.kernels.camera_rays import pixel_cone
from voxfield.kernels.primary import store_sums, trace_pixel

#: Octree levels a thread's local traversal stack holds (a compile-time size on CUDA): an
#: octree of depth up to ``MAX_LEVELS - 1``, a 2³¹-voxel-wide world.
MAX_LEVELS = 32
#: Threads per block: a multiple of the 32-thread warp.
THREADS_PER_BLOCK = 128


#: ``numba.cuda``, bound by ``jit_for_gpu`` when the kernel is first asked for.
cuda = None


def jit_for_gpu(module, function):
    """``numba.cuda.jit(function)``, with ``module.cuda`` bound first: a kernel reads ``cuda``
    as a global of its module, which is what Numba's simulator swaps its own module in for."""
    # optional: numba.cuda loads only when a GPU kernel is asked for
    from numba import cuda as numba_cuda

    module.cuda = numba_cuda
    return numba_cuda.jit(function)


@functools.cache
def primary_kernel():
    """The CUDA kernel, compiled on its first launch (one per process)."""
    return jit_for_gpu(sys.modules[__name__], _render_pixels_cuda)


def _render_pixels_cuda(
    cam, width, height, pixels, side, seed, inner_nodes, depth, stop_level, cone_scale,
    colors, facing, beam_bound, block,
    out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod,
):
    """Pixel ``pixels[cuda.grid(1)]`` (a flat index) into entry ``cuda.grid(1)`` of the
    ``out_*`` arrays, as ``kernels.primary.render_pixels`` traces it with the scalar loop."""
    entry = cuda.grid(1)
    if entry >= pixels.shape[0]:
        return
    pixel = pixels[entry]
    stack = cuda.local.array(MAX_LEVELS, types.int64)
    path = cuda.local.array(12, types.int64)
    start_stacks = cuda.local.array((2, MAX_LEVELS), types.int64)
    for k in range(12):
        path[k] = -1
    sums = cuda.local.array((1, 7), types.float64)
    tallies = cuda.local.array((1, 3), types.int64)
    for k in range(7):
        sums[0, k] = 0.0
    tallies[0, 0] = 0
    tallies[0, 1] = 0
    tallies[0, 2] = 127
    radius, spread = pixel_cone(cam, height)
    radius *= cone_scale / side
    spread *= cone_scale / side
    trace_pixel(cam, width, height, pixel, side, seed, inner_nodes, depth, stop_level,
                radius, spread, colors, facing, beam_bound, block,
                (stack, path, start_stacks), sums, tallies, 0)
    store_sums(out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod,
               entry, sums, tallies, 0, side * side)


def launch_shape(pixels: int) -> tuple[int, int]:
    """(blocks, threads per block) covering ``pixels`` threads."""
    return max(1, -(-pixels // THREADS_PER_BLOCK)), THREADS_PER_BLOCK


def empty_outputs(pixels: int) -> tuple:
    """Device arrays for the kernel's flat per-pixel outputs (``RenderResult.buffers``
    order and dtypes)."""
    # optional: numba.cuda loads only when a GPU render is asked for
    from numba import cuda

    return (cuda.device_array((pixels, 3), np.float32), cuda.device_array(pixels, np.float32),
            cuda.device_array((pixels, 3), np.float32), cuda.device_array(pixels, np.int32),
            cuda.device_array(pixels, np.int32), cuda.device_array(pixels, np.int64),
            cuda.device_array(pixels, np.int8))
