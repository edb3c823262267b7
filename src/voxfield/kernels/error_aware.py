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

from voxfield.kernels.beam import start_distance
from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.bundles import BeamBounds, OctreeView, PixelOutputs, view_colours
from voxfield.kernels.camera_rays import camera_ray, pixel_cone
from voxfield.kernels.colour import node_rgb
from voxfield.kernels.error_lookup import colour_error, oct_error, sh_error, sh_evaluate
from voxfield.kernels.facing_colour import seen_rgb
from voxfield.kernels.node_descriptor import descriptor_first_child
from voxfield.kernels.primary import normal_from_code, store_pixel
from voxfield.kernels.sampling import cmj_sample, hash_u32, pixel_pattern
from voxfield.kernels.scheduling import interleaved
from voxfield.kernels.surface_approach import trace_over_columns
from voxfield.kernels.traversal import MISS, new_scratch, trace_ray

ENCODING_OCT = 0
ENCODING_SH = 1
MAX_REFINEMENTS = 3
_QUEUE = 1 + 3 * MAX_REFINEMENTS + 4  # LIFO: at most 3 siblings wait per level
_FRESH = -1.0  # queue marker: a new ray, not a continued parent ray


@njit(cache=True, nogil=True)
def mask_error(
    encoding: int, oct_map: np.ndarray, sh: np.ndarray, mask: int, x: float, y: float, z: float
) -> float:
    if encoding == ENCODING_SH:
        return sh_error(sh, mask, x, y, z)
    return oct_error(oct_map, mask, x, y, z)


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
    """
    descriptor = inner_nodes[node]
    mask = descriptor & 0xFF
    error = mask_error(encoding, oct_map, sh, mask, x, y, z)
    if decay == 0.0 or level + 1 >= depth:
        return error
    first = descriptor_first_child(descriptor)
    total = 0.0
    count = 0
    for octant in range(8):
        if (mask >> octant) & 1:
            child_mask = inner_nodes[first + count] & 0xFF
            total += mask_error(encoding, oct_map, sh, child_mask, x, y, z)
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
    cam: np.ndarray, width: int, height: int, row0: int, row1: int, seed: int,
    view: OctreeView, refinement: Refinement, model: ErrorModel, beam: BeamBounds,
    out: PixelOutputs, maps: RefinementMaps, columns, threads: int = 1,
) -> None:
    """Trace rows ``[row0, row1)``, dealt out to the ``threads`` in turn
    (``kernels.scheduling``); ``refinement.cone_scale`` > 0 picks the base LOD by pixel
    cone; ``model.lighting_aware`` adds the bright-flag colour error to the geometric one.
    Rays at a fixed level cross the air in the column-top pyramid ``columns`` first
    (``kernels.surface_approach``; ``no_column_tops()`` for none), as the LOD renderer's do."""
    rows = row1 - row0
    for k in prange(rows):
        row = row0 + interleaved(k, rows, threads)
        render_error_aware_row(cam, width, height, row0, seed, view, refinement, model, beam,
                               out, maps, row, columns)


@njit(cache=True, nogil=True)
def render_error_aware_row(
    cam: np.ndarray, width: int, height: int, row0: int, seed: int, view: OctreeView,
    refinement: Refinement, model: ErrorModel, beam: BeamBounds, out: PixelOutputs,
    maps: RefinementMaps, row: int, columns,
) -> None:
    """One row of ``render_error_aware_rows``: its scratch, then ``trace_error_aware_row``."""
    trace_error_aware_row(cam, width, height, row0, seed, view, refinement, model, beam, out,
                          maps, row, columns, new_scratch(view.depth), new_ray_queue())


@njit(cache=True, nogil=True)
def new_ray_queue():
    """The pending rays of one pixel: cell, refinement, stop level, finest cell, start and
    entry face."""
    return (np.empty(_QUEUE, np.int64), np.empty(_QUEUE, np.int64),
            np.empty(_QUEUE, np.int64), np.empty(_QUEUE, np.int64),
            np.empty(_QUEUE, np.int64), np.empty(_QUEUE, np.int64),
            np.empty(_QUEUE, np.float64), np.empty(_QUEUE, np.int64))


