"""Primary-ray kernels: supersampled, counted, LOD-limited tracing of pixels and of ray batches."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.beam import start_distance
from voxfield.kernels.camera_rays import camera_ray, pixel_cone
from voxfield.kernels.facing_colour import seen_rgb
from voxfield.kernels.sampling import cmj_sample, pixel_pattern
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


@njit(parallel=True, cache=True, nogil=True)
def render_pixels(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    side: int, seed: int,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_scale: float, colors: np.ndarray, facing: np.ndarray,
    beam_bound: np.ndarray, block: int,
    out_color: np.ndarray, out_depth: np.ndarray, out_normal: np.ndarray,
    out_rays: np.ndarray, out_hits: np.ndarray, out_steps: np.ndarray, out_lod: np.ndarray,
) -> None:
    """Trace the listed pixels (flat indices) with side×side samples each, in list order
    (so a list in tile order keeps neighbouring rays together); pixel ``pixels[k]`` goes to
    entry ``pixels[k] - out_base`` of every flat ``out_*`` array, or to entry ``k`` when
    ``out_base`` is negative.

    ``cone_scale`` > 0 stops descent where a node is no larger than ``cone_scale`` times the
    sub-sample footprint; 0 descends to ``stop_level``. Hits are coloured by
    ``kernels.facing_colour.seen_rgb`` from ``colors`` and ``facing``; misses contribute black.
    Rays of the ``block``×``block`` pixel block ``(by, bx)`` start at ``beam_bound[by, bx]``
    (``kernels.beam``; zeros start every ray at the camera).
    """
    n = pixels.shape[0]
    chunk = 64
    for c in prange((n + chunk - 1) // chunk):
        render_pixel_chunk(
            cam, width, height, pixels, out_base, c * chunk, min(n, (c + 1) * chunk), side, seed,
            inner_nodes, depth, stop_level, cone_scale, colors, facing, beam_bound, block,
            out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod,
        )


@njit(cache=True, nogil=True)
def render_pixel_chunk(
    cam: np.ndarray, width: int, height: int, pixels: np.ndarray, out_base: int,
    first: int, last: int, side: int, seed: int,
    inner_nodes: np.ndarray, depth: int,
    stop_level: int, cone_scale: float, colors: np.ndarray, facing: np.ndarray,
    beam_bound: np.ndarray, block: int,
    out_color: np.ndarray, out_depth: np.ndarray, out_normal: np.ndarray,
    out_rays: np.ndarray, out_hits: np.ndarray, out_steps: np.ndarray, out_lod: np.ndarray,
) -> None:
    """Pixels ``first..last-1`` of ``render_pixels``: one thread's serial share.

    The traversal is inlined here, never straight into a ``prange`` body: Numba's parfor
    pass hoists the inlined loop's constant initialisations out of the parallel loop.
    """
    spp = side * side
    radius, spread = pixel_cone(cam, height)
    radius *= cone_scale / side
    spread *= cone_scale / side
    scratch = new_scratch(depth)
    for i in range(first, last):
        pixel = pixels[i]
        row = pixel // width
        col = pixel - row * width
        r = 0.0
        g = 0.0
        b = 0.0
        nx = 0.0
        ny = 0.0
        nz = 0.0
        t_sum = 0.0
        hits = 0
        steps_sum = 0
        finest = 127
        # ``subpixel`` per sample, with the pixel's pattern hashed once per pixel.
        pattern = pixel_pattern(pixel, seed) if side > 1 else 0
        t_start = start_distance(beam_bound[row // block, col // block])
        for s in range(spp):
            if side == 1:
                fx, fy = 0.5, 0.5
            else:
                fx, fy = cmj_sample(s, side, side, pattern)
            ox, oy, oz, dx, dy, dz = camera_ray(cam, col + fx, row + fy, width, height)
            node, level, t, normal, steps = trace_ray(
                ox, oy, oz, dx, dy, dz, t_start, math.inf,
                inner_nodes, depth, stop_level, radius, spread, scratch,
            )
            steps_sum += steps
            if node == MISS:
                continue
            hits += 1
            cr, cg, cb = seen_rgb(colors, facing, node, dx, dy, dz)
            r += cr
            g += cg
            b += cb
            t_sum += t
            ax, ay, az = normal_from_code(normal)
            nx += ax
            ny += ay
            nz += az
            lod = depth - level
            if lod < finest:
                finest = lod
        store_pixel(out_color, out_depth, out_normal, out_rays, out_hits, out_steps, out_lod,
                    i if out_base < 0 else pixel - out_base, r / spp, g / spp, b / spp, t_sum,
                    hits, nx, ny, nz, spp, hits, steps_sum, finest)
