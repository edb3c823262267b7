"""Figure titles name a scene file by its name: a full path wrapped across the figure and
told its reader nothing, while ``results.json`` keeps the description whole."""

from __future__ import annotations

import json

import numpy as np
import pytest

from voxfield.cli.cmd_light import preview_sheet
from voxfield.lighting.sun import SunLight
from voxfield.studies.report import scene_title
from voxfield.studies.sweep import _closest_to_adaptive, _figure

DEEP = "/data/projects/lighting/2026/scenes/stanford/reconstruction/bunny.obj"


@pytest.mark.parametrize(("scene", "title"), [
    (DEEP, "bunny.obj"),
    ("relative/dir/monu1.vox", "monu1.vox"),
    ("teapot.vox", "teapot.vox"),
    ("dem:/srv/dem/N40W074.hgt", "dem:N40W074.hgt"),
    ("builtin:sphere", "builtin:sphere"),
    ("terrain:desert", "terrain:desert"),
])
def test_a_file_is_named_by_its_name_and_a_built_in_as_given(scene, title):
    assert scene_title(scene) == title


def test_the_sweep_figure_names_the_file_not_its_path():
    cells = [{"decay": 0.2, "threshold": t, "rays": rays, "steps": 3 * rays, "psnr": 30.0,
              "ssim": 0.9} for t, rays in ((0.2, 64), (0.05, 256))]
    report = {"scene": DEEP, "width": 8, "height": 8, "base_lod": 2,
              "adaptive": {"rays": 100, "steps": 300, "psnr": 28.0, "ssim": 0.8},
              "cells": cells, "closest_to_adaptive": _closest_to_adaptive(cells, 100, (0.2,))}
    figure = _figure(report, (0.2,), (0.2, 0.05))
    assert figure._suptitle.get_text() == "error-aware sweep — bunny.obj"


def test_the_sun_bake_preview_names_the_file_not_its_path():
    sun = SunLight("noon", azimuth_deg=180.0, elevation_deg=60.0, irradiance=(1.0, 1.0, 1.0),
                   sky=(0.1, 0.1, 0.1))
    figure = preview_sheet([("noon", np.zeros((4, 4, 3), np.float32))], [sun],
                           "/srv/dem/USGS/N40W074.hgt")
    title = " ".join(figure._suptitle.get_text().split())  # the sheet wraps long titles
    assert title.startswith("N40W074.hgt: baked sun and sky light")


def test_the_comparison_names_the_file_it_was_opened_from(tmp_path):
    """``compare`` titled its sheet and tables with the octree's name (``sphere``, whatever the
    file was called); now with the file's name, and ``results.json`` keeps the path."""
    from voxfield.cli import main
    from voxfield.studies.compare import _sheet_title

    deep = tmp_path / "scenes" / "2026" / "ball.npz"
    deep.parent.mkdir(parents=True)
    assert main(["--quiet", "build", "builtin:sphere", "--out", str(deep)]) == 0
    out = tmp_path / "compare"
    assert main(["--quiet", "compare", str(deep), "--size", "12", "--out", str(out)]) == 0
    report = json.loads((out / "results.json").read_text())
    assert report["scene"]["name"] == "sphere" and report["scene"]["description"] == str(deep)
    assert (out / "results.md").read_text(encoding="utf-8").startswith(
        "# Renderer comparison: ball.npz\n")
    assert _sheet_title(report) == "ball.npz: 12×12, camera orbit"
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "<title>Renderer comparison: ball.npz</title>" in page  # results.md's heading
