"""Primary-ray generation from a packed camera, shared by every renderer and by benchmarks.

Camera parameters are a float64 array: ``[kind, position(3), forward(3), right(3), up(3),
half_width, half_height]``; kind 0 is pinhole (half sizes are tangents of the half field of
view), kind 1 orthographic (half sizes in world units), kind 2 octahedral: a light probe's
full sphere of directions from ``position``, image position (x, y) / size being the
octahedral (u, v) of ``kernels.octahedral`` — so every renderer bakes probe texels straight
from the octree, with no cube-map resampling.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.octahedral import oct_decode
from voxfield.kernels.sampling import divide, subpixel

PINHOLE = 0
ORTHOGRAPHIC = 1
OCTAHEDRAL = 2
#: Cone spread of one texel of an R×R octahedral map: the side of a square of the mean
#: texel solid angle, sqrt(4π) / R, per unit distance.
OCTAHEDRAL_TEXEL_SPREAD = math.sqrt(4.0 * math.pi)
CAMERA_PARAMS = 15


@njit(cache=True, nogil=True, inline="always")
def camera_ray(
    cam: np.ndarray, x: float, y: float, width: int, height: int
) -> tuple[float, float, float, float, float, float]:
    """Ray through image position (x, y) in pixels (0, 0 is the top-left corner); inlined,
    as a call per sample was 9 % of a 16-ray pixel's time."""
    if cam[0] == OCTAHEDRAL:
        dx, dy, dz = oct_decode(x / width, y / height)
        return cam[1], cam[2], cam[3], dx, dy, dz
    a, b = image_plane(cam, x, y, width, height)
    if cam[0] == ORTHOGRAPHIC:
        ox = cam[1] + a * cam[7] + b * cam[10]
        oy = cam[2] + a * cam[8] + b * cam[11]
        oz = cam[3] + a * cam[9] + b * cam[12]
        return ox, oy, oz, cam[4], cam[5], cam[6]
    dx, dy, dz = pinhole_direction(cam, a, b)
    return cam[1], cam[2], cam[3], dx, dy, dz


@njit(cache=True, nogil=True, inline="always")
def pinhole_direction(cam: np.ndarray, a: float, b: float) -> tuple[float, float, float]:
    """The unit direction of a pinhole camera through image-plane point ``(a, b)`` (in
    tangents of the half field of view): ``camera_ray``'s, for callers that loop over
    pixels of one camera kind."""
    dx = cam[4] + a * cam[7] + b * cam[10]
    dy = cam[5] + a * cam[8] + b * cam[11]
    dz = cam[6] + a * cam[9] + b * cam[12]
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    return dx * inv, dy * inv, dz * inv


@njit(cache=True, nogil=True, inline="always")
def image_plane(cam: np.ndarray, x: float, y: float, width: int,
                height: int) -> tuple[float, float]:
    """Image position (x, y) in pixels as the image-plane point ``(a, b)`` of ``camera_ray``."""
    return ((divide(2.0 * x, width) - 1.0) * cam[13],
            (1.0 - divide(2.0 * y, height)) * cam[14])


@njit(cache=True, nogil=True)
def pixel_cone(cam: np.ndarray, height: int) -> tuple[float, float]:
    """Cone radius at the origin and spread per unit distance covering one pixel."""
    if cam[0] == OCTAHEDRAL:
        return 0.0, OCTAHEDRAL_TEXEL_SPREAD / height
    pixel = 2.0 * cam[14] / height
    if cam[0] == ORTHOGRAPHIC:
        return pixel, 0.0
    return 0.0, pixel


@njit(parallel=True, cache=True)
def camera_ray_arrays(
    cam: np.ndarray, width: int, height: int, side: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """All rays of an image with side×side CMJ samples per pixel, pixel-major order."""
    n = width * height * side * side
    origins = np.empty((n, 3))
    directions = np.empty((n, 3))
    spp = side * side
    for row in prange(height):
        for col in range(width):
            pixel = row * width + col
            for s in range(spp):
                fx, fy = subpixel(pixel, s, side, seed)
                ox, oy, oz, dx, dy, dz = camera_ray(cam, col + fx, row + fy, width, height)
                k = pixel * spp + s
                origins[k, 0] = ox
                origins[k, 1] = oy
                origins[k, 2] = oz
                directions[k, 0] = dx
                directions[k, 1] = dy
                directions[k, 2] = dz
    return origins, directions
