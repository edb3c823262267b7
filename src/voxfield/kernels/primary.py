"""Primary-ray kernels: supersampled, counted, LOD-limited tracing of pixels and of ray batches."""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from voxfield.kernels.beam import start_distance
from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.bundles import BeamBounds, OctreeView, PixelOutputs, view_colours
from voxfield.kernels.camera_rays import camera_ray, pixel_cone
from voxfield.kernels.cone_walk import (
    prefetch_cone_landing,
    settle_cone_walk,
    walk_cone_over_columns,
)
from voxfield.kernels.facing_colour import prefetch_seen, seen_rgb
from voxfield.kernels.lane_walk import (
    LANE_WALK_PAYS,
    SLOTS,
    land_walks,
    new_walk_rows,
    record_landing,
    record_walk,
    walk_of,
    walk_to_nodes_in_lanes,
    walk_to_voxels_in_lanes,
)
from voxfield.kernels.packet_traversal import PACKET_RAYS, new_packet_scratch, trace_packet
from voxfield.kernels.sampling import (
    cmj_sample,
    cmj_sample_in,
    cmj_strata,
    new_cmj_strata,
    pixel_pattern,
)
from voxfield.kernels.scheduling import claim_items, new_run_queue
from voxfield.kernels.surface_approach import (
    FROM_CAMERA,
    HANDED_OVER,
    settle_walk,
    walk_plan,
    walk_primary_over_columns,
)
from voxfield.kernels.traversal import MISS, new_scratch, trace_ray


@njit(cache=True, nogil=True)
def normal_from_code(code: int) -> tuple[float, float, float]:
    if code < 0:
        return 0.0, 0.0, 0.0
    sign = -1.0 if code % 2 == 0 else 1.0
    axis = code // 2
    return (sign if axis == 0 else 0.0), (sign if axis == 1 else 0.0), (sign if axis == 2 else 0.0)


@njit(cache=True, nogil=True)
def store_pixel(
    out_color: np.ndarray, out_depth: np.ndarray, out_normal: np.ndarray,
    out_rays: np.ndarray, out_hits: np.ndarray, out_steps: np.ndarray, out_lod: np.ndarray,
    i: int, r: float, g: float, b: float, t_sum: float, t_norm: float,
    nx: float, ny: float, nz: float, rays: int, hits: int, steps: int, finest: int,
) -> None:
    """Write one pixel's accumulated results at index ``i``: mean depth ``t_sum / t_norm``
    and unit mean normal where something was hit, inf / zero / LOD -1 where nothing was."""
    out_color[i, 0] = r
    out_color[i, 1] = g
    out_color[i, 2] = b
    out_rays[i] = rays
    out_hits[i] = hits
    out_steps[i] = steps
    if hits > 0:
        out_depth[i] = t_sum / t_norm
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            nx /= length
            ny /= length
            nz /= length
        out_normal[i, 0] = nx
        out_normal[i, 1] = ny
        out_normal[i, 2] = nz
        out_lod[i] = finest
    else:
        out_depth[i] = math.inf
        out_normal[i, 0] = 0.0
        out_normal[i, 1] = 0.0
        out_normal[i, 2] = 0.0
        out_lod[i] = -1


