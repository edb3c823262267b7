"""The decay × threshold sweep: monotone ray counts, files written, finished cells reused."""

from __future__ import annotations

import json

import pytest

from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies.sweep import run_sweep
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
