"""Where primary rays are traced: the CPU cores (the default) or a CUDA GPU.

The GPU runs the CPU's own per-pixel code (``kernels.cuda_primary``), so a render differs
by device only in speed. The octree's arrays go to the GPU once and stay with the octree
(``Octree.derived``): frames after the first upload only the camera and the beam bounds.
The beam pass itself runs on the CPU; its bounds, and so every step count, are the CPU's.
"""

from __future__ import annotations

import importlib.util
import time

import numpy as np
from numba import config

from voxfield.errors import VoxfieldError
from voxfield.kernels import cuda_primary
from voxfield.render.result import RenderResult
from voxfield.svo.octree import Octree

DEVICES = ("cpu", "cuda")
#: Renderers that can run on CUDA so far (the error-aware one cannot yet).
CUDA_RENDERERS = ("reference", "lod", "adaptive")


def numba_cuda_installed() -> bool:
    """Whether numba-cuda (the ``cuda`` extra) is installed. Numba still ships a CUDA
    target of its own, deprecated, which sees a GPU as well but fails to compile the
    kernels (its CPU ``max`` overload does not type for the GPU)."""
    return importlib.util.find_spec("numba_cuda") is not None


def cuda_available() -> bool:
    """Whether Numba sees a CUDA GPU through numba-cuda (or its simulator, under
    ``NUMBA_ENABLE_CUDASIM=1``)."""
    if not (config.ENABLE_CUDASIM or numba_cuda_installed()):
        return False  # before Numba's own CUDA target loads, to no use
    try:
        # optional: numba.cuda loads only when a GPU is asked about
        from numba import cuda
    except ImportError:
        return False
    try:
        return bool(cuda.is_available())
    except Exception:  # a broken driver install reads as no GPU, not as a crash
        return False


def check_device(device: str, renderer: str | None = None) -> None:
    """A clear error for an unknown device, for CUDA without a GPU, and for a renderer that
    has no CUDA kernel yet."""
    if device not in DEVICES:
        raise VoxfieldError(f"unknown device {device!r}; use one of {', '.join(DEVICES)}")
    if device != "cuda":
        return
    if renderer is not None and renderer not in CUDA_RENDERERS:
        raise VoxfieldError(f"the {renderer} renderer runs on the CPU only; --device cuda "
                            f"serves {' and '.join(CUDA_RENDERERS)}")
    if not cuda_available():
        raise VoxfieldError("--device cuda: no CUDA GPU is visible here (it needs an NVIDIA "
                            "GPU, its driver and `pip install voxfield[cuda]`)")


def trace_image_cuda(
    octree: Octree, camera, *, side: int, stop_level: int, cone_scale: float, seed: int,
    channel: str, beam_bound: np.ndarray, block: int, threads: int | None = None,
    progress: bool = False, label: str = "render",
) -> RenderResult:
    """``render.primary.trace_image``'s pixels on the GPU: the same results, with
    ``seconds`` the kernel time (compilation and the first upload excluded). ``threads``,
    ``progress`` and ``label`` concern CPU renders: one kernel launch has no bands."""
    h, w = camera.height, camera.width
    buffers, seconds = trace_pixels_cuda(
        octree, camera, np.arange(h * w, dtype=np.int64), side=side, stop_level=stop_level,
        cone_scale=cone_scale, seed=seed, channel=channel, beam_bound=beam_bound, block=block)
    result = RenderResult.allocate(h, w)
    for host, values in zip(result.buffers(), buffers, strict=True):
        host.reshape(values.shape)[...] = values
    result.seconds = seconds
    return result


def trace_pixels_cuda(
    octree: Octree, camera, pixels: np.ndarray, *, side: int, stop_level: int,
    cone_scale: float, seed: int, channel: str, beam_bound: np.ndarray, block: int,
) -> tuple[tuple, float]:
    """The listed pixels (flat indices) on the GPU, as ``kernels.primary.render_pixels``
    traces them with ``out_base`` -1: flat host arrays in ``RenderResult.buffers`` order, one
    entry per listed pixel, and the kernel's seconds (compilation excluded)."""
    # optional: the CUDA target loads only when a GPU render is asked for
    from numba import cuda

    check_device("cuda")
    if octree.depth >= cuda_primary.MAX_LEVELS:
        raise VoxfieldError(f"octree depth {octree.depth} is deeper than the GPU kernel's "
                            f"{cuda_primary.MAX_LEVELS - 1} levels")
    nodes, colors, facing = octree.derived(("cuda", channel), lambda: tuple(
        cuda.to_device(np.ascontiguousarray(a))
        for a in (octree.inner_nodes, *octree.kernel_colours(channel))))
    cam = cuda.to_device(camera.params)
    bound = cuda.to_device(np.ascontiguousarray(beam_bound, np.float64))
    listed = cuda.to_device(np.ascontiguousarray(pixels, np.int64))
    outputs = cuda_primary.empty_outputs(len(pixels))
    kernel = cuda_primary.primary_kernel()
    before = (cam, camera.width, camera.height)
    after = (side, seed, nodes, octree.depth, stop_level, cone_scale, colors, facing, bound,
             block)
    kernel[1, 1](*before, listed[:0], *after, *outputs)
    cuda.synchronize()  # no pixels: compiles (or loads) the kernel outside the timing
    blocks, threads = cuda_primary.launch_shape(len(pixels))
    start = time.perf_counter()
    kernel[blocks, threads](*before, listed, *after, *outputs)
    cuda.synchronize()
    seconds = time.perf_counter() - start
    return tuple(device_array.copy_to_host() for device_array in outputs), seconds