def render_pixels(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, cone_scale: float,
    beam: BeamBounds, out: PixelOutputs, columns, threads: int | None = None,
) -> None:
    """Trace the listed pixels (flat indices) with side×side samples each, in list order
    (so a list in tile order keeps neighbouring rays together); pixel ``pixels[k]`` goes to
    entry ``pixels[k] - out_base`` of every flat output row, or to entry ``k`` when
    ``out_base`` is negative.

    ``cone_scale`` > 0 stops descent where a node is no larger than ``cone_scale`` times the
    sub-sample footprint; 0 descends to ``stop_level``. Hits are coloured by
    ``kernels.facing_colour.seen_rgb`` from the view's colours; misses contribute black.
    Rays of the ``block``×``block`` pixel block ``(by, bx)`` start at ``beam.bound[by, bx]``
    (``kernels.beam``; zeros start every ray at the camera). With a column-top pyramid
    (``svo.column_tops``; ``no_column_tops()`` for none), rays at a fixed level first skip
    the air above the surface in it (``kernels.surface_approach``): the same hits, and steps
    that count its cells.

    Every traversal gives the same hits and steps; which is faster depends on the rays.
    Supersampled rays that stop at a fixed level without a pyramid go through the packet
    traversal (``kernels.packet_traversal``) 64 at a time, in pixel and sample order, each
    from its beam bound: on the mountain terrain, 16 rays a pixel with the beam on,
    1.25-1.45× the scalar loop's restarts (top views at 2048² and 512², oblique at 512²) and
    0.95× on the 2048² oblique view. With one ray per pixel over fine voxels packets lose
    (measured in ``benchmarks/bench_traversal.py``). Each traversal has a kernel of its own,
    chosen here, so that a render compiles only the one it runs (a first render at LOD 0
    compiled all three, 2 minutes on two cores).

    Every thread Numba runs on (or ``threads`` workers, if more) claims strips of
    ``RUN_CHUNKS`` chunks of ``PIXEL_CHUNK`` pixels until none is left; the output does not
    depend on which traces what.
    """
    threads = max(threads or 1, numba.get_num_threads())
    radius, spread = pixel_cone(cam, height)
    radius *= cone_scale / side
    spread *= cone_scale / side
    fixed_level = radius == 0.0 and spread == 0.0
    common = (cam, width, height, pixels, out_base, side, seed, view, stop_level)
    with_columns = columns.level_width.shape[0] > 0
    if fixed_level and with_columns:
        render_pixels_over_columns(*common, beam, out, columns, threads,
                                   *walks_for_level(stop_level, view.depth))
    elif fixed_level and side > 1:
        render_pixels_in_packets(*common, beam, out, threads)
    elif with_columns and stop_level >= view.depth:
        render_pixels_cone_over_columns(*common, radius, spread, beam, out, columns, threads)
    else:
        render_pixels_per_ray(*common, radius, spread, beam, out, threads)


def walks_for_level(stop_level: int, depth: int) -> tuple[bool | None, bool | None]:
    """``(to_voxels, to_nodes)`` for ``hit_ray_batch`` of rays that stop at ``stop_level``
    of an octree of ``depth`` levels: the walk they take, and None for the other, which
    Numba then leaves out of the compiled batch."""
    return (True, None) if stop_level >= depth else (None, True)


#: Pixels a thread traces at a time: one 8×8 tile of ``render.primary.tile_order``. The
#: kernels below call one function per thread and never inline a traversal or an
#: allocation into their ``prange`` bodies: Numba's parfor pass would hoist the inlined
#: loop's constant initialisations, or the buffers, out of the parallel loop, shared.
PIXEL_CHUNK = 64


@njit(parallel=True, cache=True, nogil=True)
def render_pixels_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds,
    out: PixelOutputs, columns, threads: int, to_voxels, to_nodes,
) -> None:
    """``render_pixels`` through the column-top pyramid (``trace_chunk_over_columns``;
    ``to_voxels`` and ``to_nodes`` as ``hit_ray_batch`` takes them)."""
    queue = new_run_queue()
    for _ in prange(threads):
        render_chunks_over_columns(cam, width, height, pixels, out_base, side, seed, view,
                                   stop_level, beam, out, columns, queue, to_voxels,
                                   to_nodes)


@njit(parallel=True, cache=True, nogil=True)
def render_pixels_in_packets(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds,
    out: PixelOutputs, threads: int,
) -> None:
    """``render_pixels`` in packets of 64 rays (``trace_chunk_in_packets``)."""
    queue = new_run_queue()
    for _ in prange(threads):
        render_chunks_in_packets(cam, width, height, pixels, out_base, side, seed, view,
                                 stop_level, beam, out, queue)


@njit(parallel=True, cache=True, nogil=True)
def render_pixels_per_ray(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, radius: float, spread: float,
    beam: BeamBounds, out: PixelOutputs, threads: int,
) -> None:
    """``render_pixels`` one ray at a time through the octree, each with the sub-sample cone
    ``radius + spread·t`` (``trace_chunk_per_ray``)."""
    queue = new_run_queue()
    for _ in prange(threads):
        render_chunks_per_ray(cam, width, height, pixels, out_base, side, seed, view,
                              stop_level, radius, spread, beam, out, queue)


@njit(parallel=True, cache=True, nogil=True)
def render_pixels_cone_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, radius: float, spread: float,
    beam: BeamBounds, out: PixelOutputs, columns, threads: int,
) -> None:
    """``render_pixels`` of cone-LOD rays through the column-top pyramid first
    (``trace_chunk_cone_over_columns``)."""
    queue = new_run_queue()
    for _ in prange(threads):
        render_chunks_cone_over_columns(cam, width, height, pixels, out_base, side, seed,
                                        view, radius, spread, beam, out, columns, queue)


# One thread's share of a render: chunks of PIXEL_CHUNK pixels claimed from the render's
# queue (``claim_chunk``, in strips of RUN_CHUNKS) until none is left, each traced into the
# thread's own sums and stored. A chunk's pixels come out the same whichever thread takes it.


