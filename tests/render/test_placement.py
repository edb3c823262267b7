"""Standing places over a (hollow) terrain: a camera inside a voxel or under the surface is
found, one in a room or above the ground is not; a surface probe layer floats at its height."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.probes.grid import parse_grid
from voxfield.render.camera import Camera, room_camera
from voxfield.render.placement import camera_placement_problem, check_camera_placement
from voxfield.render.ray_query import trace
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.open import open_octree


@pytest.fixture(scope="module")
def hollow_terrain():
    """A rolling surface one voxel thick: empty space above and below it."""
    x, z = np.meshgrid(np.arange(64), np.arange(64), indexing="ij")
    y = (20 + 6 * np.sin(x / 9.0) * np.cos(z / 7.0)).astype(np.int64)
    coords = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))


def _look(octree, eye, target):
    """A camera given in scene coordinates, placed in the octree's (``scene_origin`` off)."""
    shift = np.asarray(octree.scene_origin, np.float64)
    return Camera.look_at(np.asarray(eye) - shift, np.asarray(target) - shift, fov_deg=60.0,
                          width=16)


def test_a_camera_under_a_hollow_terrain_is_refused(hollow_terrain):
    under = _look(hollow_terrain, (32.0, 10.0, 32.0), (40.0, 8.0, 10.0))
    assert "under the scene's surface" in camera_placement_problem(hollow_terrain, under)
    with pytest.raises(VoxfieldError, match="--eye/--target"):
        check_camera_placement(hollow_terrain, under)


def test_a_camera_above_the_terrain_is_fine(hollow_terrain):
    above = _look(hollow_terrain, (32.0, 45.0, 70.0), (32.0, 20.0, 32.0))
    assert camera_placement_problem(hollow_terrain, above) is None


def test_a_camera_inside_a_voxel_is_refused(hollow_terrain):
    x, z = 10, 10
    y = int(20 + 6 * np.sin(x / 9.0) * np.cos(z / 7.0))
    inside = _look(hollow_terrain, (x + 0.5, y + 0.5, z + 0.5), (40.0, 20.0, 40.0))
    assert "inside a voxel" in camera_placement_problem(hollow_terrain, inside)


def test_the_room_camera_in_a_closed_box_is_fine():
    cornell = open_octree("builtin:cornell")
    assert camera_placement_problem(cornell, room_camera(*cornell.voxel_bounds, size=16)) is None


def test_a_surface_layer_floats_at_its_height_over_the_ground(hollow_terrain):
    grid = parse_grid("surface:5x4@6", octree=hollow_terrain)
    assert tuple(grid.counts) == (5, 1, 4)
    positions = grid.positions
    down = trace(hollow_terrain, positions, np.tile([0.0, -1.0, 0.0], (len(positions), 1)),
                 lod=0)
    assert down.hit.all()
    np.testing.assert_allclose(down.t, 6.0, atol=1e-9)  # H above the ground below each
