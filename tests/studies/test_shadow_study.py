"""The shadow study on a scene without light: the error says what the study needs."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.render.camera import Camera
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.studies.shadow_study import run_shadow_study
from voxfield.svo import build_octree


def test_a_scene_without_emission_is_refused_with_what_it_needs(tmp_path):
    """A MagicaVoxel model or a mesh has albedo only: the study said "the octree has no
    channel 'emission'", read for its cache key, instead of asking for emitting voxels."""
    octree = build_octree(VoxelScene(np.array([[0, 0, 0], [1, 1, 1]]), np.full((2, 3), 0.5)))
    camera = Camera.look_at((5, 5, 5), (0, 0, 0), width=8)
    with pytest.raises(VoxfieldError, match="direct lighting needs emitting voxels"):
        run_shadow_study(octree, camera, tmp_path / "study")
    assert not (tmp_path / "study").exists()
