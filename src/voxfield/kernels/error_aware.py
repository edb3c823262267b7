"""Error-aware adaptive rendering kernel (EA thesis §5.1.3–5.1.4).

One ray per pixel samples the base LOD. At the node it hits, the node's error for the ray's
direction plus the decayed mean of its children's errors,
``E_N(r) = e(r, N) + d · Σ_c e(r, c) / |C|``, is compared with the threshold; above it the
ray is discarded and 2×2 rays one LOD finer replace it, recursively, up to ``max_refinements``
times (thesis: 2 → at most 1 + 4 + 16 = 21 rays). Discarded rays and their steps count.

Ray positions: the first ray goes through the pixel centre, refinement rays through the
centres of their sub-cells, except on the 4×4 level where they are the reference renderer's
CMJ samples of those cells — so refining everywhere reproduces the reference exactly.

Parent-ray reuse (thesis §6.2, an option): every ray goes through the CMJ sample of one
hashed finest-level cell inside its cell, so a refined ray already lies in one of its four
sub-cells. That sub-cell keeps the parent ray, continued one LOD finer from the parent's hit
(nothing finer can be hit before it), and only the other three get new rays. Refining
everywhere then still reproduces the reference, with 16 rays per pixel instead of 21.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.bundles import BeamBounds, OctreeView, PixelOutputs, view_colours
from voxfield.kernels.camera_rays import camera_ray, pixel_cone
from voxfield.kernels.colour import node_rgb
from voxfield.kernels.error_lookup import colour_error, sh_error, sh_evaluate
from voxfield.kernels.facing_colour import prefetch_seen, seen_rgb
from voxfield.kernels.node_descriptor import descriptor_first_child
from voxfield.kernels.octahedral import bilinear_at, bilinear_footprint, oct_encode
from voxfield.kernels.primary import (
    RAY_BATCH,
    block_start,
    hit_ray_batch,
    new_ray_batch,
    normal_from_code,
    queue_ray,
    store_pixel,
)
from voxfield.kernels.sampling import cmj_sample, hash_u32, pixel_pattern
from voxfield.kernels.scheduling import claim_items, new_run_queue
from voxfield.kernels.traversal import MISS, new_scratch, trace_ray

ENCODING_OCT = 0
ENCODING_SH = 1
MAX_REFINEMENTS = 3
_QUEUE = 1 + 3 * MAX_REFINEMENTS + 4  # LIFO: at most 3 siblings wait per level
_FRESH = -1.0  # queue marker: a new ray, not a continued parent ray


@njit(cache=True, nogil=True)
def designated_cell(cx: int, cy: int, k: int, fine: int, pattern: int) -> tuple[int, int]:
    """The finest-level cell a reused ray of cell ``(cx, cy)`` on refinement level ``k`` goes
    through: one of the ``(fine >> k)²`` cells inside it, chosen by hash."""
    span = fine >> k
    key = hash_u32(pattern ^ hash_u32((k << 20) | (cy << 10) | cx))
    pick = key % (span * span)
    return cx * span + pick % span, cy * span + pick // span


@njit(cache=True, nogil=True)
def cell_sample(fx: int, fy: int, fine: int, pattern: int) -> tuple[float, float]:
    """Position in the pixel of finest cell ``(fx, fy)``: its CMJ sample, as the reference's."""
    if fine == 1:
        return 0.5, 0.5
    return cmj_sample(fy * fine + fx, fine, fine, pattern)


