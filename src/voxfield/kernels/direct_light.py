"""Direct lighting with importance-sampled shadow rays and three ways to pick their LOD
(EA thesis §3.2.2, figs 3.4–3.6).

A surface point x is lit by the emitting voxel faces: for a Lambertian surface of albedo ρ,
``L(x) = ρ/π ∫ L_e(y) V(x, y) cosθ_x cosθ_y / r² dA_y``. Each sample picks one emitting face
with probability proportional to its emitted luminance (all faces have area 1), a point on it,
and casts one shadow ray towards it: the estimate is
``ρ/π · L_e · V · cosθ_x · cosθ_y / (r² · p(face))`` — inverse-square falloff, as in the thesis.

The shadow ray's LOD:

- ``SHADOW_REFERENCE``: voxels (LOD 0) all the way;
- ``SHADOW_DISTANCE``: the baseline of fig. 3.5b — the LOD grows with the distance ``t`` from
  the ray's origin, ``LOD(t) = floor(log2(1 + t / lod_distance))``, i.e. a cone of radius 1
  and spread ``1 / lod_distance`` in ``trace_ray``; a node is sampled at the distance where
  the ray meets it;
- ``SHADOW_ERROR_AWARE``: as the baseline, but at the node it hits the error
  ``E_N(r) = e(r, N) + d · mean_c e(r, c)`` of the error table is checked (``node_error``);
  above the threshold the node is not accepted (as occluder or as light): the ray looks
  inside it one LOD finer (only the segment inside the node, checked again at every hit),
  and where it passes through it goes on at its distance LOD. So the LOD is refined where the
  error says so, and only there (fig. 3.6).

A ray that meets a node holding emitting voxels (and does not refine it) has reached the
light: at a coarse LOD the light is the node that contains it. With every node refined
(threshold below 0) the error-aware ray finds exactly the reference's first voxel. Shadow
rays start ``SURFACE_OFFSET`` off the surface and stop just short of the sampled point.

Per shadow ray the kernel counts traversal steps, traversals (a refinement re-traverses from
the root, as a new ray would) and the LOD used: the finest LOD the ray sampled — that of the
node it stopped at, of any node it refined into, or, where it met nothing, the LOD at its end.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from voxfield.kernels.bundles import PixelOutputs
from voxfield.kernels.camera_rays import camera_ray
from voxfield.kernels.colour import node_rgb
from voxfield.kernels.error_aware import node_error
from voxfield.kernels.primary import normal_from_code, store_pixel
from voxfield.kernels.sampling import cmj_sample, hash_u32, pixel_pattern
from voxfield.kernels.scheduling import interleaved
from voxfield.kernels.traversal import (
    MISS,
    box_interval,
    flush_uninvertible,
    new_scratch,
    safe_inverse,
    trace_ray,
)

SHADOW_REFERENCE = 0
SHADOW_DISTANCE = 1
SHADOW_ERROR_AWARE = 2
#: Shadow rays start this far (voxels) off the surface they leave.
SURFACE_OFFSET = 1e-3
#: Most traversals one shadow ray may make (far more than refining every node it meets).
MAX_SHADOW_PASSES = 1 << 20
#: LOD recorded where no shadow ray was cast.
NO_LOD = -1
#: Decorrelates a pixel's light samples from its sub-pixel positions.
_LIGHT_STREAM = 0x68E31DA4


class ShadowScene(NamedTuple):
    """What a shadow ray reads of the octree: packed descriptors, depth, every node's corner
    in its level's node units, and which nodes hold emitting voxels (1) or not (0)."""

    inner_nodes: np.ndarray
    depth: int
    node_coord: np.ndarray
    node_is_light: np.ndarray


class Emitters(NamedTuple):
    """The emitting voxel faces a light sample picks from (``render.direct_light``'s
    ``EmitterFaces``): corner, axis, outward sign, radiance and the luminance CDF."""

    corner: np.ndarray
    axis: np.ndarray
    sign: np.ndarray
    radiance: np.ndarray
    cdf: np.ndarray


class ShadowLod(NamedTuple):
    """How shadow rays pick their LOD (module docstring): the mode, the baseline's LOD-1
    distance, and the error-aware refinement's depth limit, test and error table."""

    mode: int
    lod_distance: float
    max_refinements: int
    threshold: float
    decay: float
    encoding: int
    oct_map: np.ndarray
    sh: np.ndarray


class ShadowMaps(NamedTuple):
    """Per-pixel output rows beside the image's (``bundles.PixelOutputs``): the shadow rays
    cast, their traversals, steps, mean LOD used and refinements."""

    shadow_rays: np.ndarray
    shadow_traversals: np.ndarray
    shadow_steps: np.ndarray
    shadow_lod: np.ndarray
    refinements: np.ndarray


