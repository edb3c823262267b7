"""Cameras against analytic rays: centre rays, parallel orthographic rays, cube-face coverage."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from random_scenes import overhanging_terrain
from voxfield.errors import CameraError, VoxfieldError
from voxfield.render import render_lod
from voxfield.render.beam import pixel_start_bounds
from voxfield.render.camera import (
    Camera,
    beam_camera,
    cube_cameras,
    framing_camera,
    oblique_camera,
    orbit_camera,
    ortho_top_camera,
    preset_camera,
    room_camera,
    top_down_camera,
)
from voxfield.svo import build_octree
from voxfield.svo.column_tops import octree_column_tops


def test_pinhole_centre_ray_looks_at_target_and_corners_span_fov():
    cam = Camera.look_at((0, 0, 10), (0, 0, 0), fov_deg=90.0, width=2, height=2)
    o, d = cam.rays(side=1)
    assert np.allclose(o, [0, 0, 10])
    # Pixel centres of a 2×2 image sit at ±half of the half-extent: tan(45°)/2 = 0.5.
    expected = np.array([[-0.5, 0.5, -1], [0.5, 0.5, -1], [-0.5, -0.5, -1], [0.5, -0.5, -1]])
    expected /= np.linalg.norm(expected, axis=1)[:, None]
    assert np.allclose(d, expected)


def test_orthographic_rays_are_parallel_and_spread_over_the_view():
    cam = Camera.orthographic((5, 9, 5), (0, -1, 0), (0, 0, -1), view_height=10, width=10)
    o, d = cam.rays()
    assert np.allclose(d, [0, -1, 0])
    assert np.allclose(o[:, 1], 9)
    assert np.isclose(o[:, 0].min(), 0.5) and np.isclose(o[:, 0].max(), 9.5)


def test_supersampled_rays_stay_inside_their_pixel():
    cam = Camera.orthographic((2, 2, 10), (0, 0, -1), view_height=4, width=4)
    o, _ = cam.rays(side=4, seed=7)
    pixel = np.repeat(np.arange(16), 16)
    col, row = pixel % 4, pixel // 4
    assert np.all((o[:, 0] >= col) & (o[:, 0] < col + 1))
    assert np.all((4 - o[:, 1] >= row) & (4 - o[:, 1] < row + 1))


def test_cube_faces_tile_the_sphere():
    faces = cube_cameras((0, 0, 0), size=8)
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    inside = np.zeros(len(dirs), int)
    for cam in faces:
        along = dirs @ cam.forward
        with np.errstate(divide="ignore", invalid="ignore"):
            a = (dirs @ cam.right) / along
            b = (dirs @ cam.up) / along
        inside += (along > 0) & (np.abs(a) < 1) & (np.abs(b) < 1)
    assert np.all(inside == 1)
    # Right-handed faces: right = forward × up.
    for cam in faces:
        assert np.allclose(np.cross(cam.forward, cam.up), cam.right)


def test_top_down_camera_spans_the_map_at_ground_level():
    cam = top_down_camera((0, 0, 0), (64, 10, 64), size=4)
    o, d = cam.rays()
    assert np.allclose(o[0], [32, 32, 32])
    ground = o - d * (o[:, 1:2] / d[:, 1:2])
    assert ground[:, 0].min() > 0 and ground[:, 0].max() < 64


@pytest.mark.parametrize("target_y", [0.0, 200.0])
def test_a_view_straight_down_or_up_takes_the_top_views_up(target_y):
    """With no up given, a vertical view cannot use the world's up; it once refused with
    "pick another up", which no command lets a user do. It now turns as the top view does."""
    straight = Camera.look_at((32, 100, 32), (32, target_y, 32), fov_deg=90, width=4)
    top = top_down_camera((0, 0, 0), (64, 10, 64), size=4)
    assert np.allclose(straight.forward, (0.0, np.sign(target_y - 100.0), 0.0))
    assert abs(straight.up[2]) == 1.0 and np.allclose(
        np.cross(straight.forward, straight.up), straight.right)
    if target_y == 0.0:
        # the same picture as the top view
        assert np.allclose(straight.right, top.right) and np.allclose(straight.up, top.up)


def test_a_far_eye_keeps_its_direction():
    """|eye - target| overflowed to inf at 1e308 and the direction became zero, reported as
    an up vector parallel to it."""
    camera = Camera.look_at((1e308, 1.0, 1.0), (0.0, 0.0, 0.0), width=4)
    assert np.allclose(camera.forward, (-1.0, 0.0, 0.0))


@pytest.mark.parametrize("make, words", [
    (lambda: Camera.look_at((1e308, 0, 0), (-1e308, 0, 0)), "too far apart"),
    (lambda: orbit_camera((0, 0, 0), (1e308,) * 3), "too large to frame"),
    (lambda: top_down_camera((-1e308, 0, 0), (1e308, 1, 1)), "too large to frame"),
])
def test_points_too_far_apart_for_float64_are_refused_without_numpy_s_warning(make, words):
    """NumPy's overflow warnings (in subtract, in dot) reached the caller before the
    CameraError that named a direction or an eye of infinity."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CameraError, match=words):
            make()


