"""The EA error raycast (``raycast_errors``, EA §3.1.2 Algorithm 1) against independent truth.

Pins: analytic projected-area ratios (one child is ¼ of the parent from every direction, a
full mask loses nothing, the bottom layer of fig. 3.1(c)/(d) seen from the top, the side and
the diagonal); an exact polygon-union reference (shapely) over all 255 non-empty masks and 30
random directions; determinism (seed, thread count); and input validation.

Tolerance. EA Table 3.1 bounds the sampling error by half a cell times the 48 units of child
edges: 48/R (0.1875 at 256², 0.09375 at 512²). That worst case assumes aligned samples; with one
CMJ-jittered sample per cell only the cells a silhouette edge crosses can be wrong, each
independently, so the area error's standard deviation is about h^1.5·√L/2 for cell size
h = 2/R and outline length L ≲ 10: ≈1.2e-3 at 256². ``TOL_256 = 0.01`` is ~8σ of that and
1/19 of Table 3.1's bound; it would catch a half-texel camera shift or a wrong octant bit.
Most checks run at 256² (4× faster than 512², and the bound above scales as R^-1.5).
"""

from __future__ import annotations

import itertools

import numba
import numpy as np
import pytest
from shapely.geometry import MultiPoint
from shapely.ops import unary_union

from voxfield.error_table import raycast_errors
from voxfield.errors import VoxfieldError

TABLE_3_1 = {512: 0.09375, 256: 0.1875, 128: 0.375, 64: 0.75}
TOL_256 = 0.01
SINGLE_CHILDREN = [1 << c for c in range(8)]
BOTTOM_LAYER = 0b00110011  # children 0, 1, 4, 5: y-bit (bit 1 of the octant) clear
assert BOTTOM_LAYER == sum(1 << c for c in range(8) if not c & 2)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


AXES = _unit([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)])
DIAGONALS = _unit([(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)])


def test_table_3_1_matches_its_formula():
    for res, bound in TABLE_3_1.items():
        assert bound == pytest.approx(0.5 * (2 / res) * 48)  # half a cell × 48 units of edges
    assert TOL_256 < TABLE_3_1[256]


def test_single_child_is_three_quarters_from_every_direction():
    """A half-size cube's projection is the parent's scaled by ½: area ratio ¼ for any d."""
    rng = np.random.default_rng(11)
    dirs = np.concatenate([AXES, DIAGONALS, _unit(rng.normal(size=(10, 3)))])
    errors = raycast_errors(dirs, 256, 0)
    worst = np.abs(errors[SINGLE_CHILDREN] - 0.75).max()
    assert worst < TOL_256, worst


def test_full_and_empty_masks():
    dirs = np.concatenate([AXES, DIAGONALS, _unit(np.random.default_rng(12).normal(size=(8, 3)))])
    errors = raycast_errors(dirs, 128, 0)
    assert errors.shape == (256, len(dirs))
    assert np.all(errors[255] == 0.0)  # every parent ray passes through some child
    assert np.all(errors[0] == 0.0)  # by definition
    assert np.all((errors >= 0.0) & (errors <= 1.0))


def _box_area(extent, n) -> float:
    """Projected area of an a×b×c box along unit n: a·b|n_z| + b·c|n_x| + a·c|n_y|."""
    a, b, c = extent
    return a * b * abs(n[2]) + b * c * abs(n[0]) + a * c * abs(n[1])


@pytest.mark.parametrize(
    ("direction", "expected"),
    [
        ((0, -1, 0), 0.0),  # from the top (fig. 3.1(c)): the layer covers the parent's square
        ((0, 1, 0), 0.0),  # from below
        ((1, 0, 0), 0.5),  # from the side (fig. 3.1(d)): half the height
        ((0, 0, -1), 0.5),
        ((1, 1, 1), 1 / 3),  # 1 − (2/√3)/(3/√3)
        ((-1, -1, 1), 1 / 3),
        ((1, -1, 0), 0.25),  # 1 − (1.5/√2)/(2/√2)
    ],
)
def test_bottom_layer_analytic(direction, expected):
    n = _unit(direction)
    assert expected == pytest.approx(1 - _box_area((1, 0.5, 1), n) / _box_area((1, 1, 1), n))
    errors = raycast_errors(n[None, :], 256, 0)[:, 0]
    assert abs(errors[BOTTOM_LAYER] - expected) < TOL_256, errors[BOTTOM_LAYER]
    # The other layers: the top layer (y-bit set) and the x- and z-halves are the same shape.
    top_layer = 0xFF ^ BOTTOM_LAYER
    assert abs(errors[top_layer] - expected) < TOL_256