@njit(cache=True, nogil=True)
def distance_lod(t: float, lod_distance: float, depth: int) -> int:
    """``floor(log2(1 + t / lod_distance))``, at most ``depth``: the LOD the baseline samples
    at distance ``t`` (LOD ``k`` starts at ``(2^k - 1) · lod_distance``)."""
    lod = 0
    while lod < depth and float(1 << (lod + 1)) <= 1.0 + t / lod_distance:
        lod += 1
    return lod


@njit(cache=True, nogil=True)
def new_shadow_scratch(depth: int):
    """Per-thread scratch of shadow rays: the traversal's (``new_scratch``) and the
    refinement frames (stop level, end time), one per LOD a ray can refine."""
    return new_scratch(depth), np.empty(depth + 2, np.int64), np.empty(depth + 2, np.float64)


@njit(cache=True, nogil=True)
def trace_shadow_ray(
    ox: float, oy: float, oz: float, dx: float, dy: float, dz: float, tmax: float,
    scene: ShadowScene, lod: ShadowLod, work,
) -> tuple[bool, int, int, int, int]:
    """Whether the segment ``(0, tmax)`` of the ray reaches the light unblocked.

    Returns ``(visible, steps, traversals, lod_used, refinements)``. Frames: frame 0 is the
    ray at its base LOD up to ``tmax``; a refinement pushes a frame that covers only the
    refined node's interval at one LOD finer; a frame whose segment is empty pops, and the
    frame below goes on from where it ended. ``work`` comes from ``new_shadow_scratch``.
    """
    inner_nodes, depth, node_coord, node_is_light = scene
    mode, lod_distance, max_refinements, threshold, decay, encoding, oct_map, sh = lod
    scratch, frame_stop, frame_end = work
    use_distance = mode != SHADOW_REFERENCE
    radius = 1.0 if use_distance else 0.0
    spread = 1.0 / lod_distance if use_distance else 0.0
    # The same inverses as trace_ray's, so a refined node's exit time is bit-identical to the
    # entry time of whatever follows it.
    ix = safe_inverse(flush_uninvertible(dx))
    iy = safe_inverse(flush_uninvertible(dy))
    iz = safe_inverse(flush_uninvertible(dz))
    frame_stop[0] = depth
    frame_end[0] = tmax
    frames = 1
    t = 0.0
    steps = 0
    traversals = 0
    refinements = 0
    finest = depth + 1
    # Every pass pushes a finer frame, pops one with ``t`` moved past a node, or returns, so
    # the loop ends; the bound only guards against a broken octree.
    for _ in range(MAX_SHADOW_PASSES):
        if frames == 0:
            return True, steps, traversals, finest, refinements
        f = frames - 1
        base = f == 0
        node, level, t_hit, _normal, n = trace_ray(
            ox, oy, oz, dx, dy, dz, t, frame_end[f], inner_nodes, depth, frame_stop[f],
            radius if base else 0.0, spread if base else 0.0, scratch,
        )
        steps += n
        traversals += 1
        if node == MISS:
            if base:
                end_lod = distance_lod(frame_end[0], lod_distance, depth) if use_distance else 0
            else:
                end_lod = depth - frame_stop[f]
            finest = min(finest, end_lod)
            t = frame_end[f]
            frames -= 1
            continue
        finest = min(finest, depth - level)
        if mode == SHADOW_ERROR_AWARE and level < depth and f < max_refinements:
            error = node_error(node, level, depth, inner_nodes, decay, encoding, oct_map, sh,
                               dx, dy, dz)
            if error > threshold:
                size = float(1 << (depth - level))
                _enter, leave, _axis = box_interval(
                    ox, oy, oz, dx, dy, dz, ix, iy, iz, node_coord[node, 0] * size,
                    node_coord[node, 1] * size, node_coord[node, 2] * size, size,
                )
                if leave > t_hit:
                    frame_stop[frames] = level + 1
                    frame_end[frames] = min(leave, frame_end[f])
                    frames += 1
                    t = t_hit
                    refinements += 1
                    finest = min(finest, depth - level - 1)
                    continue
        # Accepted: the node is the light (at a coarse LOD, the node holding it) or blocks it.
        return node_is_light[node] != 0, steps, traversals, finest, refinements
    return False, steps, traversals, finest, refinements


@njit(cache=True, nogil=True)
def pick_face(face_cdf: np.ndarray, u: float) -> int:
    """The face whose slice of the cumulative distribution holds ``u`` (binary search)."""
    lo = 0
    hi = face_cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if u < face_cdf[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True, nogil=True)
