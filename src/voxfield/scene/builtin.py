"""Built-in procedural scenes: no files needed, for the demo and small tests."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from voxfield.checks import integer_in
from voxfield.errors import VoxfieldError
from voxfield.scene.shadow_box import shadow_box
from voxfield.scene.voxel_scene import VoxelScene


def pillars(size: int = 64) -> VoxelScene:
    """Rolling heightfield with a ring of pillars and a floating bar: depth, thin parts, colour."""
    size = integer_in(size, "the pillars scene's size", 8)
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    s = size / 64.0
    height = (6 * s + 4 * s * np.sin(x / (7 * s)) + 3 * s * np.cos(z / (9 * s))).astype(np.int64)
    height = np.maximum(height, 1)
    cx = cz = size / 2
    angle = np.arctan2(z - cz, x - cx)
    radius = np.hypot(x - cx, z - cz)
    pillar = (np.abs(radius - size * 0.32) < 2.2 * s) & (np.cos(8 * angle) > 0.8)
    height = np.where(pillar, height + int(22 * s), height)
    counts = height.ravel()
    cols = np.repeat(np.arange(size * size), counts)
    y = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    coords = np.stack([cols // size, y, cols % size], axis=1)
    t = y / max(1, counts.max())
    color = np.stack([0.25 + 0.6 * t, 0.45 + 0.3 * np.sin(cols % 7), 0.7 - 0.5 * t], axis=1)
    color[np.repeat(pillar.ravel(), counts)] = (0.8, 0.75, 0.6)
    bar_x = np.arange(int(size * 0.15), int(size * 0.85))
    bar = np.stack([bar_x, np.full_like(bar_x, int(24 * s)), np.full_like(bar_x, size // 2)], 1)
    bar_color = np.tile([[0.9, 0.1, 0.1]], (len(bar), 1))
    return VoxelScene(
        np.concatenate([coords, bar]), np.clip(np.concatenate([color, bar_color]), 0, 1),
        name="pillars",
    ).dedupe()


def menger(level: int = 3) -> VoxelScene:
    """Menger sponge: holes at every scale, the worst case for LOD (high variance everywhere)."""
    level = integer_in(level, "menger level", 1, 5)
    size = 3**level
    idx = np.arange(size)
    x, y, z = np.meshgrid(idx, idx, idx, indexing="ij")
    keep = np.ones_like(x, dtype=bool)
    for _ in range(level):
        centre = ((x % 3) == 1).astype(int) + ((y % 3) == 1) + ((z % 3) == 1)
        keep &= centre < 2
        x, y, z = x // 3, y // 3, z // 3
    coords = np.argwhere(keep)
    color = 0.2 + 0.7 * coords / max(1, size - 1)
    return VoxelScene(coords, color, name=f"menger{level}")


def sphere(radius: int = 20) -> VoxelScene:
    """A solid sphere with a latitude colour band: smooth silhouettes and curved normals."""
    radius = integer_in(radius, "sphere radius", 1)
    idx = np.arange(-radius, radius)
    x, y, z = np.meshgrid(idx, idx, idx, indexing="ij")
    d2 = (x + 0.5) ** 2 + (y + 0.5) ** 2 + (z + 0.5) ** 2
    shell = (d2 <= radius**2) & (d2 > (radius - 3) ** 2)
    coords = np.argwhere(shell)
    band = np.abs(coords[:, 1] - radius) < radius / 4
    color = np.where(band[:, None], [0.9, 0.6, 0.1], [0.2, 0.4, 0.8])
    return VoxelScene(coords, color, name="sphere")


def cornell(size: int = 32) -> VoxelScene:
    """A voxel Cornell box (red left, green right, white elsewhere, emissive ceiling patch)."""
    size = integer_in(size, "the Cornell box's size", 8)
    n = size
    idx = np.arange(n)
    x, y, z = np.meshgrid(idx, idx, idx, indexing="ij")
    wall = (x == 0) | (x == n - 1) | (y == 0) | (y == n - 1) | (z == 0)
    b = n // 4
    block = (x >= b) & (x < 2 * b) & (z >= b) & (z < 2 * b) & (y < 2 * b)
    coords = np.argwhere(wall | block)
    color = np.full((len(coords), 3), 0.73, np.float32)
    color[coords[:, 0] == 0] = (0.63, 0.06, 0.05)
    color[coords[:, 0] == n - 1] = (0.14, 0.45, 0.09)
    light = (coords[:, 1] == n - 1) & (np.abs(coords[:, 0] - n / 2 + 0.5) < n / 8) & (
        np.abs(coords[:, 2] - n / 2 + 0.5) < n / 8
    )
    emission = np.zeros_like(color)
    emission[light] = 4.0
    color[light] = 1.0
    return VoxelScene(coords, color, emission=emission, name="cornell")


BUILTIN_SCENES: dict[str, Callable[[], VoxelScene]] = {
    "pillars": pillars,
    "menger": menger,
    "sphere": sphere,
    "cornell": cornell,
    "shadowbox": shadow_box,
}


def builtin_scene(name: str) -> VoxelScene:
    """A built-in scene by name (see ``BUILTIN_SCENES``)."""
    try:
        return BUILTIN_SCENES[name]()
    except KeyError:
        known = ", ".join(sorted(BUILTIN_SCENES))
        raise VoxfieldError(f"no built-in scene {name!r}; choose one of {known}") from None
