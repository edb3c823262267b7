"""The reference and LOD renderers (EA thesis §5.1.1) over the primary-ray kernel."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numba
import numpy as np

from voxfield.checks import flag, integer_in, real_number, seed_value
from voxfield.errors import VoxfieldError
from voxfield.kernels.bundles import BeamBounds, PixelOutputs, octree_view
from voxfield.kernels.primary import render_pixels
from voxfield.parallel import run_in_bands, thread_count, threads_for
from voxfield.render.beam import pixel_start_bounds
from voxfield.render.camera import Camera, check_camera
from voxfield.render.device import check_device, trace_image_cuda
from voxfield.render.result import RenderResult
from voxfield.svo.column_tops import no_column_tops, octree_column_tops
from voxfield.svo.octree import Octree, check_octree


@dataclass(frozen=True)
class ReferenceOptions:
    """The ground-truth renderer's parameters (EA §5.1.1)."""

    side: int = field(default=4, metadata={
        "help": "side of the CMJ sample grid per pixel (default 4 → 16 rays, as the thesis)",
        "flag": "--spp-side", "type": "positive"})


@dataclass(frozen=True)
class LodOptions:
    """The fixed-LOD / cone-LOD renderer's parameters (EA §5.1.1)."""

    lod: int | None = field(default=None, metadata={
        "help": "a fixed LOD (0 = voxels) or 'cone' (default: chosen from the pixel footprint)",
        "type": "lod"})
    cone_scale: float = field(default=1.0, metadata={
        "help": "cone mode: node size accepted per pixel footprint (default 1)",
        "read_when": (lambda options: options.lod is None, "--lod cone")})
    side: int = field(default=1, metadata={
        "help": "side of the CMJ sample grid per pixel (default 1)", "cli": False})


def trace_image(
    octree: Octree, camera: Camera, *, side: int, stop_level: int, cone_scale: float,
    seed: int, channel: str = "albedo", threads: int | None = None,
    progress: bool = False, label: str = "render", beam: bool = True, device: str = "cpu",
    columns: bool = True,
) -> RenderResult:
    """Trace ``side²`` rays per pixel; the shared engine of the reference and LOD renderers.

    ``beam`` starts the rays of each pixel block at its beam bound (``render.beam``): the
    same image, fewer steps. Rays over the column-top pyramid start at their pixel's bound
    from the pyramid drawn into the image instead
    (``render.beam.raster_beam``), where the camera allows it. ``columns`` lets rays cross
    the air in the octree's column-top pyramid first (``kernels.surface_approach`` at a
    fixed level, ``kernels.cone_walk`` with a cone; built once per structure): the same
    image, in less time; the steps then count the pyramid's cells.
    ``device="cuda"`` traces the pixels on a GPU (``render.device``), with the same image
    and the octree's steps alone.
    """
    side = integer_in(side, "samples per pixel side", 1, 16)
    seed = seed_value(seed)
    # Checked, not taken for their truth: beam="no" rendered with the beam on.
    beam, columns, progress = (flag(value, name) for value, name in (
        (beam, "beam"), (columns, "columns"), (progress, "progress")))
    check_device(device)
    threads = threads_for(camera.width * camera.height * side * side, threads)
    drawn = beam and device == "cpu" and columns
    with thread_count(threads):
        bounds = pixel_start_bounds(
            octree, camera, octree_column_tops(octree) if drawn else no_column_tops(),
            stop_level=stop_level, cone_scale=cone_scale, side=side, whole_pixel=side > 1,
            enabled=beam)
    if device == "cuda":
        result = trace_image_cuda(
            octree, camera, side=side, stop_level=stop_level, cone_scale=cone_scale,
            seed=seed, channel=channel, beam_bound=bounds.bound, block=bounds.block,
            threads=threads, progress=progress, label=label)
    else:
        result = trace_image_cpu(
            octree, camera, side=side, stop_level=stop_level, cone_scale=cone_scale,
            seed=seed, channel=channel, beam_bound=bounds.bound, block=bounds.block,
            threads=threads, progress=progress, label=label, columns=columns)
    result.seconds += bounds.seconds
    result.steps += bounds.image_steps(camera.height, camera.width)
    return result


def trace_image_cpu(
    octree: Octree, camera: Camera, *, side: int, stop_level: int, cone_scale: float,
    seed: int, channel: str, beam_bound: np.ndarray, block: int, threads: int | None,
    progress: bool, label: str, columns: bool = True,
) -> RenderResult:
    """``trace_image``'s pixels on the CPU cores, in bands of tile rows (progress, Ctrl-C)."""
    colors, facing = octree.kernel_colours(channel)
    h, w = camera.height, camera.width
    cam = camera.params
    result = RenderResult.allocate(h, w)
    view = octree_view(octree.inner_nodes, octree.depth, colors, facing)
    beam = BeamBounds(beam_bound, block)
    pyramid = pixel_columns(octree, columns, side, beam_bound, cone_scale)
    order = tile_order(h, w)

    def band(rows: slice) -> None:
        pixels = order[rows.start * w : rows.stop * w]
        out = PixelOutputs(*(b.reshape(len(pixels), *b.shape[2:])
                             for b in result.buffers(rows)))
        render_pixels(cam, w, h, pixels, rows.start * w, side, seed, view, stop_level,
                      cone_scale, beam, out, pyramid, numba.get_num_threads())

    result.seconds = run_in_bands(h, band, label=label, threads=threads, progress=progress,
                                  granule=TILE, rays_per_row=w * side * side)
    return result


