"""Shared helpers of the terrain tests (tests/scene/test_terrain_*.py): small procedural
heightmaps and tree models, and per-column voxel ranges of a scene."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from voxfield.scene.terrain.dem import Heightmap
from voxfield.scene.voxel_scene import VoxelScene

TRUNK = (0.30, 0.15, 0.05)
LEAF = (0.05, 0.50, 0.10)


def column_ranges(scene: VoxelScene, f: int):
    """Per-column (min y, max y, count) of a scene's voxels, from the coords alone."""
    c = scene.coords
    key = c[:, 2] * f + c[:, 0]
    lo = np.full(f * f, np.iinfo(np.int64).max)
    hi = np.full(f * f, np.iinfo(np.int64).min)
    np.minimum.at(lo, key, c[:, 1])
    np.maximum.at(hi, key, c[:, 1])
    count = np.bincount(key, minlength=f * f)
    return lo.reshape(f, f), hi.reshape(f, f), count.reshape(f, f)


def tree(height: int = 6, crown: int = 1) -> VoxelScene:
    """A procedural tree: a 1×1 trunk and a (2·crown+1)² square crown on top."""
    trunk = [(0, y, 0) for y in range(height)]
    leaves = [
        (x, y, z)
        for y in range(height, height + 2)
        for x in range(-crown, crown + 1)
        for z in range(-crown, crown + 1)
    ]
    coords = np.array(trunk + leaves) + [crown, 0, crown]
    color = np.array([TRUNK] * len(trunk) + [LEAF] * len(leaves))
    return VoxelScene(coords, color, name="tree")


def hills(f: int = 64, seed: int = 0, amplitude: float = 6.0) -> Heightmap:
    """Smooth random hills in metres with 1 m spacing (true scale: 1 m = 1 voxel)."""
    rng = np.random.default_rng(seed)
    z = ndimage.gaussian_filter(rng.standard_normal((f, f)), 6, mode="wrap")
    z = amplitude * (z - z.min()) / (z.max() - z.min())
    return Heightmap(z, spacing=(1.0, 1.0), name="hills")