@pytest.mark.parametrize(
    "make",
    [
        lambda: Camera.look_at((0, 0, 0), (0, 0, 0)),
        lambda: Camera.look_at((0, 0, np.nan), (0, 0, 1)),
        lambda: Camera.look_at((0, 0, 0), (0, 1, 0), up=(0, 1, 0)),
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), fov_deg=0),
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), fov_deg=1e-300),  # eye lost past 1e300
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), width=0),
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), width=16.5),  # once silently 16
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), width=True),  # once a 1-pixel image
        lambda: Camera.look_at((0, 0, 0), (0, 0, 1), width=8, height=16385),
        lambda: Camera.orthographic((0, 0, 0), (0, 0, 1), view_height=-1),
        lambda: Camera.orthographic((0, 0, 0), (0, 0, 1), view_height="abc"),  # ValueError
        lambda: Camera.orthographic((0, 0, 0), (0, 0, 1), view_height=None),  # TypeError
        lambda: Camera.cube_face((0, 0, 0), "+w"),
        lambda: Camera.cube_face((0, 0, 0), "+x", size=0),
        lambda: Camera.octahedral((0, 0, 0), resolution=8.5),
    ],
)
def test_invalid_cameras_raise_camera_error(make):
    with pytest.raises(CameraError):
        make()


def test_octahedral_camera_casts_the_texel_centre_directions():
    from voxfield.kernels.octahedral import texel_directions

    cam = Camera.octahedral((1.0, 2.0, 3.0), resolution=8)
    origins, directions = cam.rays(side=1)
    assert np.allclose(origins, (1.0, 2.0, 3.0))
    assert np.allclose(directions, texel_directions(8), atol=1e-12)


def test_octahedral_render_depth_is_the_ray_cast_distance():
    # A probe inside a hollow box: each texel's depth is the distance along its direction to
    # the first wall, computed independently by the ray query.
    from voxfield.render import render_lod
    from voxfield.render.ray_query import trace
    from voxfield.scene.voxel_scene import VoxelScene
    from voxfield.svo import build_octree

    grid = np.indices((12, 12, 12)).reshape(3, -1).T
    shell = grid[(grid.min(axis=1) == 0) | (grid.max(axis=1) == 11)]
    octree = build_octree(VoxelScene(shell, np.full((len(shell), 3), 0.5)))
    cam = Camera.octahedral((4.3, 6.1, 5.2), resolution=16)
    result = render_lod(octree, cam, lod=0)
    origins, directions = cam.rays()
    hits = trace(octree, origins, directions)
    assert np.all(hits.hit)
    assert np.allclose(result.depth.ravel(), hits.t)


@pytest.mark.parametrize("seed", [1, 2])
def test_ortho_top_renders_what_a_camera_just_above_sees_with_every_block_bounded(seed):
    """The preset's height changes no colour (a camera one voxel above the top sees the same
    image at every LOD), every hit has the face it entered (from one voxel above, rays start
    inside coarse nodes, with none), and the beam bounds every block."""
    octree = build_octree(overhanging_terrain(seed, size=40))
    lo, hi = (np.asarray(b, float) for b in octree.voxel_bounds)
    preset = ortho_top_camera(lo, hi, size=32)
    centre = (lo + hi) / 2.0
    close = Camera.orthographic((centre[0], hi[1] + 1.0, centre[2]), (0, -1, 0), (0, 0, -1),
                                view_height=float(max(hi[0] - lo[0], hi[2] - lo[2])),
                                width=32)
    for lod in range(4):
        bounds = pixel_start_bounds(octree, preset, octree_column_tops(octree),
                                    stop_level=octree.depth - lod)
        assert np.all(bounds.bound > 0)
        high, low = render_lod(octree, preset, lod=lod), render_lod(octree, close, lod=lod)
        for name in ("image", "hit_count", "finest_lod"):
            assert np.array_equal(getattr(high, name), getattr(low, name)), (lod, name)
        faced = np.any(low.normal != 0, axis=-1)
        assert np.array_equal(high.normal[faced], low.normal[faced])
        assert np.all(np.any(high.normal != 0, axis=-1)[high.hit_count > 0])


