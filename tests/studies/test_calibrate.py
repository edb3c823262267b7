"""Threshold calibration: the answer meets its target and is the edge of the feasible range."""

from __future__ import annotations

import pytest

from voxfield.error_table import build_error_table
from voxfield.errors import VoxfieldError
from voxfield.render import Camera
from voxfield.render.error_aware import render_error_aware
from voxfield.scene.builtin import pillars
from voxfield.studies.calibrate import calibrate_threshold
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def setup():
    octree = build_octree(pillars(64))
    camera = Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=32)
    table = build_error_table(n_directions=64, resolution=64, oct_resolution=16)
    return octree, camera, table


def test_ray_budget_gives_the_smallest_threshold_within_budget(setup):
    octree, camera, table = setup
    budget = render_error_aware(octree, camera, table, threshold=0.25).total_rays
    cal = calibrate_threshold(octree, camera, target_rays=budget, table=table, iterations=12)
    assert cal.rays <= budget
    slightly_lower = render_error_aware(octree, camera, table, threshold=cal.threshold - 0.01)
    assert cal.threshold <= 0.25 + 1e-3
    assert slightly_lower.total_rays >= cal.rays
    assert len(cal.trail) == 12


def test_psnr_target_is_met(setup):
    octree, camera, table = setup
    cal = calibrate_threshold(octree, camera, target_psnr=25.0, table=table, iterations=8)
    assert cal.psnr >= 25.0
    # A little more threshold would miss the target or sit at the range's end.
    assert cal.threshold > 0.1


def test_impossible_or_ambiguous_targets_raise(setup):
    octree, camera, table = setup
    with pytest.raises(VoxfieldError, match="exactly one"):
        calibrate_threshold(octree, camera, table=table)
    with pytest.raises(VoxfieldError, match="no threshold"):
        calibrate_threshold(octree, camera, target_rays=1, table=table, iterations=3)
