"""Shared fixtures: the real-data folder (skip when absent) and small scenes."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(__file__).parents[1] / ".numba_cache"))

from voxfield.data import data_root  # noqa: E402
from voxfield.scene.voxel_scene import VoxelScene  # noqa: E402


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if not root.is_dir():
        pytest.skip(f"real scenes not found at {root} (set VOXFIELD_DATA to the data folder)")
    return root


def random_scene(seed: int = 0, n: int = 600, size: int = 16) -> VoxelScene:
    rng = np.random.default_rng(seed)
    coords = rng.integers(0, size, size=(n, 3))
    return VoxelScene(coords, rng.random((n, 3)), name=f"random{seed}").dedupe()