@njit(cache=True, nogil=True)
def render_chunks_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds,
    out: PixelOutputs, columns, queue: np.ndarray, to_voxels, to_nodes,
) -> None:
    sums, tallies, run = new_chunk_sums()
    scratch, batch, strata = new_scratch(view.depth), new_ray_batch(), new_cmj_strata(side)
    while True:
        first, last = claim_chunk(queue, pixels.shape[0], sums, tallies, run)
        if first == last:
            return
        trace_chunk_over_columns(cam, width, height, pixels, first, last, side, seed, view,
                                 stop_level, beam, columns, sums, tallies, scratch, batch,
                                 strata, to_voxels, to_nodes)
        store_chunk(out, pixels, out_base, first, last, sums, tallies, side * side)


@njit(cache=True, nogil=True)
def render_chunks_in_packets(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds,
    out: PixelOutputs, queue: np.ndarray,
) -> None:
    sums, tallies, run = new_chunk_sums()
    while True:
        first, last = claim_chunk(queue, pixels.shape[0], sums, tallies, run)
        if first == last:
            return
        trace_chunk_in_packets(cam, width, height, pixels, first, last, side, seed, view,
                               stop_level, beam, sums, tallies)
        store_chunk(out, pixels, out_base, first, last, sums, tallies, side * side)


@njit(cache=True, nogil=True)
def render_chunks_per_ray(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, stop_level: int, radius: float, spread: float,
    beam: BeamBounds, out: PixelOutputs, queue: np.ndarray,
) -> None:
    sums, tallies, run = new_chunk_sums()
    scratch = new_scratch(view.depth)
    while True:
        first, last = claim_chunk(queue, pixels.shape[0], sums, tallies, run)
        if first == last:
            return
        trace_chunk_per_ray(cam, width, height, pixels, first, last, side, seed, view,
                            stop_level, radius, spread, beam, sums, tallies, scratch)
        store_chunk(out, pixels, out_base, first, last, sums, tallies, side * side)


@njit(cache=True, nogil=True)
def render_chunks_cone_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int, view: OctreeView, radius: float, spread: float,
    beam: BeamBounds, out: PixelOutputs, columns, queue: np.ndarray,
) -> None:
    sums, tallies, run = new_chunk_sums()
    scratch, strata, batch = new_scratch(view.depth), new_cmj_strata(side), new_ray_batch()
    while True:
        first, last = claim_chunk(queue, pixels.shape[0], sums, tallies, run)
        if first == last:
            return
        trace_chunk_cone_over_columns(cam, width, height, pixels, first, last, side, seed,
                                      view, radius, spread, beam, columns, sums, tallies,
                                      scratch, strata, batch)
        store_chunk(out, pixels, out_base, first, last, sums, tallies, side * side)


#: Chunks a thread claims at a time: a strip of 8 tiles, 64 pixels wide. The outputs are
#: written at image positions, and two threads storing neighbouring 8×8 tiles at once wrote
#: the same cache lines (a tile's row is 8 bytes of LOD, 32 of counts, 96 of colour): on
#: two threads a 512² render that sees only sky took as long as on one. Strips 64 pixels
#: wide share no line where a row's bytes are a multiple of 64 (widths in whole strips).
RUN_CHUNKS = 8


@njit(cache=True, nogil=True)
def new_chunk_sums() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A chunk's per-pixel sums in ``add_sample``'s layout (r, g, b, normal x, y, z, depth
    sum; hits, steps, finest LOD), and the thread's claimed run (``claim_chunk``)."""
    return (np.empty((PIXEL_CHUNK, 7)), np.empty((PIXEL_CHUNK, 3), np.int64),
            np.zeros(2, np.int64))


@njit(cache=True, nogil=True)
def claim_chunk(queue: np.ndarray, n: int, sums: np.ndarray, tallies: np.ndarray,
                run: np.ndarray) -> tuple[int, int]:
    """The next chunk of the ``n`` pixels for this thread, ``first..last-1`` (equal when none
    is left): the next of its run ``run[0]..run[1]-1``, or of a new run of ``RUN_CHUNKS``
    chunks claimed from ``queue`` once that is spent; its sums zeroed (the finest LOD 127
    until a hit lowers it)."""
    if run[0] == run[1]:
        run[0], run[1] = claim_items(queue, n, PIXEL_CHUNK * RUN_CHUNKS)
    first = run[0]
    last = min(first + PIXEL_CHUNK, run[1])
    run[0] = last
    sums[:] = 0.0
    tallies[:, 0] = 0
    tallies[:, 1] = 0
    tallies[:, 2] = 127
    return first, last


