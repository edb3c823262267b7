"""The threshold study (EA §5.4): monotone ray counts, fixed adaptive row, files, resumption."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies.threshold_study import run_threshold_study
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def scene():
    octree = build_octree(pillars(64))
    return octree, Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=24)


def test_threshold_study_is_monotone_and_resumable(scene, tmp_path):
    octree, camera = scene
    kwargs = {"thresholds": (0.3, 0.05, 0.15, 0.1), "scene_name": "pillars"}
    report = run_threshold_study(octree, camera, tmp_path, **kwargs)
    rows = sorted(report["rows"], key=lambda r: r["threshold"])
    for key in ("rays", "rays_hit_pixels", "steps"):
        counts = [r["error_aware"][key] for r in rows]
        assert counts == sorted(counts, reverse=True)  # higher threshold, fewer rays
    assert rows[0]["error_aware"]["rays"] > rows[-1]["error_aware"]["rays"]
    assert all(r["adaptive"] == report["adaptive"] for r in rows)  # the fixed row
    assert report["reference"]["rays"] == 16 * camera.width * camera.height
    for name in ("results.json", "results.md", "thresholds.png"):
        assert (tmp_path / name).is_file()
    text = (tmp_path / "results.md").read_text()
    assert "Table 5.27" in text and "Table 5.28" in text
    items = sorted((tmp_path / "items").glob("*.json"))
    assert len(items) == 4 + 2  # cells + reference + adaptive
    stamps = {p.name: p.stat().st_mtime_ns for p in items}
    again = run_threshold_study(octree, camera, tmp_path, **kwargs)
    assert {p.name: p.stat().st_mtime_ns for p in items} == stamps  # nothing recomputed
    assert again["rows"] == report["rows"]


def test_study_cli_parses_thresholds():
    from voxfield.cli.cmd_study import register as add_study_parser

    parser = argparse.ArgumentParser()
    add_study_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["study", "thresholds", "builtin:pillars", "--thresholds",
                              "0.1,0.2", "--base-lod", "cone", "--size", "32"])
    assert args.thresholds == (0.1, 0.2) and args.base_lod is None and args.size == 32
    assert args.func.__name__ == "run_thresholds"


def test_a_scaled_channel_is_studied_apart_with_the_same_costs(scene, tmp_path):
    # A channel that is albedo × 0.5 changes colours, not geometry: the error-aware ray counts
    # (geometric error) match albedo's; the cache keeps the two channels apart.
    octree, camera = scene
    half_albedo = octree.color * np.float32(0.5)
    octree = octree.recoloured(attributes={**octree.attributes, "half": half_albedo})
    kwargs = {"thresholds": (0.1,), "scene_name": "pillars"}
    albedo = run_threshold_study(octree, camera, tmp_path, **kwargs)
    half = run_threshold_study(octree, camera, tmp_path, channel="half", **kwargs)
    assert half["rows"][0]["error_aware"]["rays"] == albedo["rows"][0]["error_aware"]["rays"]
    assert half["rows"][0]["error_aware"]["psnr"] != albedo["rows"][0]["error_aware"]["psnr"]
    assert len(list((tmp_path / "items").glob("*.json"))) == 2 * 3
