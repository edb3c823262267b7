"""Horizon slopes bound how steeply a ray must rise to clear every column ahead."""

from __future__ import annotations

import math

import numpy as np
import pytest

from random_scenes import octree_and_columns, overhanging_terrain, pillar_field
from voxfield.kernels.upward_rays import quadrant
from voxfield.svo.column_tops import column_tops, no_column_tops
from voxfield.svo.horizons import NOTHING_AHEAD, RING, horizon_slopes


def _level0(columns) -> np.ndarray:
    return columns.tops[: int(columns.level_width[0] * columns.level_depth[0])].reshape(
        int(columns.level_width[0]), int(columns.level_depth[0])).astype(np.int64)


def _steepest_ahead(tops: np.ndarray, step_x: int, step_z: int) -> np.ndarray:
    """Brute force, per column: the largest rise over gap to any higher column ahead
    (``inf`` for a touching one, ``NOTHING_AHEAD`` for none), every pair at once."""
    xs, zs = np.meshgrid(np.arange(tops.shape[0]), np.arange(tops.shape[1]), indexing="ij")
    xs, zs, heights = xs.ravel(), zs.ravel(), tops.ravel().astype(np.float64)
    ahead_x = (xs[None, :] - xs[:, None]) * step_x
    ahead_z = (zs[None, :] - zs[:, None]) * step_z
    rise = heights[None, :] - heights[:, None]
    counts = (ahead_x >= 0) & (ahead_z >= 0) & (rise > 0)
    gap = np.hypot(np.maximum(ahead_x - 1, 0), np.maximum(ahead_z - 1, 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(counts, rise / gap, -np.inf).max(axis=1)
    return np.where(np.isneginf(slope), NOTHING_AHEAD, slope)


@pytest.mark.parametrize("scene", [pillar_field(seed=2, size=45),
                                   overhanging_terrain(seed=1, size=29)])
def test_slopes_bound_the_steepest_column_ahead_from_above(scene):
    """Every stored slope is at least the brute-force one, infinite exactly where a higher
    column touches ahead, and no looser than the rings allow near the column."""
    columns = octree_and_columns(scene)[2]
    tops = _level0(columns)
    slopes = horizon_slopes(columns)
    assert slopes.shape == (tops.size, 4) and slopes.dtype == np.float32
    exact_count = 0
    for q, (step_x, step_z) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        assert quadrant(float(step_x), float(step_z)) == q
        stored = slopes[:, q].astype(np.float64)
        exact = _steepest_ahead(tops, step_x, step_z)
        assert np.array_equal(np.isinf(stored), np.isinf(exact))
        some = exact != NOTHING_AHEAD
        assert np.all(stored[some] >= exact[some])
        exact_count += np.isclose(stored, exact, rtol=1e-5)[some & np.isfinite(exact)].sum()
    assert exact_count > 0


def test_a_tower_within_the_near_columns_is_bounded_exactly():
    """Flat ground with one tower three columns ahead: the slope is its rise over the gap
    of two columns between them."""
    size = 12
    voxels = [(x, 0, z) for x in range(size) for z in range(size)]
    voxels += [(7, y, 5) for y in range(1, 9)]
    columns = column_tops(np.array(voxels))
    slopes = horizon_slopes(columns)
    from_column = 4 * size + 5
    assert 2 * RING > 3
    assert slopes[from_column, quadrant(1.0, 1.0)] == pytest.approx(8 / 2, rel=1e-5)
    assert slopes[from_column, quadrant(-1.0, 1.0)] == NOTHING_AHEAD
    assert math.isinf(slopes[6 * size + 5, quadrant(1.0, -1.0)])


def test_no_pyramid_gives_no_slopes_and_a_bad_ring_is_refused():
    assert horizon_slopes(no_column_tops()).shape == (0, 4)
    with pytest.raises(ValueError, match="ring"):
        horizon_slopes(column_tops(np.array([[0, 0, 0]])), ring=1)
