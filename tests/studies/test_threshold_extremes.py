"""The threshold study with thresholds far outside the thesis's range: every finite one (and
infinity) ends in a finished folder, figure and report included."""

from __future__ import annotations

import io
import json
import math

import matplotlib.pyplot as plt
import pytest
from PIL import Image

from voxfield.cli import main
from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies import threshold_study
from voxfield.studies.threshold_study import run_threshold_study
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def scene():
    octree = build_octree(pillars(16))
    return octree, Camera.look_at((20, 16, 24), (8, 2, 8), fov_deg=50, width=8)


@pytest.mark.parametrize("thresholds", [(1e308,), (-1e308, 0.5, 1e308)])
def test_any_threshold_gives_the_figure_and_the_report(scene, tmp_path, thresholds):
    octree, camera = scene
    report = run_threshold_study(octree, camera, tmp_path, thresholds=thresholds)
    assert [row["threshold"] for row in report["rows"]] == list(thresholds)
    with Image.open(tmp_path / "thresholds.png") as figure:
        assert figure.size[0] > 1000  # the five panels were drawn
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "<table>" in html and "thresholds" in html
    json.loads((tmp_path / "results.json").read_text())  # strict JSON


def test_the_cli_study_with_a_huge_threshold_finishes(tmp_path, capsys):
    assert main(["study", "thresholds", "builtin:pillars", "--size", "8", "--quiet",
                 "--thresholds", "1e308", "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().err == ""
    assert (tmp_path / "thresholds.png").is_file() and (tmp_path / "report.html").is_file()


def _cell(k: int) -> dict:
    return {"rays": 100 - k, "rays_hit_pixels": 90 - k, "steps": 1000 - k, "psnr": 30.0 + k,
            "rmse": 0.01, "ssim": 0.9}


@pytest.mark.parametrize("thresholds", [
    (1.7976931348623157e308,), (0.1, float("inf")), (float("nan"), 0.2), (-1e308, 1e308),
])
def test_every_threshold_is_a_point_inside_the_figure(thresholds):
    report = {"scene": "s", "decay": 0.2, "adaptive": _cell(0),
              "rows": [{"threshold": t, "error_aware": _cell(k)}
                       for k, t in enumerate(thresholds)]}
    figure = threshold_study._figure(report)
    try:
        figure.savefig(io.BytesIO(), format="png")
        for ax in figure.axes:
            low, high = ax.get_xlim()
            x = ax.lines[0].get_xdata()
            assert len(x) == len(thresholds)
            assert all(math.isfinite(v) and low < v < high for v in x), (x, low, high)
    finally:
        plt.close(figure)
