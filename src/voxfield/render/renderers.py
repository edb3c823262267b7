"""The reference and LOD renderers (EA thesis §5.1.1) over the primary-ray kernel."""

from __future__ import annotations

import contextlib
import time

import numba
import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.primary import render_pixels
from voxfield.progress import progress_bar
from voxfield.render.camera import Camera
from voxfield.render.result import RenderResult
from voxfield.svo.octree import Octree

RENDERERS = ("reference", "lod")


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


def trace_image(
    octree: Octree, camera: Camera, *, side: int, stop_level: int, cone_scale: float,
    seed: int, channel: str = "albedo", threads: int | None = None,
    progress: bool = False, label: str = "render",
) -> RenderResult:
    """Trace ``side²`` rays per pixel; the shared engine of the reference and LOD renderers."""
    if side < 1 or side > 16:
        raise VoxfieldError(f"samples per pixel side must be in 1..16, got {side}")
    colors = octree.channel(channel)
    h, w = camera.height, camera.width
    image = np.empty((h, w, 3), np.float32)
    depth = np.empty((h, w), np.float32)
    normal = np.empty((h, w, 3), np.float32)
    rays = np.empty((h, w), np.int32)
    hits = np.empty((h, w), np.int32)
    steps = np.empty((h, w), np.int64)
    lod = np.empty((h, w), np.int8)
    band = max(8, min(64, h // 16 or 1))
    cam = camera.params
    args = (octree.inner_nodes, octree.depth, stop_level, cone_scale, colors)
    flat = (image.reshape(-1, 3), depth.reshape(-1), normal.reshape(-1, 3), rays.reshape(-1),
            hits.reshape(-1), steps.reshape(-1), lod.reshape(-1))
    # An empty pixel list loads (or compiles) the kernel outside the timed region.
    render_pixels(cam, w, h, np.empty(0, np.int64), side, seed, *args, *flat)
    start = time.perf_counter()
    bar_options = {"total": h, "desc": label, "unit": "row", "enabled": progress}
    with thread_count(threads), progress_bar(**bar_options) as bar:
        for row0 in range(0, h, band):
            row1 = min(h, row0 + band)
            pixels = np.arange(row0 * w, row1 * w, dtype=np.int64)
            render_pixels(cam, w, h, pixels, side, seed, *args,
                          *(a[row0 * w : row1 * w] for a in flat))
            bar.update(row1 - row0)
    seconds = time.perf_counter() - start
    return RenderResult(image, depth, normal, rays, hits, steps, lod, seconds)


def render_reference(
    octree: Octree, camera: Camera, *, side: int = 4, seed: int = 0, channel: str = "albedo",
    threads: int | None = None, progress: bool = False,
) -> RenderResult:
    """Ground truth: ``side``×``side`` CMJ rays per pixel, all sampling LOD 0 (thesis: 4×4)."""
    result = trace_image(
        octree, camera, side=side, stop_level=octree.depth, cone_scale=0.0, seed=seed,
        channel=channel, threads=threads, progress=progress, label="reference",
    )
    result.renderer = "reference"
    result.params = {"samples_per_pixel": side * side, "seed": seed, "channel": channel}
    return result


def render_lod(
    octree: Octree, camera: Camera, *, lod: int | None = None, cone_scale: float = 1.0,
    side: int = 1, seed: int = 0, channel: str = "albedo",
    threads: int | None = None, progress: bool = False,
) -> RenderResult:
    """One ray per pixel sampling a fixed LOD, or (``lod=None``) the LOD whose nodes match the
    pixel cone: a node is sampled once it is no larger than ``cone_scale`` pixel footprints."""
    if lod is not None and not 0 <= lod <= octree.depth:
        raise VoxfieldError(f"LOD must be between 0 and {octree.depth} for this octree, got {lod}")
    if lod is None and not cone_scale > 0.0:
        raise VoxfieldError("cone LOD selection needs a positive cone scale")
    stop_level = octree.depth if lod is None else octree.depth - lod
    result = trace_image(
        octree, camera, side=side, stop_level=stop_level,
        cone_scale=cone_scale if lod is None else 0.0, seed=seed,
        channel=channel, threads=threads, progress=progress, label="lod",
    )
    result.renderer = "lod"
    result.params = {
        "lod": "cone" if lod is None else lod, "cone_scale": cone_scale,
        "samples_per_pixel": side * side, "seed": seed, "channel": channel,
    }
    return result


def render(octree: Octree, camera: Camera, renderer: str = "reference", **options) -> RenderResult:
    """Render with a renderer chosen by name (``reference`` or ``lod``)."""
    if renderer == "reference":
        return render_reference(octree, camera, **options)
    if renderer == "lod":
        return render_lod(octree, camera, **options)
    raise VoxfieldError(f"unknown renderer {renderer!r}; choose one of {', '.join(RENDERERS)}")
