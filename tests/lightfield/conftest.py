"""Small scenes and probes shared by the light-field tests."""

from __future__ import annotations

import numpy as np
import pytest
from lf_helpers import CORNELL_PROBE, one_probe

from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.open import open_octree


@pytest.fixture(scope="session")
def cornell():
    return open_octree("builtin:cornell")


@pytest.fixture(scope="session")
def cornell_probe64(cornell):
    return one_probe(cornell, CORNELL_PROBE, 64)


@pytest.fixture(scope="session")
def walled_room():
    """A closed 32³ room split by a solid wall at x = 15 (one voxel thick, full height)."""
    n = 32
    idx = np.arange(n)
    x, y, z = np.meshgrid(idx, idx, idx, indexing="ij")
    solid = ((x == 0) | (x == n - 1) | (y == 0) | (y == n - 1) | (z == 0) | (z == n - 1)
             | (x == 15))
    coords = np.argwhere(solid)
    color = np.full((len(coords), 3), 0.5, np.float32)
    color[coords[:, 0] == 15] = (0.9, 0.2, 0.1)
    return build_octree(VoxelScene(coords, color, name="walled"))