def test_single_child_bit_layout():
    """Octant c = x | y<<1 | z<<2, bit set = high half. Viewed along +x, children 0 and 1
    (same y, z) project onto one square, so the mask {0, 1} loses as much as one child; so do
    {0, 2}/{0, 4} along y/z. Along the other axes the pair covers twice the area."""
    errors = raycast_errors(_unit([(1, 0, 0), (0, 1, 0), (0, 0, 1)]), 128, 0)
    tol = 2 * TOL_256  # 128²: the jitter bound doubles when R halves (≈ ×2.8 for R^-1.5)
    for axis, pair in enumerate((0b11, 0b101, 0b10001)):
        for view in range(3):
            expected = 0.75 if view == axis else 0.5
            assert abs(errors[pair, view] - expected) < tol, (pair, view, errors[pair, view])


def _plane_basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
    right = _unit(np.cross(d, helper))
    return right, np.cross(d, right)


_UNIT_CORNERS = np.array(list(itertools.product((0.0, 1.0), repeat=3)))


def exact_errors(dirs: np.ndarray) -> np.ndarray:
    """(256, n) exact errors: union area of the present children's projected hulls over the
    parent's projected hull, all with shapely (no rays)."""
    out = np.zeros((256, len(dirs)))
    for k, d in enumerate(dirs):
        right, up = _plane_basis(d)

        def hull(points, right=right, up=up):
            return MultiPoint(np.c_[points @ right, points @ up]).convex_hull

        children = []
        for c in range(8):
            low = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1]) * 0.5 - 0.5
            children.append(hull(low + 0.5 * _UNIT_CORNERS))
        parent = hull(_UNIT_CORNERS - 0.5).area
        for m in range(1, 256):
            area = unary_union([children[c] for c in range(8) if m >> c & 1]).area
            out[m, k] = 1.0 - area / parent
    return out


def test_shapely_reference_single_child_is_exact():
    """The reference itself: one child is exactly ¼ of the parent, so e = 0.75."""
    ref = exact_errors(_unit(np.random.default_rng(3).normal(size=(4, 3))))
    assert np.allclose(ref[SINGLE_CHILDREN], 0.75, atol=1e-12)
    assert np.allclose(ref[255], 0.0, atol=1e-12)


def test_raycast_matches_exact_polygon_areas():
    dirs = _unit(np.random.default_rng(1).normal(size=(30, 3)))
    ref = exact_errors(dirs)
    est = raycast_errors(dirs, 256, 0)
    diff = np.abs(est - ref)
    worst = diff.max()
    m, k = np.unravel_index(diff.argmax(), diff.shape)
    msg = (
        f"max |ray − exact| = {worst:.2e} (rms {np.sqrt(np.mean(diff**2)):.1e}) at mask {m:#04x}, "
        f"direction {dirs[k]}; Table 3.1 bound at 256²: {TABLE_3_1[256]}"
    )
    assert worst < TABLE_3_1[256], msg
    assert worst < TOL_256, msg


def test_same_seed_is_bit_identical_and_seeds_differ_within_tolerance():
    dirs = _unit(np.random.default_rng(5).normal(size=(12, 3)))
    a = raycast_errors(dirs, 128, seed=7)
    b = raycast_errors(dirs, 128, seed=7)
    c = raycast_errors(dirs, 128, seed=8)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.abs(a - c).max() < 2 * TOL_256  # 128²: see test_single_child_bit_layout


def test_thread_count_does_not_change_results():
    dirs = _unit(np.random.default_rng(6).normal(size=(16, 3)))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = raycast_errors(dirs, 128, 3)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = raycast_errors(dirs, 128, 3)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one, two)


def test_direction_length_does_not_matter():
    dirs = _unit(np.random.default_rng(7).normal(size=(5, 3)))
    # Normalising 3.5·d may differ from d in the last bit; allow a ray or two of the 64².
    diff = np.abs(raycast_errors(dirs, 64, 0) - raycast_errors(dirs * 3.5, 64, 0)).max()
    assert diff <= 2.5 / 64**2, diff


@pytest.mark.parametrize(
    "args",
    [
        (np.zeros((0, 3)), 64),
        (np.ones((4, 2)), 64),
        (np.ones(3), 64),
        (np.ones((2, 3)), 1),
        (np.ones((2, 3)), 5000),
    ],
)
def test_bad_shapes_and_resolutions_raise(args):
    with pytest.raises(VoxfieldError):
        raycast_errors(*args)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("bad", [(0.0, 0.0, 0.0), (np.nan, 0.0, 1.0), (np.inf, 0.0, 0.0)])
def test_degenerate_directions_raise(bad):
    with pytest.raises(VoxfieldError):
        raycast_errors(np.array([bad]), 16, 0)
