"""A PSNR of identical images is infinite, which JSON keeps as null: the tables must say ∞
(the best score), not "—" (nothing measured), whether the value is fresh or read back from
a study's cache; the lighting figure must not drop it as a missing bar."""

from __future__ import annotations

import json
import math

from voxfield.json_output import to_json
from voxfield.metrics import psnr_text
from voxfield.studies.lighting_study import _figure as lighting_figure
from voxfield.studies.report import fmt_psnr
from voxfield.studies.threshold_study import _markdown as threshold_markdown


def test_a_psnr_cell_tells_equal_from_unmeasured():
    assert fmt_psnr({"psnr": math.inf}) == "∞"
    assert fmt_psnr({"psnr": None}) == "∞"  # the same, read back from JSON
    assert fmt_psnr({"psnr": 31.234}, ".1f") == "31.2"
    assert fmt_psnr(None) == fmt_psnr({}) == fmt_psnr({"rays": 3}) == "—"
    # The probe render's console and comparison figure read a bare value the same way.
    assert psnr_text(math.inf) == psnr_text(None) == "∞"
    assert psnr_text(math.nan) == fmt_psnr({"psnr": math.nan}) == "—"
    assert psnr_text(31.234) == "31.23"


def _quality(psnr):
    return {"rays": 10, "rays_hit_pixels": 10, "steps": 20, "psnr": psnr, "rmse": 0.0,
            "ssim": 1.0}


def test_a_study_table_reads_the_same_fresh_and_from_its_cache():
    report = {"scene": "s", "width": 4, "height": 4, "decay": 0.2, "base_lod": 2, "seed": 0,
              "reference": {"rays": 256, "steps": 300}, "adaptive": _quality(20.0),
              "rows": [{"threshold": 0.1, "error_aware": _quality(math.inf),
                        "adaptive": _quality(20.0)}]}
    fresh = threshold_markdown(report)
    cached = threshold_markdown(json.loads(json.dumps(to_json(report))))
    assert fresh == cached
    assert "| 0.1 | 20.000 | ∞ |" in fresh


def test_the_lighting_figure_draws_an_equal_image_as_the_tallest_bar():
    contenders = ("adaptive", "error_aware", "lighting_aware")
    row = {"channel": "albedo", **{name: _quality(psnr) for name, psnr in
                                   zip(contenders, (15.0, None, 40.0), strict=True)}}
    figure = lighting_figure({"scene": "s", "rows": [row]})
    psnr_axis = figure.axes[2]
    heights = [bar.get_height() for bar in psnr_axis.patches]
    assert len(heights) == 3 and heights[1] > max(heights[0], heights[2])
    assert "∞" in [text.get_text() for text in psnr_axis.texts]


def test_curves_that_share_points_stay_apart_and_legends_cover_no_panel():
    """In curves.png an adaptive renderer that never refined sat, one point, under the LOD
    curve's first, and "EA d=0.2" under "EA+colour"; thresholds.png's legends covered
    points."""
    from voxfield.studies.curves_study import curves_figure
    from voxfield.studies.threshold_study import _figure as threshold_figure

    point = {"steps": 100, "rays": 50, "psnr": 30.0, "ssim": 0.9}
    curves = {name: {"points": [dict(point)]} for name in ("EA d=0.2", "EA+colour", "A", "LOD")}
    figure = curves_figure({"scene": "s", "cameras": {"top": {"kind": "perspective",
                                                               "curves": curves}}})
    for ax in figure.axes:
        lines = ax.get_lines()
        assert len({line.get_marker() for line in lines}) == len(lines) == 4
        assert len({line.get_markersize() for line in lines}) == 4
    def varied(t):
        return {"rays": 100 - 100 * t, "rays_hit_pixels": 90 - 100 * t, "steps": 300 - 100 * t,
                "psnr": 30 - t, "rmse": 0.01 + t, "ssim": 0.95 - t}

    report = {"scene": "s", "decay": 0.2, "adaptive": varied(0.5),
              "rows": [{"threshold": t, "error_aware": varied(t)} for t in (0.1, 0.2)]}
    figure = threshold_figure(report)
    assert all(ax.get_legend() is None for ax in figure.axes) and len(figure.legends) == 1


def test_the_shadow_table_tells_the_reference_from_an_equal_image():
    """The reference's own row has no PSNR ("—"); a render equal to it has an infinite one,
    which JSON stores as null (∞). Both were null, and both read "—"."""
    from voxfield.studies.shadow_study import results_markdown, summary_text

    def row(renderer, **psnr):
        return {"renderer": renderer, "shadow_lod": renderer, "light_samples": 4,
                "shadow_rays": 10, "shadow_traversals": 10, "shadow_steps": 30,
                "shadow_steps_per_ray": 3.0, "shadow_refinements": 0, "traversal_steps": 90,
                "seconds": 0.1, **psnr}

    report = {"settings": {"lod_distance": 8.0, "threshold": 0.1, "decay": 0.2,
                           "encoding": "f16", "max_refinements": None},
              "beam": None, "scene": {"name": "s", "depth": 5, "voxels": 100},
              "camera": {"width": 4, "height": 4, "label": ""}, "note": "",
              "folder": "out", "rows": [row("reference"), row("full-res", psnr=math.inf),
                                        row("distance", psnr=21.5)]}
    for text in (results_markdown(report),
                 results_markdown(json.loads(json.dumps(to_json(report))))):
        cells = {line.split("|")[1].strip(): line.split("|")[3].strip()
                 for line in text.splitlines() if line.startswith("| ")}
        assert (cells["reference"], cells["full-res"], cells["distance"]) == ("—", "∞", "21.50")
    console = summary_text(report).splitlines()
    assert console[1].split()[2] == "—" and console[2].split()[2] == "∞"
