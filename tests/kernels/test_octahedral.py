"""Octahedral direction mapping (kernels/octahedral.py).

Pins: encode/decode round trips (random directions, axes, poles, equator, fold edges); the
fold identities of the square's boundary (an edge point and its mirror about the edge's
midpoint are one direction, all four corners are −y); texel-centre directions are unit, split
evenly over the eight octants and cover the sphere; ``add_border`` copies the texel that is the
sphere-neighbour across each edge and corner; ``oct_bilinear`` reproduces constants, returns a
texel's own value at its centre and is single-valued on the fold (same direction → same value).
"""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.kernels.octahedral import (
    add_border,
    oct_bilinear,
    oct_decode,
    oct_encode,
    texel_directions,
)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, accurate for tiny angles (atan2 of |a×b| and a·b)."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.arctan2(cross, np.sum(a * b, axis=-1))


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _round_trip(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    uv = np.array([oct_encode(*d) for d in dirs])
    back = np.array([oct_decode(u, v) for u, v in uv])
    return uv, back


def test_round_trip_random_directions():
    dirs = _unit(np.random.default_rng(0).normal(size=(5000, 3)))
    uv, back = _round_trip(dirs)
    assert np.all((uv >= 0.0) & (uv <= 1.0))
    assert np.allclose(np.linalg.norm(back, axis=1), 1.0, atol=1e-14)
    assert _angle(dirs, back).max() < 1e-12


def test_round_trip_axes_poles_equator_and_diagonals():
    special = [
        (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1),
        (-0.0, -1, 0.0), (0.0, -1, -0.0), (-0.0, 1, -0.0),
    ]
    t = np.linspace(0, 2 * np.pi, 73)
    equator = np.stack([np.cos(t), np.zeros_like(t), np.sin(t)], axis=1)
    diagonals = [(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    dirs = np.concatenate([_unit(special), equator, _unit(diagonals)])
    uv, back = _round_trip(dirs)
    assert np.all((uv >= 0.0) & (uv <= 1.0))
    assert _angle(dirs, back).max() < 1e-12
    # Where things land (module convention: +y at the centre, −y at the corners, u ~ x, v ~ z).
    assert oct_encode(0.0, 1.0, 0.0) == (0.5, 0.5)
    assert oct_encode(0.0, -1.0, 0.0) in {(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)}
    assert oct_encode(1.0, 0.0, 0.0) == (1.0, 0.5)
    assert oct_encode(0.0, 0.0, 1.0) == (0.5, 1.0)
    # The equator is the inner diamond |u - ½| + |v - ½| = ½.
    eq_uv = uv[len(special) : len(special) + len(t)]
    assert np.allclose(np.abs(eq_uv - 0.5).sum(axis=1), 0.5, atol=1e-15)


def test_round_trip_on_fold_edges():
    """Lower-hemisphere directions with x = 0 or z = 0 encode onto the square's edges (the
    fold); decoding must give them back whichever side's sign convention encode picked."""
    s = np.linspace(-1, 1, 41)
    h = -np.sqrt(np.clip(1 - s * s, 0, None))  # y <= 0
    dirs = np.concatenate([
        np.stack([np.zeros_like(s), h, s], axis=1),   # x = 0
        np.stack([-np.zeros_like(s), h, s], axis=1),  # x = -0.0
        np.stack([s, h, np.zeros_like(s)], axis=1),   # z = 0
        np.stack([s, h, -np.zeros_like(s)], axis=1),  # z = -0.0
    ])
    dirs = _unit(dirs)
    uv, back = _round_trip(dirs)
    on_edge = np.any((uv == 0.0) | (uv == 1.0), axis=1)
    assert on_edge.all()
    assert _angle(dirs, back).max() < 1e-12


def test_fold_identifies_mirrored_edge_points_and_corners():
    """Independent fact about the octahedral square: a point on an edge and its mirror about
    that edge's midpoint are the same direction; the four corners are all the −y pole."""
    for t in np.linspace(0, 1, 33):
        for a, b in [((0.0, t), (0.0, 1 - t)), ((1.0, t), (1.0, 1 - t)),
                     ((t, 0.0), (1 - t, 0.0)), ((t, 1.0), (1 - t, 1.0))]:
            da, db = np.array(oct_decode(*a)), np.array(oct_decode(*b))
            assert da[1] <= 1e-15  # the square's boundary is all lower hemisphere
            assert _angle(da, db) < 1e-12, (a, b, da, db)
    for corner in [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]:
        assert np.allclose(oct_decode(*corner), (0.0, -1.0, 0.0), atol=1e-15)


@pytest.mark.parametrize("resolution", [4, 8, 16, 32])
def test_texel_directions_unit_and_evenly_split_over_octants(resolution):
    dirs = texel_directions(resolution)
    assert dirs.shape == (resolution * resolution, 3)
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-14)
    # Texel centres are never on x = 0 or z = 0 (odd multiples of 1/R); with even R some sit
    # exactly on the equator (y = 0): count those half to each hemisphere.
    assert np.all(dirs[:, 0] != 0) and np.all(dirs[:, 2] != 0)
    on_equator = np.abs(dirs[:, 1]) < 1e-12
    weights = np.zeros(8)
    for d, eq in zip(dirs, on_equator, strict=True):
        ox, oz = int(d[0] > 0), int(d[2] > 0) << 2
        if eq:
            weights[ox | oz] += 0.5
            weights[ox | 2 | oz] += 0.5
        else:
            weights[ox | int(d[1] > 0) << 1 | oz] += 1
    assert np.all(weights == resolution * resolution / 8), weights
    # Row-major (v, u): x has the sign of u − ½ and z the sign of v − ½ on every texel.
    centres = (np.arange(resolution) + 0.5) / resolution - 0.5
    grid = dirs.reshape(resolution, resolution, 3)
    assert np.all(np.sign(grid[:, :, 0]) == np.sign(centres)[None, :])
    assert np.all(np.sign(grid[:, :, 2]) == np.sign(centres)[:, None])


def test_texel_directions_cover_the_sphere():
    """Covering radius bound: uv→sphere is Lipschitz with constant ≤ 2 (uv→[-1,1]²) · √2
    (tilt of an octahedron face over the plane) · √3 (radial projection, |p| ≥ 1/√3) = 2√6,
    and every uv point is within √2/(2R) of a texel centre, so every direction lies within
    √12/R rad of a texel-centre direction."""
    resolution = 16
    texels = texel_directions(resolution)
    probe = _unit(np.random.default_rng(1).normal(size=(4000, 3)))
    nearest = np.arccos(np.clip(probe @ texels.T, -1, 1).max(axis=1))
    assert nearest.max() < np.sqrt(12) / resolution, nearest.max()


def _mirror_inside(u: float, v: float) -> tuple[float, float]:
    """Where a uv point just outside the square lands: crossing the u = 0 (or 1) edge mirrors u
    across that edge and v about ½ (the edge's midpoint, by the fold identity above); likewise
    for v. Applying both rules handles corners."""
    if u < 0:
        u, v = -u, 1 - v
    elif u > 1:
        u, v = 2 - u, 1 - v
    if v < 0:
        u, v = 1 - u, -v
    elif v > 1:
        u, v = 1 - u, 2 - v
    return u, v


@pytest.mark.parametrize("resolution", [2, 3, 5, 8])
def test_add_border_copies_the_neighbour_across_the_fold(resolution):
    rng = np.random.default_rng(resolution)
    maps = rng.random((3, resolution, resolution))
    bordered = add_border(maps)
    assert bordered.shape == (3, resolution + 2, resolution + 2)
    assert np.array_equal(bordered[:, 1:-1, 1:-1], maps)
    for row in range(resolution + 2):
        for col in range(resolution + 2):
            if 1 <= row <= resolution and 1 <= col <= resolution:
                continue
            # Bordered texel (row, col) has its centre at uv = ((col - ½)/R, (row - ½)/R).
            u, v = _mirror_inside((col - 0.5) / resolution, (row - 0.5) / resolution)
            src_col, src_row = int(u * resolution), int(v * resolution)
            assert np.array_equal(bordered[:, row, col], maps[:, src_row, src_col]), (row, col)


def test_add_border_agrees_with_decoded_directions():
    """The border texel's mirrored centre decodes to a direction next to the texel centre it
    copies (within one texel's angular size): the wrap is a sphere neighbour, not a far texel."""
    resolution = 8
    dirs = texel_directions(resolution).reshape(resolution, resolution, 3)
    bordered = add_border(np.moveaxis(dirs, -1, 0))  # (3, R+2, R+2) of texel directions
    border = [(r, c) for r in range(resolution + 2) for c in range(resolution + 2)
              if r in (0, resolution + 1) or c in (0, resolution + 1)]
    for row, col in border:
        u, v = (col - 0.5) / resolution, (row - 0.5) / resolution
        edge = np.array(oct_decode(min(max(u, 0.0), 1.0), min(max(v, 0.0), 1.0)))
        copied = bordered[:, row, col]
        assert _angle(edge, copied) < np.sqrt(12) / resolution, (row, col)


def test_oct_bilinear_reproduces_a_constant_everywhere():
    bordered = add_border(np.full((7, 7), 0.3))
    grid = np.linspace(0.0, 1.0, 57)
    values = np.array([[oct_bilinear(bordered, u, v) for u in grid] for v in grid])
    assert np.allclose(values, 0.3, rtol=0, atol=1e-15)
    for corner in [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]:
        assert abs(oct_bilinear(bordered, *corner) - 0.3) < 1e-15


def test_oct_bilinear_returns_the_texel_value_at_its_centre():
    resolution = 8
    maps = np.random.default_rng(3).random((resolution, resolution))
    bordered = add_border(maps)
    centres = (np.arange(resolution) + 0.5) / resolution
    got = np.array([[oct_bilinear(bordered, u, v) for u in centres] for v in centres])
    assert np.allclose(got, maps, atol=1e-12), np.abs(got - maps).max()


def test_oct_bilinear_is_exact_for_maps_linear_in_uv():
    """Between texel centres (uv in [½/R, 1 − ½/R]²) bilinear interpolation of a map that is
    linear in (u, v) must give that linear function back."""
    resolution = 8
    centres = (np.arange(resolution) + 0.5) / resolution
    maps = 0.2 + 0.5 * centres[None, :] - 0.3 * centres[:, None]
    bordered = add_border(maps)
    pts = np.random.default_rng(4).uniform(0.5 / resolution, 1 - 0.5 / resolution, (200, 2))
    got = np.array([oct_bilinear(bordered, u, v) for u, v in pts])
    want = 0.2 + 0.5 * pts[:, 0] - 0.3 * pts[:, 1]
    assert np.allclose(got, want, atol=1e-12), np.abs(got - want).max()


def test_oct_bilinear_is_single_valued_on_the_fold():
    """An edge point and its mirror are one direction, so a lookup there must give one value
    (for any map, smooth or not); likewise the four corners (the −y pole)."""
    resolution = 8
    bordered = add_border(np.random.default_rng(5).random((resolution, resolution)))
    worst = 0.0
    for t in np.linspace(0, 1, 29):
        for a, b in [((0.0, t), (0.0, 1 - t)), ((1.0, t), (1.0, 1 - t)),
                     ((t, 0.0), (1 - t, 0.0)), ((t, 1.0), (1 - t, 1.0))]:
            worst = max(worst, abs(oct_bilinear(bordered, *a) - oct_bilinear(bordered, *b)))
    corners = [oct_bilinear(bordered, *c) for c in [(0, 0), (0, 1.0), (1.0, 0), (1.0, 1.0)]]
    worst = max(worst, max(corners) - min(corners))
    assert worst < 1e-12, worst


def test_oct_bilinear_is_continuous_across_the_fold():
    """Two uv points just inside opposite halves of an edge (u = ε at v and at 1 − v) decode to
    directions O(ε) apart, so a smooth function's texel map must give nearby values there."""
    resolution = 16
    a = _unit(np.array([0.3, -0.5, 0.8]))
    dirs = texel_directions(resolution)
    bordered = add_border((dirs @ a).reshape(resolution, resolution))
    eps = 1e-6
    worst = 0.0
    for t in np.linspace(0.02, 0.98, 25):
        for p, q in [((eps, t), (eps, 1 - t)), ((1 - eps, t), (1 - eps, 1 - t)),
                     ((t, eps), (1 - t, eps)), ((t, 1 - eps), (1 - t, 1 - eps))]:
            assert _angle(np.array(oct_decode(*p)), np.array(oct_decode(*q))) < 1e-5
            worst = max(worst, abs(oct_bilinear(bordered, *p) - oct_bilinear(bordered, *q)))
    # f = d·a changes by at most one texel's angular size (√12/R) between the two lookups'
    # stencils; a wrong wrap would read texels from far across the sphere (|Δf| up to 2).
    assert worst < np.sqrt(12) / resolution, worst
