"""The assembled terrain (``voxfield.scene.terrain.layout``): the voxel budget guard."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import SceneTooLargeError
from voxfield.scene.terrain.layout import terrain_scene


def test_voxel_budget_guard():
    with pytest.raises(SceneTooLargeError, match="max_voxels"):
        terrain_scene(np.zeros((8, 8)), 64, max_voxels=1000)
