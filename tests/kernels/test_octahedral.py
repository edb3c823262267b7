"""Octahedral direction mapping (kernels/octahedral.py).

Pins: encode/decode round trips (random directions, axes, poles, equator, fold edges); the
fold identities of the square's boundary (an edge point and its mirror about the edge's
midpoint are one direction, all four corners are −y); texel-centre directions are unit, split
evenly over the eight octants and cover the sphere; ``add_border`` copies the texel that is the
sphere-neighbour across each edge and corner; ``oct_bilinear`` reproduces constants, returns a
texel's own value at its centre and is single-valued on the fold (same direction → same value).
Also: ``texel_of_direction`` agrees with the texel-centre directions and steps into the mirrored
texel when a direction crosses a fold edge; border texels sit one texel from the interior texel
they pad; lookups stay continuous next to the corners (the −y pole) and across the equator;
snorm16 normal codes meet a measured error bound and precise rounding never loses to naive.
"""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import (
    SNORM16_MAX,
    add_border,
    decode_normal_snorm16,
    decode_normals_snorm16,
    encode_normal_snorm16,
    encode_normal_snorm16_naive,
    encode_normals_snorm16,
    oct_bilinear,
    oct_decode,
    oct_encode,
    texel_directions,
    texel_of_direction,
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


# --- texel indices and the fold --------------------------------------------------------------


@pytest.mark.parametrize("resolution", [1, 4, 7, 16])
def test_texel_of_direction_finds_each_texel_centre(resolution):
    dirs = texel_directions(resolution)
    got = [texel_of_direction(*d, resolution) for d in dirs]
    want = [(row, col) for row in range(resolution) for col in range(resolution)]
    assert got == want


def test_texel_of_direction_covers_the_whole_sphere_and_far_edges():
    resolution = 8
    dirs = _unit(np.random.default_rng(11).normal(size=(3000, 3)))
    cells = np.array([texel_of_direction(*d, resolution) for d in dirs])
    assert cells.min() >= 0 and cells.max() <= resolution - 1
    # Brute force: a direction's texel holds the uv point oct_encode gives it.
    uv = np.array([oct_encode(*d) for d in dirs])
    assert np.array_equal(cells[:, 1], np.minimum((uv[:, 0] * resolution).astype(int), 7))
    assert np.array_equal(cells[:, 0], np.minimum((uv[:, 1] * resolution).astype(int), 7))
    # u = 1 (+x) and v = 1 (+z) are inside the last texel, not past it.
    assert texel_of_direction(1.0, 0.0, 0.0, resolution) == (resolution // 2, resolution - 1)
    assert texel_of_direction(0.0, 0.0, 1.0, resolution) == (resolution - 1, resolution // 2)


@pytest.mark.parametrize("resolution", [6, 16])
def test_crossing_a_fold_edge_lands_in_the_mirrored_texel(resolution):
    """A lower-hemisphere direction next to the x = 0 plane folds onto the v = 0 or v = 1
    edge; nudged across the plane it must stay on that edge at the mirrored column (likewise
    z = 0 with the u edges and rows). The two uv points are far apart in the square but the
    directions are neighbours on the sphere."""
    eps = 1e-7
    checked = 0
    for t in np.linspace(-0.95, 0.95, 23):
        h = -np.sqrt(1 - t * t)
        for edge_axis in (0, 2):
            other = 2 - edge_axis
            for side in (-1.0, 1.0):
                before = np.zeros(3)
                before[1], before[other], before[edge_axis] = h, t, side * eps
                after = before.copy()
                after[edge_axis] = -side * eps
                a, b = _unit(before), _unit(after)
                assert _angle(a, b) < 3 * eps
                ra, ca = texel_of_direction(*a, resolution)
                rb, cb = texel_of_direction(*b, resolution)
                if edge_axis == 0:  # x flips: the point stays on the v = 0 or v = 1 row
                    assert ra == rb and ra in (0, resolution - 1)
                    assert cb == resolution - 1 - ca
                else:  # z flips: the point stays on the u = 0 or u = 1 column
                    assert ca == cb and ca in (0, resolution - 1)
                    assert rb == resolution - 1 - ra
                checked += 1
    assert checked == 23 * 4


def test_decode_is_continuous_across_the_equator():
    """The equator is the inner diamond; points just inside and outside it decode to
    directions O(ε) apart (the fold only reflects the outer triangles, it does not tear)."""
    eps = 1e-7
    worst = 0.0
    for s in np.linspace(0.01, 0.99, 41):  # the diamond's corners touch the square's edges
        for sx in (-1, 1):
            for sz in (-1, 1):
                # A point on the diamond |px| + |pz| = 1 and its normal (±1, ±1)/√2 in p-space.
                px, pz = sx * s, sz * (1 - s)
                n = np.array([sx, sz]) / np.sqrt(2)
                inner = np.array([px, pz]) - eps * n
                outer = np.array([px, pz]) + eps * n
                a = np.array(oct_decode(*(inner * 0.5 + 0.5)))
                b = np.array(oct_decode(*(outer * 0.5 + 0.5)))
                assert a[1] > 0 > b[1]
                worst = max(worst, _angle(a, b))
    assert worst < 10 * eps, worst


def _max_neighbour_angle(dirs: np.ndarray) -> float:
    """Largest angle between 8-connected interior texels: "one texel" on this map."""
    worst = 0.0
    for dr, dc in [(0, 1), (1, 0), (1, 1), (1, -1)]:
        a = dirs[max(dr, 0):, max(-dc, 0): dirs.shape[1] - max(dc, 0)]
        b = dirs[: dirs.shape[0] - dr, max(dc, 0):][:, : a.shape[1]]
        worst = max(worst, _angle(a, b).max())
    return worst


@pytest.mark.parametrize("resolution", [4, 8, 16])
def test_border_texel_is_one_texel_from_the_interior_texel_it_pads(resolution):
    """Fill a map with its own texel directions: every border texel must hold a direction no
    farther from the interior texel next to it than two interior neighbours ever are (a wrong
    wrap would put a texel from across the sphere there, up to π away)."""
    dirs = texel_directions(resolution).reshape(resolution, resolution, 3)
    bordered = np.moveaxis(add_border(np.moveaxis(dirs, -1, 0)), 0, -1)
    one_texel = _max_neighbour_angle(dirs)
    worst = 0.0
    for row in range(resolution + 2):
        for col in range(resolution + 2):
            if 1 <= row <= resolution and 1 <= col <= resolution:
                continue
            inner_row = min(max(row, 1), resolution)
            inner_col = min(max(col, 1), resolution)
            padded = bordered[inner_row, inner_col]
            worst = max(worst, _angle(bordered[row, col], padded))
    assert worst <= one_texel * (1 + 1e-9), (worst, one_texel)


def test_oct_bilinear_is_continuous_near_the_pole_corners():
    """Just inside each of the four corners the map reads the −y pole's neighbourhood: a
    smooth function (the y component) must give nearly the same value at all four."""
    resolution = 16
    dirs = texel_directions(resolution)
    bordered = add_border(dirs[:, 1].reshape(resolution, resolution))
    eps = 1e-6
    values = [oct_bilinear(bordered, u, v)
              for u, v in [(eps, eps), (1 - eps, eps), (eps, 1 - eps), (1 - eps, 1 - eps)]]
    assert max(values) - min(values) < 1e-9
    # And the value is the pole's (−1) up to the interpolation error of one texel.
    assert abs(values[0] + 1) < np.sqrt(12) / resolution


# --- snorm16 normal codes ------------------------------------------------------------------------

#: Measured worst angular error of the precise encoder: 4.31e-5 rad over 6M random directions
#: and 1M around each face centre of the octahedron (the most stretched spot). The naive
#: encoder's worst there is 6.47e-5 rad; both sit under the analytic bound √6 · √2 / 32767 ≈
#: 1.06e-4 rad (p-square → sphere Lipschitz constant √6 times half a code cell's diagonal).
PRECISE_SNORM16_MAX_ERROR = 4.5e-5
NAIVE_SNORM16_BOUND = np.sqrt(6) * np.sqrt(2) / SNORM16_MAX


def _snorm16_test_directions() -> np.ndarray:
    rng = np.random.default_rng(21)
    uniform = rng.normal(size=(200_000, 3))
    face_centres = np.array([(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)])
    near_faces = (_unit(face_centres)[:, None, :]
                  + 1e-3 * rng.normal(size=(8, 25_000, 3))).reshape(-1, 3)
    return _unit(np.concatenate([uniform, near_faces]))


def test_snorm16_round_trip_error_bounds_precise_versus_naive():
    dirs = _snorm16_test_directions()
    precise = encode_normals_snorm16(dirs)
    naive = encode_normals_snorm16(dirs, precise=False)
    assert precise.dtype == np.int16 and precise.shape == (len(dirs), 2)
    back_precise = decode_normals_snorm16(precise)
    back_naive = decode_normals_snorm16(naive)
    assert np.allclose(np.linalg.norm(back_precise, axis=1), 1.0, atol=1e-14)
    err_precise = _angle(dirs, back_precise)
    err_naive = _angle(dirs, back_naive)
    assert err_naive.max() < NAIVE_SNORM16_BOUND
    assert err_precise.max() < PRECISE_SNORM16_MAX_ERROR, err_precise.max()
    # Precise tries naive's code among its candidates, so it is never worse, and its worst
    # case is clearly lower (measured 4.31e-5 against 6.47e-5).
    assert np.all(err_precise <= err_naive + 1e-15)
    assert err_precise.max() < 0.75 * err_naive.max()
    assert np.mean(err_precise < err_naive) > 0.1


def test_snorm16_device_functions_match_the_array_wrappers():
    dirs = _unit(np.random.default_rng(22).normal(size=(300, 3)))
    codes = encode_normals_snorm16(dirs)
    naive = encode_normals_snorm16(dirs, precise=False)
    back = decode_normals_snorm16(codes)
    for d, c, n, b in zip(dirs, codes, naive, back, strict=True):
        assert encode_normal_snorm16(*d) == tuple(int(x) for x in c)
        assert encode_normal_snorm16_naive(*d) == tuple(int(x) for x in n)
        assert np.array_equal(decode_normal_snorm16(int(c[0]), int(c[1])), b)


def test_snorm16_codes_of_axes_and_poles():
    assert encode_normal_snorm16(0.0, 1.0, 0.0) == (0, 0)
    assert encode_normal_snorm16(1.0, 0.0, 0.0) == (SNORM16_MAX, 0)
    assert encode_normal_snorm16(0.0, 0.0, -1.0) == (0, -SNORM16_MAX)
    a, b = encode_normal_snorm16(0.0, -1.0, 0.0)
    assert abs(a) == SNORM16_MAX and abs(b) == SNORM16_MAX
    # Length does not matter; -32768 reads as -1 like any snorm format.
    assert encode_normal_snorm16(0.0, 0.0, -5.0) == (0, -SNORM16_MAX)
    assert decode_normal_snorm16(-32768, 0) == decode_normal_snorm16(-SNORM16_MAX, 0)
    assert np.allclose(decode_normal_snorm16(-SNORM16_MAX, 0), (-1.0, 0.0, 0.0), atol=1e-15)


def test_snorm16_round_trip_of_decoded_codes_is_exact():
    """Every code's own direction re-encodes to itself (or, on the fold, to its mirror twin,
    which decodes to the same direction): stored normals survive a decode/encode cycle."""
    codes = np.random.default_rng(23).integers(-SNORM16_MAX, SNORM16_MAX + 1, size=(20_000, 2))
    dirs = decode_normals_snorm16(codes)
    again = encode_normals_snorm16(dirs)
    assert np.array_equal(decode_normals_snorm16(again), dirs)


def test_snorm16_wrappers_refuse_bad_input():
    with pytest.raises(VoxfieldError, match="N×3"):
        encode_normals_snorm16(np.zeros((4, 2)))
    with pytest.raises(VoxfieldError, match="zero vector"):
        encode_normals_snorm16([[0.0, 0.0, 0.0]])
    with pytest.raises(VoxfieldError, match="NaN"):
        encode_normals_snorm16([[np.nan, 1.0, 0.0]])
    with pytest.raises(VoxfieldError, match="N×2"):
        decode_normals_snorm16(np.zeros((3, 3), np.int16))
    with pytest.raises(VoxfieldError, match="integers"):
        decode_normals_snorm16(np.zeros((3, 2)))
    with pytest.raises(VoxfieldError, match="int16"):
        decode_normals_snorm16(np.array([[40_000, 0]]))
    assert encode_normals_snorm16(np.empty((0, 3))).shape == (0, 2)
    assert decode_normals_snorm16(np.empty((0, 2), np.int16)).shape == (0, 3)