def pixel_columns(octree: Octree, columns: bool, side: int, beam_bound: np.ndarray,
                  cone_scale: float = 0.0):
    """The column-top pyramid ``render_pixels`` should walk, or none: supersampled rays at a
    fixed level from the camera (no beam bound: probe cameras, ``beam=False``) go faster in
    packets through the octree alone (mountain terrain, 16 rays a pixel: packets 1.1-1.3×
    the walk without a beam, the walk 1.1-1.2× packets with one). Cone-LOD rays walk it as
    their cone allows (``kernels.cone_walk``)."""
    if not columns or (cone_scale == 0.0 and side > 1 and not np.any(beam_bound > 0)):
        return no_column_tops()
    return octree_column_tops(octree)


#: Side of the square pixel tiles traced one after another, one tile per thread's chunk.
TILE = 8


def tile_order(height: int, width: int) -> np.ndarray:
    """Flat pixel indices in ``TILE``×``TILE`` tiles (tiles in row-major order, the pixels
    inside each in Morton order): neighbouring rays run one after another and share cached
    nodes and restarts, and a packet's consecutive pixels are 2×2 quads, not strips. Bands of
    whole tile rows are contiguous runs of it."""
    return _tile_order(height, width).copy()


@functools.lru_cache(maxsize=8)
def _tile_order(height: int, width: int) -> np.ndarray:
    """The sort behind ``tile_order``, once per image size (it costs more than a copy)."""
    rows, cols = np.divmod(np.arange(height * width, dtype=np.int64), width)
    inside = np.zeros_like(rows)
    for bit in range(TILE.bit_length() - 1):  # Morton order inside a tile
        inside |= ((cols >> bit) & 1) << (2 * bit) | ((rows >> bit) & 1) << (2 * bit + 1)
    key = (rows // TILE * (-(-width // TILE)) + cols // TILE) * TILE * TILE + inside
    return np.argsort(key, kind="stable")


def cone_scale_value(cone_scale) -> float:
    """A cone LOD's node size per pixel footprint: a finite number above 0."""
    scale = real_number(cone_scale, "cone scale")
    if not scale > 0.0:
        raise VoxfieldError(f"cone LOD selection needs a positive cone scale, got {cone_scale}")
    return scale


def render_reference(
    octree: Octree, camera: Camera, *, side: int = ReferenceOptions.side, seed: int = 0,
    channel: str = "albedo",
    threads: int | None = None, progress: bool = False, beam: bool = True,
    device: str = "cpu", columns: bool = True,
) -> RenderResult:
    """Ground truth: ``side``×``side`` CMJ rays per pixel, all sampling LOD 0 (thesis: 4×4).
    ``beam=False`` starts every ray at the camera (same image, more steps); ``columns``
    crosses the air in the column-top pyramid first (``trace_image``; same image);
    ``device`` is ``"cpu"`` or ``"cuda"`` (same image)."""
    check_octree(octree, "render_reference")
    check_camera(camera, "render_reference")
    result = trace_image(
        octree, camera, side=side, stop_level=octree.depth, cone_scale=0.0, seed=seed,
        channel=channel, threads=threads, progress=progress, label="reference", beam=beam,
        device=device, columns=columns,
    )
    result.renderer = "reference"
    result.params = {"samples_per_pixel": side * side, "seed": seed, "channel": channel}
    return result


def render_lod(
    octree: Octree, camera: Camera, *, lod: int | None = LodOptions.lod,
    cone_scale: float = LodOptions.cone_scale, side: int = LodOptions.side, seed: int = 0,
    channel: str = "albedo",
    threads: int | None = None, progress: bool = False, beam: bool = True,
    device: str = "cpu", columns: bool = True,
) -> RenderResult:
    """One ray per pixel sampling a fixed LOD, or (``lod=None``) the LOD whose nodes match the
    pixel cone: a node is sampled once it is no larger than ``cone_scale`` pixel footprints.
    ``beam=False`` starts every ray at the camera (same image, more steps); ``columns``
    crosses the air in the column-top pyramid first, at a fixed LOD or as the cone allows
    (``trace_image``; same image); ``device`` is ``"cpu"`` or ``"cuda"`` (same image)."""
    check_octree(octree, "render_lod")
    check_camera(camera, "render_lod")
    if lod is not None:
        lod = integer_in(lod, "LOD", 0, octree.depth)
    else:
        cone_scale = cone_scale_value(cone_scale)
    stop_level = octree.depth if lod is None else octree.depth - lod
    result = trace_image(
        octree, camera, side=side, stop_level=stop_level,
        cone_scale=cone_scale if lod is None else 0.0, seed=seed,
        channel=channel, threads=threads, progress=progress, label="lod", beam=beam,
        device=device, columns=columns,
    )
    result.renderer = "lod"
    result.params = {
        "lod": "cone" if lod is None else lod, "cone_scale": cone_scale,
        "samples_per_pixel": side * side, "seed": seed, "channel": channel,
    }
    return result