def light_sample(
    px: float, py: float, pz: float, nx: float, ny: float, nz: float,
    u: float, v: float, emitters: Emitters, scene: ShadowScene, lod: ShadowLod, work,
) -> tuple[float, float, float, int, int, int, int]:
    """One light sample at surface point p with normal n, for a white (albedo 1) surface.

    ``(u, v)`` in [0, 1)² picks the face (``u`` through the luminance CDF, its remainder
    across the face) and the point on it. Returns ``(r, g, b, steps, traversals, lod_used,
    refinements)``; no ray is cast (lod ``NO_LOD``) when the point and the face do not face
    each other.
    """
    face_corner, face_axis, face_sign, face_radiance, face_cdf = emitters
    face = pick_face(face_cdf, u)
    below = face_cdf[face - 1] if face > 0 else 0.0
    probability = face_cdf[face] - below
    a = min(max((u - below) / probability, 0.0), 1.0)
    axis = face_axis[face]
    sign = face_sign[face]
    qx = face_corner[face, 0]
    qy = face_corner[face, 1]
    qz = face_corner[face, 2]
    plane = 1.0 if sign > 0 else 0.0
    if axis == 0:
        qx += plane
        qy += a
        qz += v
    elif axis == 1:
        qx += a
        qy += plane
        qz += v
    else:
        qx += a
        qy += v
        qz += plane
    ox = px + SURFACE_OFFSET * nx
    oy = py + SURFACE_OFFSET * ny
    oz = pz + SURFACE_OFFSET * nz
    wx = qx - ox
    wy = qy - oy
    wz = qz - oz
    r2 = wx * wx + wy * wy + wz * wz
    if not r2 > 0.0:
        return 0.0, 0.0, 0.0, 0, 0, NO_LOD, 0
    dist = math.sqrt(r2)
    wx /= dist
    wy /= dist
    wz /= dist
    cos_surface = nx * wx + ny * wy + nz * wz
    toward = wx if axis == 0 else (wy if axis == 1 else wz)
    cos_light = -sign * toward
    if cos_surface <= 0.0 or cos_light <= 0.0:
        return 0.0, 0.0, 0.0, 0, 0, NO_LOD, 0
    visible, steps, traversals, lod_used, refinements = trace_shadow_ray(
        ox, oy, oz, wx, wy, wz, dist - SURFACE_OFFSET, scene, lod, work)
    if not visible:
        return 0.0, 0.0, 0.0, steps, traversals, lod_used, refinements
    weight = cos_surface * cos_light / (r2 * probability * math.pi)
    return (face_radiance[face, 0] * weight, face_radiance[face, 1] * weight,
            face_radiance[face, 2] * weight, steps, traversals, lod_used, refinements)


@njit(parallel=True, cache=True, nogil=True)
def render_direct_light_rows(
    cam: np.ndarray, width: int, height: int, row0: int, row1: int, seed: int,
    grid_x: int, grid_y: int, scene: ShadowScene, albedo: np.ndarray, emission: np.ndarray,
    emitters: Emitters, lod: ShadowLod, out: PixelOutputs, maps: ShadowMaps, threads: int = 1,
) -> None:
    """Rows ``[row0, row1)``, dealt out to the ``threads`` in turn (``kernels.scheduling``):
    ``grid_x · grid_y`` samples per pixel, each a primary ray at LOD 0 through a CMJ
    sub-pixel position and, where it hits a surface, one light sample.

    A primary ray that hits an emitter shows its radiance clamped to 1 (display range, so
    the light's edges anti-alias); the pixel is the mean of its samples, clamped to [0, 1].
    """
    rows = row1 - row0
    for k in prange(rows):
        row = row0 + interleaved(k, rows, threads)
        render_direct_light_row(cam, width, height, row0, seed, grid_x, grid_y, scene, albedo,
                                emission, emitters, lod, out, maps, row)