@njit(cache=True, nogil=True)
def store_chunk(out: PixelOutputs, pixels: np.ndarray, out_base: int, first: int, last: int,
                sums: np.ndarray, tallies: np.ndarray, spp: int) -> None:
    """Pixels ``first..last-1``'s sums into the outputs (``render_pixels``'s indexing)."""
    for j in range(last - first):
        i = first + j
        store_sums(out.color, out.depth, out.normal, out.rays, out.hits, out.steps, out.lod,
                   i if out_base < 0 else pixels[i] - out_base, sums, tallies, j, spp)


@njit(cache=True, nogil=True, inline="always")
def store_sums(
    out_color: np.ndarray, out_depth: np.ndarray, out_normal: np.ndarray,
    out_rays: np.ndarray, out_hits: np.ndarray, out_steps: np.ndarray, out_lod: np.ndarray,
    i: int, sums: np.ndarray, tallies: np.ndarray, j: int, spp: int,
) -> None:
    """``store_pixel`` of the sums row ``j`` (``add_sample``'s layout) at index ``i``."""
    store_pixel(out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod,
                i, sums[j, 0] / spp, sums[j, 1] / spp, sums[j, 2] / spp, sums[j, 6],
                tallies[j, 0], sums[j, 3], sums[j, 4], sums[j, 5], spp, tallies[j, 0],
                tallies[j, 1], tallies[j, 2])


@njit(cache=True, nogil=True, inline="always")
def sample_ray(cam: np.ndarray, width: int, height: int, pixel: int, s: int, side: int,
               pattern: int) -> tuple[float, float, float, float, float, float]:
    """Sample ``s`` of ``pixel``: the pixel centre for one sample, else its CMJ position."""
    row = pixel // width
    col = pixel - row * width
    if side == 1:
        fx, fy = 0.5, 0.5
    else:
        fx, fy = cmj_sample(s, side, side, pattern)
    return camera_ray(cam, col + fx, row + fy, width, height)


@njit(cache=True, nogil=True, inline="always")
def chunk_pixel(pixels: np.ndarray, index: int, width: int, side: int, seed: int,
                beam: BeamBounds, column: np.ndarray,
                row: np.ndarray) -> tuple[int, int, int, float]:
    """``(pattern, x, y, t_start)`` of the pixel ``pixels[index]``: its CMJ pattern, with
    the pattern's stratum permutations drawn into ``column`` and ``row`` (``side`` > 1), its
    position and its start bound."""
    pixel = pixels[index]
    pattern = 0
    if side > 1:
        pattern = pixel_pattern(pixel, seed)
        cmj_strata(side, side, pattern, column, row)
    y_pixel = pixel // width
    x_pixel = pixel - y_pixel * width
    return pattern, x_pixel, y_pixel, block_start(beam.bound, beam.block, y_pixel, x_pixel)