@pytest.mark.parametrize("change, words", [
    ({"position": np.full(3, np.nan)}, "position"),
    ({"position": np.array([1.0, 2.0])}, "position"),
    ({"forward": np.zeros(3)}, "orthonormal"),
    ({"up": np.array([0.0, 2.0, 0.0])}, "orthonormal"),
    ({"right": np.array([np.inf, 0.0, 0.0])}, "right"),
    ({"kind": 9}, "kind"),
    ({"half_width": "x"}, "half_width must be a number"),  # NumPy's isfinite TypeError
    ({"half_height": None}, "half_height must be a number"),
])
def test_a_camera_built_or_replaced_field_by_field_is_checked(change, words):
    """The constructors make valid cameras; one assembled by hand, or by
    ``dataclasses.replace``, rendered black or its packed parameters shifted."""
    camera = Camera.look_at((40.0, 40.0, 40.0), (16.0, 16.0, 16.0), width=8)
    with pytest.raises(CameraError, match=words):
        dataclasses.replace(camera, **change)


@pytest.mark.parametrize("lo, hi, fov, words", [
    ([0.0, 0.0], [32.0, 32.0], None, "box minimum"),
    ([32.0, 0.0, 0.0], [0.0, 32.0, 32.0], None, "exceeds its maximum"),
    ([0.0, 0.0, 0.0], [32.0, 32.0, 32.0], 0.0, "field of view"),  # once the preset's own
])
def test_a_preset_view_of_an_impossible_box_or_field_is_refused(lo, hi, fov, words):
    with pytest.raises(CameraError, match=words):
        preset_camera("top", lo, hi, size=8, fov_deg=fov)


@pytest.mark.parametrize("maker", [top_down_camera, oblique_camera, orbit_camera])
@pytest.mark.parametrize("fov", [0.0, -30.0, 180.0])
def test_a_framing_view_refuses_its_field_before_it_divides_by_it(maker, fov):
    """``orbit_camera(fov_deg=0)`` printed NumPy's divide-by-zero warning before the
    camera's refusal: the makers that place the eye by the field now check it first."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CameraError, match="field of view"):
            maker((0.0, 0.0, 0.0), (32.0, 32.0, 32.0), size=8, fov_deg=fov)


@pytest.mark.parametrize("side", [-1, 0, 17, 2**31, 1.9, "2"])
def test_rays_refuse_a_side_the_renderers_do_not_take(side):
    """-1 looped for ever and 2^31 overflowed the ray count and wrote past the arrays."""
    camera = Camera.look_at((0, 0, 10), (0, 0, 0), width=2)
    with pytest.raises(VoxfieldError, match="samples per pixel side"):
        camera.rays(side=side)
    with pytest.raises(VoxfieldError, match="seed"):
        camera.rays(side=1, seed=-1)
    origins, dirs = camera.rays(side=16)
    assert origins.shape == dirs.shape == (2 * 2 * 256, 3)


@pytest.mark.parametrize("make", [top_down_camera, oblique_camera, orbit_camera, beam_camera,
                                  room_camera, ortho_top_camera])
def test_a_view_helper_refuses_a_box_that_is_not_one(make):
    """Two-number corners raised IndexError or a broadcasting ValueError from inside."""
    with pytest.raises(CameraError, match="three numbers"):
        make((0, 0), (10, 10))
    with pytest.raises(CameraError, match="exceeds"):
        make((0, 0, 0), (10, -1, 10))
    assert make((0, 0, 0), (10, 10, 10), size=8).width == 8


def test_a_field_of_view_must_be_a_number_and_framing_needs_points():
    with pytest.raises(CameraError, match="field of view"):
        Camera.look_at((0, 0, 10), (0, 0, 0), fov_deg="60")
    with pytest.raises(CameraError, match="at least one point"):
        framing_camera(np.zeros((0, 3)))