@njit(cache=True, nogil=True)
def node_error(
    node: int, level: int, depth: int, inner_nodes: np.ndarray, decay: float,
    encoding: int, oct_map: np.ndarray, sh: np.ndarray, x: float, y: float, z: float,
) -> float:
    """``E_N(r)``: the node's own error plus ``decay`` times its children's mean error.

    Children on the voxel level have no children of their own and contribute zero error.
    Every mask's octahedral map is read at the same direction: it is encoded, and its
    bilinear footprint found, once (the same values as ``oct_error`` each time).
    """
    descriptor = inner_nodes[node]
    mask = descriptor & 0xFF
    octahedral = encoding != ENCODING_SH
    x0, y0, fx, fy = 0, 0, 0.0, 0.0
    if octahedral:
        u, v = oct_encode(x, y, z)
        x0, y0, fx, fy = bilinear_footprint(oct_map.shape[1] - 2, u, v)
        error = bilinear_at(oct_map[mask], x0, y0, fx, fy)
    else:
        error = sh_error(sh, mask, x, y, z)
    if decay == 0.0 or level + 1 >= depth:
        return error
    first = descriptor_first_child(descriptor)
    total = 0.0
    count = 0
    for octant in range(8):
        if (mask >> octant) & 1:
            child_mask = inner_nodes[first + count] & 0xFF
            if octahedral:
                total += bilinear_at(oct_map[child_mask], x0, y0, fx, fy)
            else:
                total += sh_error(sh, child_mask, x, y, z)
            count += 1
    return error + decay * total / count


@njit(cache=True, nogil=True)
def node_error_precomputed(
    node: int, level: int, depth: int, inner_nodes: np.ndarray, decay: float, sh: np.ndarray,
    children_sh: np.ndarray, x: float, y: float, z: float,
) -> float:
    """``E_N(r)`` with SH errors and the children's mean SH coefficients precomputed per
    node (SH is linear: the mean of the children's errors is the error of their mean
    coefficients), so the children cost one evaluation instead of one each."""
    error = sh_evaluate(sh[inner_nodes[node] & 0xFF], x, y, z)
    if decay == 0.0 or level + 1 >= depth:
        return error
    return error + decay * sh_evaluate(children_sh[node], x, y, z)


@njit(cache=True, nogil=True)
def luminance(colors: np.ndarray, node: int) -> float:
    r, g, b = node_rgb(colors, node)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


@njit(cache=True, nogil=True)
def node_colour_error(
    node: int, inner_nodes: np.ndarray, colors: np.ndarray, bright_ratio: float,
    light_map: np.ndarray, class_of: np.ndarray, symmetry_of: np.ndarray,
    symmetries: np.ndarray, x: float, y: float, z: float,
) -> float:
    """Colour error of an inner node: its children brighter than ``(1 + bright_ratio)`` times
    its own luminance are flagged bright, and the configuration's table error is read."""
    descriptor = inner_nodes[node]
    mask = descriptor & 0xFF
    first = descriptor_first_child(descriptor)
    limit = (1.0 + bright_ratio) * luminance(colors, node)
    bright = 0
    slot = 0
    for octant in range(8):
        if (mask >> octant) & 1:
            if luminance(colors, first + slot) > limit:
                bright |= 1 << octant
            slot += 1
    if bright == 0 or bright == mask:
        return 0.0  # one luminance class: no colour error in the binary model
    return colour_error(light_map, class_of, symmetry_of, symmetries, mask, bright, x, y, z)


@njit(cache=True, nogil=True)
def lighting_node_error(
    node: int, level: int, depth: int, inner_nodes: np.ndarray, decay: float,
    colors: np.ndarray, bright_ratio: float, light_map: np.ndarray, class_of: np.ndarray,
    symmetry_of: np.ndarray, symmetries: np.ndarray, x: float, y: float, z: float,
) -> float:
    """The colour part of the lighting-aware ``E_N(r)`` (EA §6.1), decayed over children like
    the geometric part; children on the voxel level have no colour error."""
    error = node_colour_error(node, inner_nodes, colors, bright_ratio, light_map, class_of,
                              symmetry_of, symmetries, x, y, z)
    if decay == 0.0 or level + 1 >= depth:
        return error
    descriptor = inner_nodes[node]
    mask = descriptor & 0xFF
    first = descriptor_first_child(descriptor)
    total = 0.0
    count = 0
    for octant in range(8):
        if (mask >> octant) & 1:
            total += node_colour_error(first + count, inner_nodes, colors, bright_ratio,
                                       light_map, class_of, symmetry_of, symmetries, x, y, z)
            count += 1
    return error + decay * total / count


