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
    # The message says the range searched and the closest the renders came, as numbers a
    # person reads: the fewest rays at the range's top, the best PSNR at its bottom.
    fewest = render_error_aware(octree, camera, table, threshold=1.0).total_rays
    with pytest.raises(VoxfieldError) as refused:
        calibrate_threshold(octree, camera, target_rays=1, table=table, iterations=3)
    assert str(refused.value) == (f"no threshold in 0..1 meets the budget of 1 rays: the "
                                  f"fewest, {fewest:,}, come at threshold 1")
    with pytest.raises(VoxfieldError) as refused:
        calibrate_threshold(octree, camera, target_psnr=1000.0, table=table, iterations=3)
    message = str(refused.value)
    assert message.startswith("no threshold in 0..1 meets the target of 1000 dB: the best, ")
    assert message.endswith(" dB, comes at threshold 0")
    best = message.split("the best, ")[1].split(" dB")[0]
    assert len(best.split(".")[1]) == 2  # 29.96, not 29.962130326265637
