"""The decay × threshold sweep: monotone ray counts, files written, finished cells reused."""

from __future__ import annotations

import json
import math

import pytest

from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies.sweep import _closest_to_adaptive, _figure, _markdown, run_sweep
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def scene():
    octree = build_octree(pillars(64))
    return octree, Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=24)


def test_sweep_grid_is_monotone_and_resumable(scene, tmp_path):
    octree, camera = scene
    kwargs = {"decays": (0.1, 0.3), "thresholds": (0.4, 0.2, 0.05), "scene_name": "pillars"}
    report = run_sweep(octree, camera, tmp_path, **kwargs)
    for decay in (0.1, 0.3):
        rays = [c["rays"] for c in report["cells"] if c["decay"] == decay]
        assert rays == sorted(rays) and rays[0] < rays[-1]  # lower threshold, more rays
    for name in ("results.json", "results.md", "sweep.png"):
        assert (tmp_path / name).is_file()
    assert "Table 5.1" in (tmp_path / "results.md").read_text()
    items = sorted((tmp_path / "items").glob("*.json"))
    stamps = {p.name: p.stat().st_mtime_ns for p in items}
    again = run_sweep(octree, camera, tmp_path, **kwargs)
    assert {p.name: p.stat().st_mtime_ns for p in items} == stamps  # nothing recomputed
    assert json.loads((tmp_path / "results.json").read_text())["cells"] == json.loads(
        json.dumps(again["cells"]))
    assert len(items) == 2 * 3 + 2  # cells + reference + adaptive


def test_a_pick_at_the_grid_s_edge_says_so(scene, tmp_path):
    """The thesis's thresholds stop at 0.175: on a scene whose adaptive renderer casts fewer
    rays than any of them, the "closest" threshold was the grid's end, reported as a match.
    One threshold cannot bracket the adaptive count; a huge and a tiny one (one ray a pixel,
    every pixel refined) always do."""
    octree, camera = scene
    one = run_sweep(octree, camera, tmp_path / "one", decays=(0.2,), thresholds=(0.15,))
    assert not one["closest_to_adaptive"][0]["within_grid"]
    text = (tmp_path / "one" / "results.md").read_text()
    assert "0.150 (edge)" in text and "calibrate --target-rays" in text
    both = run_sweep(octree, camera, tmp_path / "both", decays=(0.2,), thresholds=(1e6, 1e-6))
    assert both["closest_to_adaptive"][0]["within_grid"]
    assert "(edge)" not in (tmp_path / "both" / "results.md").read_text()


def test_threshold_headers_read_as_the_picks_table_does():
    """The grid's headers and the figure's ticks printed ``inf`` and ``-1.0`` for the
    thresholds that the picks table, below them, prints as ``∞`` and ``-1``."""
    thresholds, decays = (math.inf, -1.0), (0.2,)
    cells = [{"decay": 0.2, "threshold": t, "rays": rays, "steps": 3 * rays, "psnr": 30.0,
              "ssim": 0.9} for t, rays in zip(thresholds, (64, 256), strict=True)]
    report = {"scene": "s", "width": 8, "height": 8, "base_lod": 2,
              "adaptive": {"rays": 100, "steps": 300, "psnr": 28.0, "ssim": 0.8},
              "cells": cells, "closest_to_adaptive": _closest_to_adaptive(cells, 100, decays)}
    text = _markdown(report, decays, thresholds)
    assert "| decay \\ threshold | ∞ | -1 |" in text
    assert "inf" not in text and "-1.0" not in text
    grid_panel = _figure(report, decays, thresholds).axes[0]
    assert [tick.get_text() for tick in grid_panel.get_xticklabels()] == ["∞", "-1"]