class Refinement(NamedTuple):
    """Where a pixel's first ray stops and how far refinement may go (EA §5.1.3, §6.2)."""

    base_stop_level: int
    cone_scale: float
    max_refinements: int
    reuse_parent: bool


class ErrorModel(NamedTuple):
    """The refinement test: ``e(r, N) + decay · mean_c e(r, c) > threshold``, the geometric
    table in one encoding, the optional lighting-aware colour error (EA §6.1) and the
    optional colour term (``colour_weight`` times a per-node ``colour_error``)."""

    threshold: float
    decay: float
    encoding: int
    oct_map: np.ndarray
    sh: np.ndarray
    children_sh: np.ndarray
    lighting_aware: bool
    bright_ratio: float
    light_map: np.ndarray
    class_of: np.ndarray
    symmetry_of: np.ndarray
    symmetries: np.ndarray
    colour_weight: float
    colour_error: np.ndarray
    colour_to_voxels: bool
    context: np.ndarray


class RefinementMaps(NamedTuple):
    """Per-pixel output rows beside the image's (``bundles.PixelOutputs``): refinements and
    discarded rays."""

    refined: np.ndarray
    discarded: np.ndarray


@njit(parallel=True, cache=True, nogil=True)
def render_error_aware_rows(
    cam: np.ndarray, width: int, height: int, row0: int, pixels: np.ndarray, seed: int,
    view: OctreeView, refinement: Refinement, model: ErrorModel, beam: BeamBounds,
    out: PixelOutputs, maps: RefinementMaps, columns, threads: int = 1,
) -> None:
    """Trace the pixels ``pixels`` lists, in that order (flat indices from row ``row0``, a
    band's; ``render.primary.tile_order`` keeps neighbouring rays together), each thread
    claiming the next ``REFINE_CHUNK`` of them from a shared counter
    (``kernels.scheduling``): single tiles, not the LOD renderers' strips of 8, which left
    one thread idle in a band of a 64-pixel-wide probe face. ``refinement.cone_scale`` > 0
    picks the base LOD by pixel cone; ``model.lighting_aware`` adds the bright-flag colour
    error to the geometric one. Rays at a fixed level cross the air in the column-top
    pyramid ``columns`` first (``kernels.surface_approach``; ``no_column_tops()`` for none),
    as the LOD renderer's do."""
    queue = new_run_queue()
    for _ in prange(max(threads, 1)):
        render_claimed_chunks(cam, width, height, row0, pixels, seed, view, refinement,
                              model, beam, out, maps, columns, queue)


@njit(cache=True, nogil=True)
def render_claimed_chunks(
    cam: np.ndarray, width: int, height: int, row0: int, pixels: np.ndarray, seed: int,
    view: OctreeView, refinement: Refinement, model: ErrorModel, beam: BeamBounds,
    out: PixelOutputs, maps: RefinementMaps, columns, queue: np.ndarray,
) -> None:
    """One thread's chunks of ``render_error_aware_rows``, with its scratch, ray batch and
    records allocated once (never in the ``prange`` body, where Numba's parfor pass would
    hoist them out of the parallel loop, shared)."""
    scratch, batch = new_scratch(view.depth), new_ray_batch()
    records = new_chunk_records(refinement.max_refinements)
    while True:
        first, last = claim_items(queue, pixels.shape[0], REFINE_CHUNK)
        if first == last:
            return
        trace_pixel_chunk(cam, width, height, row0, pixels, first, last, seed, view,
                          refinement, model, beam, out, maps, columns, scratch, batch, records)


#: Pixels whose rays are traced together, one refinement level at a time
#: (``trace_pixel_chunk``): an 8×8 tile in tile order. With up to 16 rays a pixel at the
#: finest level, a chunk's records stay in the L2 cache (2 refinements: 1,344 rays,
#: 194 KiB).
REFINE_CHUNK = 64

