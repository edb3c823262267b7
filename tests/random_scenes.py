"""Random voxel scenes for tests (a module of its own: test files import it by name, which a
``conftest`` would not allow once a subfolder has its own ``conftest``)."""

from __future__ import annotations

import numpy as np

from voxfield.scene.voxel_scene import VoxelScene


def random_scene(seed: int = 0, n: int = 600, size: int = 16) -> VoxelScene:
    rng = np.random.default_rng(seed)
    coords = rng.integers(0, size, size=(n, 3))
    return VoxelScene(coords, rng.random((n, 3)), name=f"random{seed}").dedupe()
