"""Bjøntegaard deltas against curves whose gap is known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.studies.bjontegaard import bd_cost, bd_quality

COST = np.array([1e4, 3e4, 1e5, 3e5, 1e6])


def quality(cost):
    """A concave, rising cost–quality curve (dB against log cost)."""
    return 20.0 + 6.0 * np.log10(cost / 1e4) - 0.5 * np.log10(cost / 1e4) ** 2


def test_a_curve_shifted_up_by_one_db_gains_one_db():
    assert bd_quality(COST, quality(COST), COST, quality(COST) + 1.0) == pytest.approx(1.0)
    assert bd_quality(COST, quality(COST) + 1.0, COST, quality(COST)) == pytest.approx(-1.0)


def test_the_same_quality_for_four_fifths_of_the_cost_saves_twenty_percent():
    cheaper = 0.8 * COST
    assert bd_cost(COST, quality(COST), cheaper, quality(COST)) == pytest.approx(-20.0)
    # And, measured at equal cost, that curve is higher by the gap the slope implies.
    gain = bd_quality(COST, quality(COST), cheaper, quality(COST))
    assert gain > 0


def test_identical_curves_differ_by_nothing_whatever_the_sampling():
    dense = np.geomspace(1e4, 1e6, 17)
    assert bd_quality(COST, quality(COST), dense, quality(dense)) == pytest.approx(0.0, abs=0.02)
    assert bd_cost(COST, quality(COST), dense, quality(dense)) == pytest.approx(0.0, abs=0.5)


def test_curves_that_do_not_overlap_or_have_one_point_are_refused():
    with pytest.raises(VoxfieldError, match="overlap"):
        bd_quality(COST, quality(COST), COST * 1e3, quality(COST))
    with pytest.raises(VoxfieldError, match="two distinct"):
        bd_quality(COST[:1], quality(COST[:1]), COST, quality(COST))
    with pytest.raises(VoxfieldError, match="positive"):
        bd_cost(-COST, quality(COST), COST, quality(COST))


def test_a_sliver_of_overlap_is_refused():
    with pytest.raises(VoxfieldError, match="too little"):
        bd_quality(COST, quality(COST), COST * 99.0, quality(COST))


def test_a_dominated_setting_changes_nothing():
    """A point costing more for less quality is never chosen: it leaves the deltas alone."""
    worse_cost = np.append(COST, 5e5)
    worse_psnr = np.append(quality(COST), 21.0)
    base = bd_quality(COST, quality(COST), COST, quality(COST) + 1.0)
    assert bd_quality(worse_cost, worse_psnr, COST, quality(COST) + 1.0) == pytest.approx(base)
    assert bd_cost(worse_cost, worse_psnr, 0.8 * COST, quality(COST)) == pytest.approx(-20.0)