# A chunk's ray records. Integers: the pixel (in the chunk), the ray's cell and refinement,
# its stop level, the finest cell a reused ray goes through, the record of its first child
# (-1: a sample, or a miss), what it hit (node, level, entry face, steps) and, for a
# continued ray, its parent's entry face.
(_PIXEL, _CELL_X, _CELL_Y, _REFINEMENT, _STOP, _FINE_X, _FINE_Y, _CHILD, _NODE, _LEVEL,
 _NORMAL, _STEPS, _PARENT_NORMAL) = range(13)
# Floats: where a continued ray resumes (``_FRESH`` for a new ray), its hit time, direction.
_TMIN, _T, _DX, _DY, _DZ = range(5)


@njit(cache=True, nogil=True)
def rays_per_pixel(max_refinements: int) -> int:
    """The most rays a pixel can cast: ``1 + 4 + ... + 4^max_refinements``."""
    return ((1 << (2 * max_refinements + 2)) - 1) // 3


class ChunkRecords(NamedTuple):
    """What ``trace_pixel_chunk`` keeps of a chunk: rows for every ray its pixels may cast
    (``ints`` and ``floats``, the columns above), the pixels' start distances, sample
    patterns and image places (row, column), and the stack ``add_pixel_samples`` replays a
    pixel's rays with."""

    ints: np.ndarray
    floats: np.ndarray
    starts: np.ndarray
    patterns: np.ndarray
    places: np.ndarray
    stack: np.ndarray


@njit(cache=True, nogil=True)
def new_chunk_records(max_refinements: int) -> ChunkRecords:
    """``ChunkRecords`` for chunks of ``REFINE_CHUNK`` pixels."""
    count = REFINE_CHUNK * rays_per_pixel(max_refinements)
    return ChunkRecords(np.empty((count, 13), np.int64), np.empty((count, 5)),
                        np.empty(REFINE_CHUNK), np.empty(REFINE_CHUNK, np.int64),
                        np.empty((REFINE_CHUNK, 2), np.int64), np.empty(_QUEUE, np.int64))


@borrowing
def trace_pixel_chunk(
    cam: np.ndarray, width: int, height: int, row0: int, pixels: np.ndarray, first: int,
    last: int, seed: int, view: OctreeView, refinement: Refinement, model: ErrorModel,
    beam: BeamBounds, out: PixelOutputs, maps: RefinementMaps, columns, scratch, batch,
    records: ChunkRecords,
) -> None:
    """Pixels ``pixels[first:last]`` (flat indices from row ``row0``), breadth first: every
    pixel's first ray, then the error test of each hit, which queues the 2×2 finer rays of
    those over the threshold; then those rays, and so on. A level's rays are traced together
    in ray batches (``kernels.primary.hit_ray_batch``: walks in SIMD lanes,
    settling overlapped), where one pixel at a time left each ray to wait on its own walk.
    Each pixel's samples are then added up in the order a per-pixel, depth-first refinement
    adds them (``add_pixel_samples``), so the image is the same to the last bit."""
    ints, floats, places = records.ints, records.floats, records.places
    starts, patterns = records.starts, records.patterns
    base_stop_level, _, max_refinements, reuse_parent = refinement
    fine = 1 << max_refinements  # finest cells per pixel side
    for j in range(last - first):
        row = row0 + pixels[first + j] // width
        col = pixels[first + j] % width
        places[j, 0] = row
        places[j, 1] = col
        patterns[j] = pixel_pattern(row * width + col, seed)
        starts[j] = block_start(beam.bound, beam.block, row, col)
        ints[j, _PIXEL] = j
        ints[j, _CELL_X] = 0
        ints[j, _CELL_Y] = 0
        ints[j, _REFINEMENT] = 0
        ints[j, _STOP] = base_stop_level
        floats[j, _TMIN] = _FRESH
        if reuse_parent:
            ints[j, _FINE_X], ints[j, _FINE_Y] = designated_cell(0, 0, 0, fine, patterns[j])
    level_first = np.int64(0)  # not a literal 0: one compilation of ``trace_records``
    count = last - first
    while level_first < count:
        level_last = count
        trace_records(cam, width, height, view, refinement, level_first, level_last,
                      columns, scratch, batch, records)
        count = refine_records(view, refinement, model, level_first, level_last, count,
                               records)
        level_first = level_last
    add_chunk_samples(view, refinement, out, maps, row0, last - first, records)