@borrowing
def trace_error_aware_row(
    cam: np.ndarray, width: int, height: int, row0: int, seed: int, view: OctreeView,
    refinement: Refinement, model: ErrorModel, beam: BeamBounds, out: PixelOutputs,
    maps: RefinementMaps, row: int, columns, scratch, queue,
) -> None:
    """One row of ``render_error_aware_rows`` with the caller's scratch and ray queue (the
    traversal is inlined here, never straight into a ``prange`` body, where Numba's parfor
    pass would hoist its initialisations)."""
    inner_nodes, depth, facing = view.inner_nodes, view.depth, view.facing
    colors = view_colours(view)
    base_stop_level, cone_scale, max_refinements, reuse_parent = refinement
    (threshold, decay, encoding, oct_map, sh, children_sh, lighting_aware, bright_ratio,
     light_map, class_of, symmetry_of, symmetries, colour_weight, colour_error,
     colour_to_voxels, context) = model
    beam_bound, block = beam
    out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod = out
    out_refined, out_discarded = maps
    fine = 1 << max_refinements  # finest cells per pixel side
    radius, spread = pixel_cone(cam, height)
    radius *= cone_scale
    spread *= cone_scale
    # q_fx, q_fy: (reuse) the finest cell the ray goes through; q_tmin: where a continued
    # ray resumes
    q_x, q_y, q_k, q_stop, q_fx, q_fy, q_tmin, q_normal = queue
    for col in range(width):
        pixel = row * width + col
        pattern = pixel_pattern(pixel, seed)
        t_start = start_distance(beam_bound[row // block, col // block])
        r = 0.0
        g = 0.0
        b = 0.0
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
        q_x[0] = 0
        q_y[0] = 0
        q_k[0] = 0
        q_stop[0] = base_stop_level
        q_tmin[0] = _FRESH
        if reuse_parent:
            q_fx[0], q_fy[0] = designated_cell(0, 0, 0, fine, pattern)
        n = 1
        while n > 0:
            n -= 1
            cx = q_x[n]
            cy = q_y[n]
            k = q_k[n]
            stop = q_stop[n]
            tmin = q_tmin[n]
            cell_x = q_fx[n]
            cell_y = q_fy[n]
            cells = 1 << k
            if reuse_parent:
                fx, fy = cell_sample(cell_x, cell_y, fine, pattern)
            elif cells == 4:
                fx, fy = cmj_sample(cy * 4 + cx, 4, 4, pattern)
            else:
                fx = (cx + 0.5) / cells
                fy = (cy + 0.5) / cells
            ox, oy, oz, dx, dy, dz = camera_ray(cam, col + fx, row + fy, width, height)
            if k == 0 and cone_scale > 0.0:
                node, level, t, normal, steps = trace_ray(
                    ox, oy, oz, dx, dy, dz, max(tmin, t_start), math.inf, inner_nodes, depth,
                    stop, radius, spread, scratch)
            else:
                node, level, t, normal, steps = trace_over_columns(
                    ox, oy, oz, dx, dy, dz, max(tmin, t_start), math.inf, inner_nodes, depth,
                    stop, scratch, columns)
            if tmin == _FRESH:
                rays += 1
            elif normal < 0 and t == tmin:
                normal = q_normal[n]  # entered through the parent's face
            steps_sum += steps
            if node == MISS:
                if tmin != _FRESH:
                    discarded += 1  # a continued ray: it hit its parent's node
                continue
            if k < max_refinements and level < depth:
                if children_sh.shape[0] > 0:
                    error = node_error_precomputed(node, level, depth, inner_nodes, decay,
                                                   sh, children_sh, dx, dy, dz)
                else:
                    error = node_error(node, level, depth, inner_nodes, decay, encoding,
                                       oct_map, sh, dx, dy, dz)
                if context.shape[0] > 0 and context[node]:
                    error = 0.0  # inside a repeating surface: a shift, not a silhouette
                if lighting_aware:
                    error += lighting_node_error(
                        node, level, depth, inner_nodes, decay, colors, bright_ratio,
                        light_map, class_of, symmetry_of, symmetries, dx, dy, dz)
                colour_part = 0.0
                if colour_weight > 0.0:
                    colour_part = colour_weight * colour_error[node]
                    error += colour_part
                if error > threshold:
                    # Colour alone over the threshold: finer LODs average it again, so
                    # the sub-rays may go straight to the voxels.
                    finer = depth if colour_to_voxels and colour_part > threshold else level + 1
                    # Discard this sample; its cell is covered by four finer rays.
                    refined += 1
                    if not reuse_parent:
                        discarded += 1
                    for sub in range(4):
                        sx = 2 * cx + (sub & 1)
                        sy = 2 * cy + (sub >> 1)
                        q_x[n] = sx
                        q_y[n] = sy
                        q_k[n] = k + 1
                        q_stop[n] = finer
                        q_tmin[n] = _FRESH
                        if reuse_parent:
                            span = fine >> (k + 1)
                            if cell_x // span == sx and cell_y // span == sy:
                                # The parent ray lies in this sub-cell: continue it.
                                q_fx[n] = cell_x
                                q_fy[n] = cell_y
                                q_tmin[n] = t
                                q_normal[n] = normal
                            else:
                                q_fx[n], q_fy[n] = designated_cell(sx, sy, k + 1, fine,
                                                                   pattern)
                        n += 1
                    continue
            weight = 1.0 / (cells * cells)
            hits += 1
            cr, cg, cb = seen_rgb(colors, facing, node, dx, dy, dz)
            r += weight * cr
            g += weight * cg
            b += weight * cb
            t_sum += weight * t
            t_weight += weight
            ax, ay, az = normal_from_code(normal)
            nx += weight * ax
            ny += weight * ay
            nz += weight * az
            lod = depth - level
            if lod < finest:
                finest = lod
        i = row - row0
        out_refined[i, col] = refined
        out_discarded[i, col] = discarded
        store_pixel(out_color[i], out_depth[i], out_normal[i], out_rays[i], out_hits[i],
                    out_steps[i], out_lod[i], col, r, g, b, t_sum, t_weight, nx, ny, nz,
                    rays, hits, steps_sum, finest)
