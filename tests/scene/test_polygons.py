"""Polygon triangulation: fans for convex polygons, ear clipping for concave ones."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.scene.mesh import load_mesh
from voxfield.scene.polygons import ear_clip, triangulate


def _area(points2d: np.ndarray) -> float:
    x, y = points2d[:, 0], points2d[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _triangle_areas(points2d: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (points2d[triangles[:, i]] for i in range(3))
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                  - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _star(rng, n: int) -> np.ndarray:
    """A random simple polygon: corners at increasing angles less than a half turn apart,
    random radii (star-shaped about the origin, often concave)."""
    steps = rng.uniform(0.5, 1.0, n)
    angles = np.cumsum(steps) * (2 * np.pi / steps.sum())
    radii = rng.uniform(0.2, 1.0, n)
    return np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)


@pytest.mark.parametrize("seed", range(40))
def test_ear_clipping_tiles_a_random_simple_polygon(seed):
    rng = np.random.default_rng(seed)
    flat = _star(rng, int(rng.integers(4, 40)))
    # placed in 3D on a tilted plane, either way round: the triangles still tile it
    basis = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2]
    for points2d in (flat, flat[::-1]):
        points = points2d @ basis.T + rng.normal(size=3)
        triangles = ear_clip(points)
        assert triangles.shape == (len(points) - 2, 3)
        areas = _triangle_areas(points2d, triangles)
        # every triangle turns the polygon's way, and together they cover its area once
        assert np.all(np.sign(areas) == np.sign(_area(points2d)))
        assert areas.sum() == pytest.approx(_area(points2d), rel=1e-9)


def test_convex_polygons_keep_their_fan_and_concave_ones_are_clipped():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    notch = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]],
                     float)  # an L: the fan from corner 0 would cover the missing square
    vertices = np.concatenate([square, notch])
    counts = np.array([4, 6])
    tris = triangulate(counts, np.arange(10), vertices)
    np.testing.assert_array_equal(tris[:2], [[0, 1, 2], [0, 2, 3]])
    l_shape = vertices[tris[2:]][:, :, :2]
    areas = _triangle_areas(vertices[:, :2], tris[2:])
    assert np.all(areas > 0) and areas.sum() == pytest.approx(3.0)
    centroids = l_shape.mean(axis=1)
    assert not np.any((centroids[:, 0] > 1) & (centroids[:, 1] > 1))  # nothing in the notch


@pytest.mark.parametrize("scale", [1e300, 1e-300, 2.0 ** 600])
def test_polygons_far_from_unit_size_are_cut_as_at_unit_size(scale):
    """Turns and normals multiply coordinates: at 1e300 they overflowed (NumPy warning at
    each step), at 1e-300 they underflowed to 0 and an L passed for convex and was fanned
    over its notch."""
    notch = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]],
                     float)
    corners = np.arange(len(notch))
    unit = triangulate(np.array([6]), corners, notch)
    np.testing.assert_array_equal(triangulate(np.array([6]), corners, notch * scale), unit)
    np.testing.assert_array_equal(ear_clip(notch * scale), ear_clip(notch))
    areas = _triangle_areas(notch[:, :2], unit)
    assert np.all(areas > 0) and areas.sum() == pytest.approx(3.0)


def test_an_obj_floor_plan_keeps_its_notch_empty(tmp_path):
    (tmp_path / "plan.obj").write_text(
        "v 0 0 0\nv 2 0 0\nv 2 0 1\nv 1 0 1\nv 1 0 2\nv 0 0 2\nf 3 4 5 6 1 2\n")
    mesh = load_mesh(tmp_path / "plan.obj")
    corners = mesh.vertices[mesh.triangles]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1).sum()
    assert area == pytest.approx(3.0)  # the fan from the file's first corner gave 4


def test_a_byte_order_mark_is_not_part_of_the_first_statement(tmp_path):
    (tmp_path / "bom.obj").write_bytes(
        "\ufeffv 0 0 0\nv 4 0 0\nv 0 1 0\nf 1 2 3\n".encode("utf-8"))
    mesh = load_mesh(tmp_path / "bom.obj")
    np.testing.assert_array_equal(mesh.vertices[mesh.triangles[0]],
                                  [[0, 0, 0], [4, 0, 0], [0, 1, 0]])


def test_a_hole_cut_by_an_outline_that_doubles_back_stays_open():
    # a 4 × 4 square with a 2 × 2 hole, one polygon: out along the bridge at the bottom-left,
    # round the hole the other way, back along the bridge (its corners appear twice)
    outline = [(0, 0), (4, 0), (4, 4), (0, 4), (0, 0), (1, 1), (1, 3), (3, 3), (3, 1), (1, 1)]
    flat = np.array(outline, float)
    triangles = ear_clip(np.c_[flat, np.zeros(len(flat))])
    areas = _triangle_areas(flat, triangles)
    assert len(triangles) == len(flat) - 2
    assert np.all(areas >= 0) and areas.sum() == pytest.approx(12.0)
    centroids = flat[triangles].mean(axis=1)
    assert not np.any(np.all((centroids > 1) & (centroids < 3), axis=1))  # none in the hole


def test_straight_corners_do_not_make_a_convex_polygon_concave():
    # a rectangle with its edge midpoints, tilted in 3D: rounding makes their turns ±1e-17,
    # and a convex polygon keeps the fan (its triangles' order) all the same
    rng = np.random.default_rng(3)
    square = np.array([(0, 0), (1, 0), (2, 0), (2, 1), (2, 2), (1, 2), (0, 2), (0, 1)], float)
    for _ in range(50):
        basis = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2]
        points = square * rng.uniform(0.1, 10) @ basis.T + rng.normal(size=3) * 100
        tris = triangulate(np.array([8]), np.arange(8), points)
        np.testing.assert_array_equal(tris, [[0, k + 1, k + 2] for k in range(6)])


def test_a_comb_of_thousands_of_corners_is_tiled():
    # 1,000 teeth, 4,003 corners, counter-clockwise: every gap a notch the fan would fill
    outline = [(0.0, 0.0), (1000.0, 0.0), (1000.0, 1.0)]
    for k in range(999, -1, -1):
        outline += [(k + 0.5, 1.0), (k + 0.5, 10.0), (k, 10.0), (k, 1.0)]
    flat = np.array(outline)
    triangles = ear_clip(np.c_[flat, np.zeros(len(flat))])
    areas = _triangle_areas(flat, triangles)
    assert len(triangles) == len(flat) - 2
    assert np.all(areas >= -1e-12) and areas.sum() == pytest.approx(_area(flat))
    assert _area(flat) == pytest.approx(1000 + 1000 * 0.5 * 9)