@borrowing
def trace_records(
    cam: np.ndarray, width: int, height: int, view: OctreeView, refinement: Refinement,
    level_first: int, level_last: int, columns, scratch, batch, records: ChunkRecords,
) -> None:
    """Trace records ``level_first..level_last-1`` (one refinement level of a chunk) into
    their hit rows: rays at a fixed level in batches of ``RAY_BATCH`` that stop at one
    level, first rays of a cone-LOD render one by one through the octree."""
    ints, floats, places = records.ints, records.floats, records.places
    starts, patterns = records.starts, records.patterns
    _, cone_scale, max_refinements, reuse_parent = refinement
    fine = 1 << max_refinements
    radius, spread = pixel_cone(cam, height)
    radius *= cone_scale
    spread *= cone_scale
    # ``np.int64``: with plain literals Numba compiled ``record_batch`` a second time, for
    # a literal -1 as the stop level.
    queued = np.int64(0)
    batch_stop = np.int64(-1)
    for r in range(level_first, level_last + 1):
        stop = ints[r, _STOP] if r < level_last else -1
        if queued > 0 and (r == level_last or queued == RAY_BATCH or stop != batch_stop):
            # The batch is traced from this one call: LLVM copies a callee's code into its
            # caller at every call site, and the lane walk is large to compile.
            record_batch(view, batch_stop, scratch, columns, batch, queued, records)
            queued = np.int64(0)
        if r == level_last:
            break
        j = ints[r, _PIXEL]
        cx = ints[r, _CELL_X]
        cy = ints[r, _CELL_Y]
        k = ints[r, _REFINEMENT]
        cells = 1 << k
        if reuse_parent:
            fx, fy = cell_sample(ints[r, _FINE_X], ints[r, _FINE_Y], fine, patterns[j])
        elif cells == 4:
            fx, fy = cmj_sample(cy * 4 + cx, 4, 4, patterns[j])
        else:
            fx = (cx + 0.5) / cells
            fy = (cy + 0.5) / cells
        ox, oy, oz, dx, dy, dz = camera_ray(cam, places[j, 1] + fx, places[j, 0] + fy, width,
                                            height)
        floats[r, _DX] = dx
        floats[r, _DY] = dy
        floats[r, _DZ] = dz
        tmin = max(floats[r, _TMIN], starts[j])
        if tmin == math.inf:
            # The beam showed every ray of the block misses; a walk would take no step.
            record_hit(records, r, MISS, 0, math.inf, -1, 0)
        elif k == 0 and cone_scale > 0.0:
            node, level, t, normal, steps = trace_ray(
                ox, oy, oz, dx, dy, dz, tmin, math.inf, view.inner_nodes, view.depth, stop,
                radius, spread, scratch)
            record_hit(records, r, node, level, t, normal, steps)
        else:
            batch_stop = stop
            queue_ray(batch, queued, r, ox, oy, oz, dx, dy, dz, tmin)
            queued += 1


@borrowing
def record_batch(view: OctreeView, stop_level: int, scratch, columns, batch, count: int,
                 records: ChunkRecords) -> None:
    """Trace the batch's ``count`` rays to ``stop_level`` and record each hit with its ray."""
    # Refinements walk to coarser nodes and to voxels: both walks are compiled in.
    hit_ray_batch(batch, count, view, stop_level, scratch, columns, True, True)
    hit_ints, hit_floats = batch[4], batch[5]
    for b in range(count):
        record_hit(records, hit_ints[b, 0], hit_ints[b, 1], hit_ints[b, 2], hit_floats[b, 0],
                   hit_ints[b, 3], hit_ints[b, 4])