@njit(cache=True, nogil=True)
def render_direct_light_row(
    cam: np.ndarray, width: int, height: int, row0: int, seed: int, grid_x: int, grid_y: int,
    scene: ShadowScene, albedo: np.ndarray, emission: np.ndarray, emitters: Emitters,
    lod: ShadowLod, out: PixelOutputs, maps: ShadowMaps, row: int,
) -> None:
    """One row of ``render_direct_light_rows`` (the traversal is inlined here, never straight
    into a ``prange`` body, where Numba's parfor pass would hoist its initialisations)."""
    inner_nodes, depth, _node_coord, node_is_light = scene
    samples = grid_x * grid_y
    work = new_shadow_scratch(depth)
    i = row - row0
    for col in range(width):
        pattern = pixel_pattern(row * width + col, seed)
        light_pattern = hash_u32(pattern + _LIGHT_STREAM)
        r = 0.0
        g = 0.0
        b = 0.0
        nx_sum = 0.0
        ny_sum = 0.0
        nz_sum = 0.0
        t_sum = 0.0
        hits = 0
        steps_sum = 0
        shadow_traversals = 0
        shadow_steps = 0
        lod_sum = 0
        lod_count = 0
        refinements = 0
        for s in range(samples):
            if samples == 1:
                fx, fy = 0.5, 0.5
            else:
                fx, fy = cmj_sample(s, grid_x, grid_y, pattern)
            ox, oy, oz, dx, dy, dz = camera_ray(cam, col + fx, row + fy, width, height)
            node, level, t, normal, steps = trace_ray(
                ox, oy, oz, dx, dy, dz, 0.0, math.inf, inner_nodes, depth, depth, 0.0, 0.0,
                work[0],
            )
            steps_sum += steps
            if node == MISS:
                continue
            hits += 1
            t_sum += t
            nx, ny, nz = normal_from_code(normal)
            nx_sum += nx
            ny_sum += ny
            nz_sum += nz
            if node_is_light[node]:
                r += min(emission[node, 0], 1.0)
                g += min(emission[node, 1], 1.0)
                b += min(emission[node, 2], 1.0)
                continue
            u, v = cmj_sample(s, grid_x, grid_y, light_pattern)
            lr, lg, lb, n_steps, n_traversals, lod_used, n_refined = light_sample(
                ox + t * dx, oy + t * dy, oz + t * dz, nx, ny, nz, u, v, emitters, scene, lod,
                work,
            )
            ar, ag, ab = node_rgb(albedo, node)
            r += ar * lr
            g += ag * lg
            b += ab * lb
            shadow_traversals += n_traversals
            shadow_steps += n_steps
            refinements += n_refined
            if lod_used != NO_LOD:
                lod_sum += lod_used
                lod_count += 1
        scale = 1.0 / samples
        store_pixel(
            out.color[i], out.depth[i], out.normal[i], out.rays[i], out.hits[i],
            out.steps[i], out.lod[i], col, min(r * scale, 1.0), min(g * scale, 1.0),
            min(b * scale, 1.0), t_sum, hits, nx_sum, ny_sum, nz_sum,
            samples + shadow_traversals, hits, steps_sum + shadow_steps, 0,
        )
        maps.shadow_rays[i, col] = lod_count
        maps.shadow_traversals[i, col] = shadow_traversals
        maps.shadow_steps[i, col] = shadow_steps
        maps.shadow_lod[i, col] = lod_sum / lod_count if lod_count else NO_LOD
        maps.refinements[i, col] = refinements


@njit(parallel=True, cache=True, nogil=True)
def direct_light_points(
    points: np.ndarray, normals: np.ndarray, seed: int, grid_x: int, grid_y: int,
    scene: ShadowScene, emitters: Emitters, lod: ShadowLod,
    out_radiance: np.ndarray, out_steps: np.ndarray, out_lod: np.ndarray,
) -> None:
    """Light reflected by a white surface at given points (``grid_x · grid_y`` CMJ light
    samples each): the camera-independent measure of how much light reaches a region."""
    n = points.shape[0]
    samples = grid_x * grid_y
    chunk = 64
    for c in prange((n + chunk - 1) // chunk):
        work = new_shadow_scratch(scene.depth)
        for k in range(c * chunk, min(n, (c + 1) * chunk)):
            pattern = hash_u32(pixel_pattern(k, seed) + _LIGHT_STREAM)
            r = 0.0
            g = 0.0
            b = 0.0
            steps = 0
            lod_sum = 0
            lod_count = 0
            for s in range(samples):
                u, v = cmj_sample(s, grid_x, grid_y, pattern)
                lr, lg, lb, n_steps, _traversals, lod_used, _refined = light_sample(
                    points[k, 0], points[k, 1], points[k, 2],
                    normals[k, 0], normals[k, 1], normals[k, 2], u, v, emitters, scene, lod,
                    work,
                )
                r += lr
                g += lg
                b += lb
                steps += n_steps
                if lod_used != NO_LOD:
                    lod_sum += lod_used
                    lod_count += 1
            out_radiance[k, 0] = r / samples
            out_radiance[k, 1] = g / samples
            out_radiance[k, 2] = b / samples
            out_steps[k] = steps
            out_lod[k] = lod_sum / lod_count if lod_count else NO_LOD