@njit(cache=True, nogil=True, inline="always")
def strata_sample_ray(cam: np.ndarray, width: int, height: int, x_pixel: int, y_pixel: int,
                      s: int, side: int, pattern: int, column: np.ndarray,
                      row: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """``sample_ray`` from the pixel's stratum permutations (``sampling.cmj_strata`` of its
    pattern in ``column`` and ``row``), the same ray."""
    fx, fy = 0.5, 0.5
    if side > 1:
        fx, fy = cmj_sample_in(s, s % side, s // side, side, side, pattern, column, row)
    return camera_ray(cam, x_pixel + fx, y_pixel + fy, width, height)


@njit(cache=True, nogil=True, inline="always")
def beam_start(beam_bound: np.ndarray, block: int, pixel: int, width: int) -> float:
    row = pixel // width
    return block_start(beam_bound, block, row, pixel - row * width)


@njit(cache=True, nogil=True, inline="always")
def block_start(beam_bound: np.ndarray, block: int, row: int, col: int) -> float:
    """Where the rays of pixel ``(row, col)`` start: its block's bound, with no division
    for the raster's per-pixel bounds (``block`` 1), which one-ray renders read per ray."""
    if block == 1:
        return start_distance(beam_bound[row, col])
    return start_distance(beam_bound[row // block, col // block])


@njit(cache=True, nogil=True, inline="always")
def add_sample(sums: np.ndarray, tallies: np.ndarray, j: int, colors,
               facing: np.ndarray, depth: int, node: int, level: int, t: float, normal: int,
               steps: int, dx: float, dy: float, dz: float) -> None:
    """Add one traced sample to pixel ``j``'s sums: colour and normal of a hit, its depth,
    its steps, and the finest LOD sampled."""
    tallies[j, 1] += steps
    if node == MISS:
        return
    tallies[j, 0] += 1
    cr, cg, cb = seen_rgb(colors, facing, node, dx, dy, dz)
    sums[j, 0] += cr
    sums[j, 1] += cg
    sums[j, 2] += cb
    ax, ay, az = normal_from_code(normal)
    sums[j, 3] += ax
    sums[j, 4] += ay
    sums[j, 5] += az
    sums[j, 6] += t
    if depth - level < tallies[j, 2]:
        tallies[j, 2] = depth - level


@borrowing
def trace_chunk_per_ray(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, first: int, last: int,
    side: int, seed: int, view: OctreeView, stop_level: int, radius: float, spread: float,
    beam: BeamBounds, sums: np.ndarray, tallies: np.ndarray, scratch,
) -> None:
    """Every sample through the scalar traversal, with the cone ``radius + spread·t``
    (``scratch``: ``traversal.new_scratch``)."""
    for j in range(last - first):
        trace_pixel(cam, width, height, pixels[first + j], side, seed, view.inner_nodes,
                    view.depth, stop_level, radius, spread, view_colours(view), view.facing,
                    beam.bound, beam.block, scratch, sums, tallies, j)


@borrowing
def trace_chunk_cone_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, first: int, last: int,
    side: int, seed: int, view: OctreeView, radius: float, spread: float, beam: BeamBounds,
    columns, sums: np.ndarray, tallies: np.ndarray, scratch, strata, batch,
) -> None:
    """Every sample with the cone ``radius + spread·t`` down to the voxels, through the
    column-top pyramid first (``kernels.cone_walk``): ``trace_chunk_per_ray``'s hits, in
    fewer steps, ``RAY_BATCH`` rays at a time (``trace_cone_batch``). A pixel's stratum
    permutations are drawn once, as in ``trace_chunk_over_columns``: 16-ray renders of the
    2048² mountain terrain ran 1.09-1.14× as fast as with a permutation per sample."""
    column, row = strata
    queued = np.int64(0)
    for j in range(last - first):
        pattern, x_pixel, y_pixel, t_start = chunk_pixel(pixels, first + j, width, side, seed,
                                                         beam, column, row)
        for s in range(side * side):
            ox, oy, oz, dx, dy, dz = strata_sample_ray(cam, width, height, x_pixel, y_pixel, s,
                                                       side, pattern, column, row)
            queue_ray(batch, queued, j, ox, oy, oz, dx, dy, dz, t_start)
            queued += 1
            if queued == RAY_BATCH:
                trace_cone_batch(batch, queued, view, radius, spread, scratch, columns, sums,
                                 tallies)
                queued = np.int64(0)
    trace_cone_batch(batch, queued, view, radius, spread, scratch, columns, sums, tallies)


@borrowing
def trace_cone_batch(batch, count: int, view: OctreeView, radius: float, spread: float,
                     scratch, columns, sums: np.ndarray, tallies: np.ndarray) -> None:
    """``trace_ray_batch`` for cone-LOD rays: every queued ray's walk through the pyramid
    (``cone_walk.walk_cone_over_columns``), with what its landing reads prefetched, then
    every settling, then every shading, so that one ray's cache misses overlap the next
    ones' work."""
    rays, walk_ints, walk_times = batch[0], batch[2], batch[3]
    hits = (batch[4], batch[5])
    inner_nodes, depth, facing = view.inner_nodes, view.depth, view.facing
    colors = view_colours(view)
    for k in range(count):
        walk = walk_cone_over_columns(rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3],
                                      rays[k, 4], rays[k, 5], rays[k, 6], radius, spread,
                                      depth, columns)
        prefetch_cone_landing(columns, walk)
        t, cells, cx, cz, level = walk
        walk_times[k, 0] = t
        walk_ints[k, 1] = cells
        walk_ints[k, 2] = cx
        walk_ints[k, 3] = cz
        walk_ints[k, 4] = level
    for k in range(count):
        dx, dy, dz = rays[k, 3], rays[k, 4], rays[k, 5]
        node, level, t, normal, steps = settle_cone_walk(
            rays[k, 0], rays[k, 1], rays[k, 2], dx, dy, dz, rays[k, 6], inner_nodes, depth,
            radius, spread, scratch, columns,
            (walk_times[k, 0], walk_ints[k, 1], walk_ints[k, 2], walk_ints[k, 3],
             walk_ints[k, 4]))
        if node >= 0:
            prefetch_seen(colors, facing, node)
        queue_hit(hits, k, batch[1][k], node, level, t, normal, steps, dx, dy, dz)
    shade_batch(hits, count, sums, tallies, colors, facing, depth)


@borrowing
def trace_chunk_over_columns(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, first: int, last: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds, columns,
    sums: np.ndarray, tallies: np.ndarray, scratch, batch, strata, to_voxels, to_nodes,
) -> None:
    """Every sample to ``stop_level`` through ``kernels.surface_approach``: the air in the
    column-top pyramid, then the octree where the ray reaches the surface, ``RAY_BATCH``
    rays at a time (``trace_ray_batch``). From a beam bound one ray at a time beats the
    packets here, supersampled or not (mountain terrain, 16 rays a pixel: 1.1-1.2× the
    packets); ``render.primary.pixel_columns`` decides. ``scratch``
    (``traversal.new_scratch``), ``batch`` (``new_ray_batch``) and ``strata``
    (``sampling.new_cmj_strata(side)``) are the caller's.

    A supersampled pixel's stratum permutations are drawn once (``sampling.cmj_strata``),
    not again for each sample: the same sample positions, and 16-ray pixels 1.1× faster."""
    column, row = strata
    # ``np.int64``: with a plain 0 Numba typed the last, partial batch's count as the
    # literal 0 and compiled ``trace_ray_batch`` a second time for it (15 s on two cores
    # with the walk compiled in).
    queued = np.int64(0)
    for j in range(last - first):
        pattern, x_pixel, y_pixel, t_start = chunk_pixel(pixels, first + j, width, side, seed,
                                                         beam, column, row)
        if t_start == math.inf:
            continue  # the beam showed every ray of the block misses: black, and no steps
        for s in range(side * side):
            ox, oy, oz, dx, dy, dz = strata_sample_ray(cam, width, height, x_pixel, y_pixel, s,
                                                       side, pattern, column, row)
            queue_ray(batch, queued, j, ox, oy, oz, dx, dy, dz, t_start)
            queued += 1
            if queued == RAY_BATCH:
                trace_ray_batch(batch, queued, view, stop_level, scratch, columns, sums,
                                tallies, to_voxels, to_nodes)
                queued = np.int64(0)
    trace_ray_batch(batch, queued, view, stop_level, scratch, columns, sums, tallies,
                    to_voxels, to_nodes)


#: Rays a chunk queues before it traces them (``trace_ray_batch``): one call of the lane
#: walk (``lane_walk.SLOTS``) where the batches walk in lanes; 32 for the one-ray walk, which
#: read 0.95-1.02× as fast with 16 or 64.
RAY_BATCH = SLOTS if LANE_WALK_PAYS else 32


@njit(cache=True, nogil=True)
def new_ray_batch():
    """``trace_ray_batch``'s queue: the rays and their walks (``lane_walk.new_walk_rows``),
    the rays' pixel rows and their hits (``queue_hit``'s two arrays)."""
    rays, walk_ints, walk_times = new_walk_rows(RAY_BATCH)
    return (rays, np.empty(RAY_BATCH, np.int64), walk_ints, walk_times,
            np.empty((RAY_BATCH, 5), np.int64), np.empty((RAY_BATCH, 4)))


@borrowing
def queue_ray(batch, k: int, j: int, ox: float, oy: float, oz: float, dx: float, dy: float,
              dz: float, tmin: float) -> None:
    """Queue the ray ``o + t·d`` from ``tmin`` of pixel row ``j`` at ``k``."""
    rays, pixel_rows = batch[0], batch[1]
    rays[k, 0] = ox
    rays[k, 1] = oy
    rays[k, 2] = oz
    rays[k, 3] = dx
    rays[k, 4] = dy
    rays[k, 5] = dz
    rays[k, 6] = tmin
    pixel_rows[k] = j


@borrowing
def trace_ray_batch(batch, count: int, view: OctreeView, stop_level: int, scratch, columns,
                    sums: np.ndarray, tallies: np.ndarray, to_voxels, to_nodes) -> None:
    """Trace the first ``count`` queued rays into their pixels' sums in three passes: walk
    every ray through the pyramid, settle every walk (``surface_approach.settle_walk``),
    shade every hit. A walk prefetches the line of the column it stops in, and a settled
    hit its colour, so each pass finds the last one's loads done: a batch's cache misses
    overlap instead of each stalling its ray (mountain terrain, one and 16 rays a pixel,
    2048² and 512², top and 45° views: 1.05-1.20× as fast as tracing and shading each ray
    in turn). The walks go through the pyramid side by side in SIMD lanes (``lane_walk``)
    where the target has AVX-512 (``lane_walk.LANE_WALK_PAYS``), to voxels through a walk
    compiled for LOD 0, to coarser nodes through one for any level; otherwise one by one.
    With the lanes the batch compiles no one-ray walk: when pyramids with int32 heights had
    no cell records and their rays were walked one by one here, a first reference render
    (``voxfield render builtin:pillars``, empty cache) took 74 s instead of 58 on two
    cores."""
    hit_ray_batch(batch, count, view, stop_level, scratch, columns, to_voxels, to_nodes)
    shade_batch((batch[4], batch[5]), count, sums, tallies, view_colours(view), view.facing,
                view.depth)


@borrowing
def hit_ray_batch(batch, count: int, view: OctreeView, stop_level: int, scratch,
                  columns, to_voxels, to_nodes) -> None:
    """The first two passes of ``trace_ray_batch``: every queued ray's hit (node, level,
    time, entry face, steps) into the batch's hits (``queue_hit``), each hit's colour
    prefetched. The error-aware renderer decides on these before it shades.

    ``to_voxels`` and ``to_nodes`` say which lane walks the batch may take: anything for
    the walk to voxels (LOD 0) and the walk to coarser nodes, None for one it never takes
    (``walks_for_level``), which Numba then prunes from the compiled batch. A reference
    render's batches compile no walk to coarser nodes, a fixed-LOD render's none to
    voxels: ``voxfield render builtin:pillars`` with an empty cache took 56 s instead of 75
    on two cores. (Rays whose walk was left out go to the octree from their start: the
    same hits, in other steps.)"""
    rays, pixel_rows, walk_ints, walk_times = batch[0], batch[1], batch[2], batch[3]
    hits = (batch[4], batch[5])
    inner_nodes, depth, facing = view.inner_nodes, view.depth, view.facing
    colors = view_colours(view)
    if LANE_WALK_PAYS:
        # (A constant: Numba compiles one of the two branches.)
        finest = walk_plan(0.0, depth, stop_level, columns, FROM_CAMERA)[0]
        # (``is not None`` on an argument typed None: the branch is pruned before typing.)
        walks = finest >= 0 and columns.cell_records.shape[0] > 0
        if walks and finest == 0 and to_voxels is not None:
            walk_to_voxels_in_lanes(rays, count, depth, columns, walk_ints, walk_times)
            land_walks(rays, count, walk_ints, walk_times, columns, math.inf, 0)
        elif walks and finest > 0 and to_nodes is not None:
            walk_to_nodes_in_lanes(rays, count, depth, finest, columns, walk_ints, walk_times)
            land_walks(rays, count, walk_ints, walk_times, columns, math.inf, finest)
        else:
            # No pyramid (or one built without records, which renders are not given), or no
            # walk for this level: each ray goes to the octree from its start, as
            # ``walk_over_columns`` hands it over.
            for k in range(count):
                store_walk(walk_ints, walk_times, k,
                           (HANDED_OVER, rays[k, 6], 0, -1, -1, -1, math.inf, -1))
    else:
        for k in range(count):
            store_walk(walk_ints, walk_times, k, walk_primary_over_columns(
                rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5],
                rays[k, 6], depth, stop_level, columns))
    for k in range(count):
        dx, dy, dz = rays[k, 3], rays[k, 4], rays[k, 5]
        node, level, t, normal, steps = settle_walk(
            rays[k, 0], rays[k, 1], rays[k, 2], dx, dy, dz, rays[k, 6], math.inf,
            inner_nodes, depth, stop_level, scratch, columns, walk_of(walk_ints, walk_times, k))
        if node >= 0:
            prefetch_seen(colors, facing, node)
        queue_hit(hits, k, pixel_rows[k], node, level, t, normal, steps, dx, dy, dz)


@njit(cache=True, nogil=True, inline="always")
def store_walk(walk_ints: np.ndarray, walk_times: np.ndarray, k: int, walk) -> None:
    """Keep ray ``k``'s walk (``surface_approach.walk_over_columns``'s tuple) for its settling."""
    verdict, t_from, cells, cx, cz, y, t, normal = walk
    record_walk(walk_ints, walk_times, k, verdict, t_from, cells, cx, cz)
    record_landing(walk_ints, walk_times, k, y, t, normal)


@borrowing
def queue_hit(hits, k: int, j: int, node: int, level: int, t: float, normal: int, steps: int,
              dx: float, dy: float, dz: float) -> None:
    ints, floats = hits
    ints[k, 0] = j
    ints[k, 1] = node
    ints[k, 2] = level
    ints[k, 3] = normal
    ints[k, 4] = steps
    floats[k, 0] = t
    floats[k, 1] = dx
    floats[k, 2] = dy
    floats[k, 3] = dz


@borrowing
def shade_batch(hits, count: int, sums: np.ndarray, tallies: np.ndarray, colors,
                facing: np.ndarray, depth: int) -> None:
    """``add_sample`` for the first ``count`` queued hits, in queue order."""
    ints, floats = hits
    for k in range(count):
        add_sample(sums, tallies, ints[k, 0], colors, facing, depth, ints[k, 1], ints[k, 2],
                   floats[k, 0], ints[k, 3], ints[k, 4], floats[k, 1], floats[k, 2],
                   floats[k, 3])


@njit(cache=True, nogil=True, inline="always")
def trace_pixel(
    cam: np.ndarray, width: int, height: int, pixel: int, side: int, seed: int,
    inner_nodes: np.ndarray, depth: int, stop_level: int, radius: float, spread: float,
    colors, facing: np.ndarray, beam_bound: np.ndarray, block: int, scratch,
    sums: np.ndarray, tallies: np.ndarray, j: int,
) -> None:
    """All ``side²`` samples of one pixel through ``trace_ray``, added to row ``j`` of the
    sums: the one per-pixel loop of the CPU scalar path and the CUDA kernel
    (``kernels.cuda_primary``), so both targets trace and shade alike."""
    pattern = pixel_pattern(pixel, seed) if side > 1 else 0
    t_start = beam_start(beam_bound, block, pixel, width)
    for s in range(side * side):
        ox, oy, oz, dx, dy, dz = sample_ray(cam, width, height, pixel, s, side, pattern)
        node, level, t, normal, steps = trace_ray(
            ox, oy, oz, dx, dy, dz, t_start, math.inf,
            inner_nodes, depth, stop_level, radius, spread, scratch,
        )
        add_sample(sums, tallies, j, colors, facing, depth, node, level, t, normal, steps,
                   dx, dy, dz)


@njit(cache=True, nogil=True)
def trace_chunk_in_packets(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, first: int, last: int,
    side: int, seed: int, view: OctreeView, stop_level: int, beam: BeamBounds,
    sums: np.ndarray, tallies: np.ndarray,
) -> None:
    """Every sample to ``stop_level``, 64 consecutive samples (in pixel, then sample order)
    per packet."""
    inner_nodes, depth, facing = view.inner_nodes, view.depth, view.facing
    colors = view_colours(view)
    scratch = new_packet_scratch(depth)
    origins = np.empty((PACKET_RAYS, 3))
    directions = np.empty((PACKET_RAYS, 3))
    tmins = np.empty(PACKET_RAYS)
    tmaxs = np.full(PACKET_RAYS, math.inf)
    owner = np.empty(PACKET_RAYS, np.int64)
    hit_node = np.empty(PACKET_RAYS, np.int64)
    hit_level = np.empty(PACKET_RAYS, np.int64)
    hit_t = np.empty(PACKET_RAYS)
    hit_normal = np.empty(PACKET_RAYS, np.int64)
    hit_steps = np.empty(PACKET_RAYS, np.int64)
    spp = side * side
    total = (last - first) * spp
    pixel = 0
    pattern = 0
    t_start = 0.0
    for start in range(0, total, PACKET_RAYS):
        n = min(PACKET_RAYS, total - start)
        for k in range(n):
            j = (start + k) // spp
            s = start + k - j * spp
            if s == 0:  # a new pixel: hash its pattern once
                pixel = pixels[first + j]
                pattern = pixel_pattern(pixel, seed) if side > 1 else 0
                t_start = beam_start(beam.bound, beam.block, pixel, width)
            ox, oy, oz, dx, dy, dz = sample_ray(cam, width, height, pixel, s, side, pattern)
            origins[k, 0] = ox
            origins[k, 1] = oy
            origins[k, 2] = oz
            directions[k, 0] = dx
            directions[k, 1] = dy
            directions[k, 2] = dz
            tmins[k] = t_start
            owner[k] = j
        trace_packet(n, origins, directions, tmins, tmaxs, inner_nodes, depth, stop_level,
                     scratch, hit_node, hit_level, hit_t, hit_normal, hit_steps)
        for k in range(n):
            add_sample(sums, tallies, owner[k], colors, facing, depth, hit_node[k],
                       hit_level[k], hit_t[k], hit_normal[k], hit_steps[k], directions[k, 0],
                       directions[k, 1], directions[k, 2])