@njit(cache=True, nogil=True, inline="always")
def record_hit(records: ChunkRecords, r: int, node: int, level: int, t: float, normal: int,
               steps: int) -> None:
    """Ray ``r``'s hit; a continued ray that hits where it resumes entered through its
    parent's face."""
    ints, floats = records.ints, records.floats
    if floats[r, _TMIN] != _FRESH and normal < 0 and t == floats[r, _TMIN]:
        normal = ints[r, _PARENT_NORMAL]
    ints[r, _NODE] = node
    ints[r, _LEVEL] = level
    ints[r, _NORMAL] = normal
    ints[r, _STEPS] = steps
    floats[r, _T] = t


@borrowing
def refine_records(view: OctreeView, refinement: Refinement, model: ErrorModel,
                   level_first: int, level_last: int, count: int,
                   records: ChunkRecords) -> int:
    """The error test (``E_N(r) > threshold``) of records ``level_first..level_last-1``:
    each hit over the threshold gets four finer rays at ``count`` on (``_CHILD``), in its
    sub-cells' order. Returns the new record count."""
    ints, floats, patterns = records.ints, records.floats, records.patterns
    inner_nodes, depth = view.inner_nodes, view.depth
    colors = view_colours(view)
    _, _, max_refinements, reuse_parent = refinement
    (threshold, decay, encoding, oct_map, sh, children_sh, lighting_aware, bright_ratio,
     light_map, class_of, symmetry_of, symmetries, colour_weight, colour_error,
     colour_to_voxels, context) = model
    fine = 1 << max_refinements
    for r in range(level_first, level_last):
        ints[r, _CHILD] = -1
        node = ints[r, _NODE]
        level = ints[r, _LEVEL]
        k = ints[r, _REFINEMENT]
        if node == MISS:
            continue
        if k >= max_refinements or level >= depth:
            prefetch_seen(colors, view.facing, node)  # a sample: see ``add_chunk_samples``
            continue
        dx, dy, dz = floats[r, _DX], floats[r, _DY], floats[r, _DZ]
        if children_sh.shape[0] > 0:
            error = node_error_precomputed(node, level, depth, inner_nodes, decay, sh,
                                           children_sh, dx, dy, dz)
        else:
            error = node_error(node, level, depth, inner_nodes, decay, encoding, oct_map, sh,
                               dx, dy, dz)
        if context.shape[0] > 0 and context[node]:
            error = 0.0  # inside a repeating surface: a shift, not a silhouette
        if lighting_aware:
            error += lighting_node_error(
                node, level, depth, inner_nodes, decay, colors, bright_ratio, light_map,
                class_of, symmetry_of, symmetries, dx, dy, dz)
        colour_part = 0.0
        if colour_weight > 0.0:
            colour_part = colour_weight * colour_error[node]
            error += colour_part
        if error <= threshold:
            prefetch_seen(colors, view.facing, node)
            continue
        # Colour alone over the threshold: finer LODs average it again, so the sub-rays may
        # go straight to the voxels.
        finer = depth if colour_to_voxels and colour_part > threshold else level + 1
        ints[r, _CHILD] = count
        j = ints[r, _PIXEL]
        cell_x, cell_y = ints[r, _FINE_X], ints[r, _FINE_Y]
        for sub in range(4):
            sx = 2 * ints[r, _CELL_X] + (sub & 1)
            sy = 2 * ints[r, _CELL_Y] + (sub >> 1)
            ints[count, _PIXEL] = j
            ints[count, _CELL_X] = sx
            ints[count, _CELL_Y] = sy
            ints[count, _REFINEMENT] = k + 1
            ints[count, _STOP] = finer
            floats[count, _TMIN] = _FRESH
            if reuse_parent:
                span = fine >> (k + 1)
                if cell_x // span == sx and cell_y // span == sy:
                    # The parent ray lies in this sub-cell: continue it from its hit.
                    ints[count, _FINE_X] = cell_x
                    ints[count, _FINE_Y] = cell_y
                    floats[count, _TMIN] = floats[r, _T]
                    ints[count, _PARENT_NORMAL] = ints[r, _NORMAL]
                else:
                    ints[count, _FINE_X], ints[count, _FINE_Y] = designated_cell(
                        sx, sy, k + 1, fine, patterns[j])
            count += 1
    return count


