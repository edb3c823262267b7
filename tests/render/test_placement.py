"""Standing places over a (hollow) terrain: a camera inside a voxel or under the surface is
found, one in a room or above the ground is not; a surface probe layer floats at its height."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.probes.grid import parse_grid
from voxfield.render.camera import Camera, room_camera
from voxfield.render.placement import (
    camera_placement_problem,
    check_camera_placement,
    could_be_buried,
    empty_view_problem,
    one_colour_view_note,
    view_note,
)
from voxfield.render.ray_query import trace
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.open import open_octree


def _rolling_surface() -> np.ndarray:
    """Voxel coordinates of a rolling surface one voxel thick over a 64² footprint."""
    x, z = np.meshgrid(np.arange(64), np.arange(64), indexing="ij")
    y = (20 + 6 * np.sin(x / 9.0) * np.cos(z / 7.0)).astype(np.int64)
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


@pytest.fixture(scope="module")
def hollow_terrain():
    """A rolling surface one voxel thick: empty space above and below it."""
    coords = _rolling_surface()
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


def test_a_surface_layer_over_a_roof_says_its_probes_lie_outside(hollow_terrain):
    """``--grid surface:`` over a closed room laid every probe above the ceiling, where no
    probe sees the room, without a word; over a terrain it says nothing."""
    with pytest.warns(UserWarning, match="every probe of the 3x3 surface layer lies above "
                      "the scene's box"):
        grid = parse_grid("surface:3x3@4", octree=open_octree("builtin:cornell"))
    assert np.all(grid.positions[:, 1] > open_octree("builtin:cornell").voxel_bounds[1][1])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parse_grid("surface:3x3@4", octree=hollow_terrain)


def _random_view(rng, kind):
    eye = rng.uniform(-80.0, 150.0, 3)
    # Half of them aimed near the scene (64 × 32 × 64), half anywhere.
    aim = np.array([32.0, 16.0, 32.0]) + rng.normal(scale=20.0, size=3)
    target = aim if rng.random() < 0.5 else eye + rng.normal(size=3)
    if kind == "orthographic":
        return Camera.orthographic(eye, target - eye, view_height=rng.uniform(2.0, 40.0),
                                   width=24, height=16)
    return Camera.look_at(eye, target, fov_deg=rng.uniform(10.0, 100.0), width=24, height=16)


@pytest.mark.parametrize("kind", ["pinhole", "orthographic"])
def test_a_view_called_empty_hits_nothing_and_both_kinds_occur(kind):
    """Against the octree's own ray cast of every pixel: a view the test calls empty has no
    hit (it never refuses a view that shows something), over random eyes and directions
    around and inside ``builtin:pillars``; and it does call many of them empty."""
    pillars = open_octree("builtin:pillars")
    rng = np.random.default_rng(11)
    empty = seeing = 0
    for _ in range(120):
        view = _random_view(rng, kind)
        origins, dirs = view.rays()
        hits = trace(pillars, origins, dirs, lod=0).hit.any()
        if empty_view_problem(pillars, view) is not None:
            assert not hits
            empty += 1
        seeing += hits
    assert empty >= 20 and seeing >= 20, (empty, seeing)


def test_a_view_looking_away_is_refused_and_a_probe_sees_every_way():
    pillars = open_octree("builtin:pillars")
    away = Camera.look_at((32.0, 16.0, -50.0), (32.0, 16.0, -100.0), width=32)
    assert "meets nothing of the scene" in camera_placement_problem(pillars, away)
    with pytest.raises(VoxfieldError, match="meets nothing"):
        check_camera_placement(pillars, away)
    assert empty_view_problem(pillars, Camera.octahedral((32.0, 500.0, 32.0), 8)) is None
    big = Camera.look_at((32.0, 16.0, -50.0), (32.0, 16.0, 0.0), fov_deg=1.0, width=2048)
    assert empty_view_problem(pillars, big) is None  # sampled on 256², still sees the box


def test_a_render_notes_every_problem_the_full_test_finds(hollow_terrain):
    """``view_note`` casts the eye's rays only where ``could_be_buried``: over random eyes
    around, above, inside and under the hollow terrain, it says what the full test says,
    and skips the rays for most eyes outside the terrain's column of space."""
    rng = np.random.default_rng(5)
    found = skipped = 0
    for i in range(150):
        # Every other eye over the terrain's footprint, between below it and its crest.
        eye = (rng.uniform((0.0, -10.0, 0.0), (64.0, 27.0, 64.0)) if i % 2 else
               rng.uniform((-40.0, -20.0, -40.0), (104.0, 60.0, 104.0)))
        view = _look(hollow_terrain, eye, eye + rng.normal(size=3) * 20.0)
        full = camera_placement_problem(hollow_terrain, view)
        assert view_note(hollow_terrain, view) == full
        found += full is not None and "meets nothing" not in full
        skipped += not could_be_buried(hollow_terrain, view)
    assert found >= 10 and skipped >= 50, (found, skipped)


def _two_colour_terrain(second_colour):
    """The hollow terrain with its half x >= 32 in ``second_colour``."""
    coords = _rolling_surface()
    colours = np.full((len(coords), 3), 0.5, np.float32)
    colours[coords[:, 0] >= 32] = second_colour
    return build_octree(VoxelScene(coords, colours))


@pytest.mark.parametrize(("target_x", "one_colour"), [(8.0, True), (56.0, True), (32.0, False)])
def test_a_view_of_one_colour_is_noted_and_one_of_two_is_not(target_x, one_colour):
    """A narrow view of either half sees one colour, one over the seam sees both; the
    one-colour note reads the colours the rays hit, not the scene's."""
    octree = _two_colour_terrain((0.1, 0.6, 0.2))
    shift = np.asarray(octree.scene_origin, np.float64)
    view = Camera.look_at(np.array([target_x, 60.0, 32.0]) - shift,
                          np.array([target_x, 20.0, 32.5]) - shift, fov_deg=8.0, width=48)
    origins, dirs = view.rays()
    hits = trace(octree, origins, dirs, lod=0)
    points = origins[hits.hit] + hits.t[hits.hit, None] * dirs[hits.hit]
    halves = np.unique(points[:, 0] + octree.scene_origin[0] >= 32)
    assert len(halves) == (1 if one_colour else 2)  # what the view sees, found independently
    note = one_colour_view_note(octree, view)
    assert (note is not None) == one_colour
    if one_colour:
        assert "one colour in 'albedo'" in note


def test_measuring_commands_say_so_where_lighting_and_shadows_do_not(hollow_terrain):
    """``study_camera`` notes a one-colour view in the channel a command measures; the
    lighting and shadow studies, which measure their own light (no ``--channel``), are not
    told about their albedo."""
    import argparse

    from voxfield.cli.options import study_camera

    args = argparse.Namespace(scene="x", camera="top", eye=None, target=None, fov=None,
                              size=32, base_lod=2, channel="albedo")
    with pytest.warns(UserWarning, match="one colour in 'albedo'"):
        study_camera(args, hollow_terrain)
    del args.channel
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        study_camera(args, hollow_terrain)