@borrowing
def add_chunk_samples(view: OctreeView, refinement: Refinement, out: PixelOutputs,
                      maps: RefinementMaps, row0: int, count: int,
                      records: ChunkRecords) -> None:
    """The chunk's ``count`` pixels' samples added up into their outputs (rows from
    ``row0``). One call for the chunk: a call per pixel passed every array of its bundles
    again each time. ``refine_records`` has asked for each sample's colour as it found
    the ray needs no refinement, so the colours are loaded, or on their way, by now."""
    for j in range(count):
        add_pixel_samples(view, refinement, out, maps, records.places[j, 0] - row0,
                          records.places[j, 1], j, records)


@njit(cache=True, nogil=True, inline="always")
def add_pixel_samples(view: OctreeView, refinement: Refinement, out: PixelOutputs,
                      maps: RefinementMaps, i: int, col: int, j: int,
                      records: ChunkRecords) -> None:
    """Pixel ``j``'s rays added up into its outputs (row ``i``, column ``col``), depth first
    from its first ray with the last sub-cell's rays first: the order a pixel refined on
    its own adds them in (a stack of its pending rays), so the sums round alike."""
    ints, floats, stack = records.ints, records.floats, records.stack
    depth, facing = view.depth, view.facing
    colors = view_colours(view)
    reuse_parent = refinement.reuse_parent
    r_sum = 0.0
    g_sum = 0.0
    b_sum = 0.0
    nx = 0.0
    ny = 0.0
    nz = 0.0
    t_sum = 0.0
    t_weight = 0.0
    rays = 0
    hits = 0
    steps_sum = 0
    refined = 0
    discarded = 0  # rays that hit but give no sample
    finest = 127
    stack[0] = j  # the pixel's first ray is record j
    n = 1
    while n > 0:
        n -= 1
        r = stack[n]
        fresh = floats[r, _TMIN] == _FRESH
        if fresh:
            rays += 1
        steps_sum += ints[r, _STEPS]
        node = ints[r, _NODE]
        if node == MISS:
            if not fresh:
                discarded += 1  # a continued ray: it hit its parent's node
            continue
        child = ints[r, _CHILD]
        if child >= 0:
            # Refined: this sample is discarded, its cell covered by four finer rays.
            refined += 1
            if not reuse_parent:
                discarded += 1
            for sub in range(4):
                stack[n] = child + sub
                n += 1
            continue
        cells = 1 << ints[r, _REFINEMENT]
        weight = 1.0 / (cells * cells)
        dx, dy, dz = floats[r, _DX], floats[r, _DY], floats[r, _DZ]
        hits += 1
        cr, cg, cb = seen_rgb(colors, facing, node, dx, dy, dz)
        r_sum += weight * cr
        g_sum += weight * cg
        b_sum += weight * cb
        t_sum += weight * floats[r, _T]
        t_weight += weight
        ax, ay, az = normal_from_code(ints[r, _NORMAL])
        nx += weight * ax
        ny += weight * ay
        nz += weight * az
        lod = depth - ints[r, _LEVEL]
        if lod < finest:
            finest = lod
    maps.refined[i, col] = refined
    maps.discarded[i, col] = discarded
    store_pixel(out.color[i], out.depth[i], out.normal[i], out.rays[i], out.hits[i],
                out.steps[i], out.lod[i], col, r_sum, g_sum, b_sum, t_sum, t_weight, nx, ny,
                nz, rays, hits, steps_sum, finest)
