"""An image equal to the reference has an infinite PSNR (null in results.json). The study
figures drew it as NaN: the best points vanished from every PSNR panel, a panel of them only
was empty under a made-up axis, and the sweep's figure raised TypeError where two thresholds
cast the same rays, one equal to the reference. They now stand on the panel's top edge."""

from __future__ import annotations

import math

import numpy as np

from voxfield.studies.curves_study import curves_figure
from voxfield.studies.psnr_axis import INFINITE_GID, INFINITE_NOTE
from voxfield.studies.resolution_study import _figure as resolution_figure
from voxfield.studies.sweep import _closest_to_adaptive
from voxfield.studies.sweep import _figure as sweep_figure
from voxfield.studies.threshold_study import _figure as threshold_figure


def _quality(rays, psnr):
    return {"rays": rays, "rays_hit_pixels": rays, "steps": 3 * rays, "psnr": psnr,
            "rmse": 0.0 if psnr is None else 0.01, "ssim": 1.0, "rays_per_pixel": 1.0}


def _top_edge_x(ax) -> list[float]:
    """x of what an axis draws for infinite PSNRs, on its top edge (y = 1 in axes units)."""
    xs = []
    for line in ax.get_lines():
        if line.get_gid() == INFINITE_GID:
            assert np.allclose(line.get_ydata(), 1.0)
            xs += [float(x) for x in line.get_xdata()]
    return xs


def _panel(figure, title):
    return next(ax for ax in figure.axes if ax.get_title() == title)


def _notes(ax) -> list[str]:
    return [text.get_text() for text in ax.texts]


def _sweep_report(cells, decays, adaptive):
    return {"scene": "s", "width": 8, "height": 8, "base_lod": 2, "adaptive": adaptive,
            "cells": cells, "closest_to_adaptive": _closest_to_adaptive(
                cells, adaptive["rays"], decays)}


def test_sweep_figure_draws_equal_images_at_the_top_even_at_equal_ray_counts():
    cells = [{"decay": 0.2, "threshold": 0.2, **_quality(1000, None)},
             {"decay": 0.2, "threshold": 0.1, **_quality(1000, 40.0)},
             {"decay": 0.2, "threshold": 0.3, **_quality(600, 30.0)}]
    figure = sweep_figure(_sweep_report(cells, (0.2,), _quality(800, 25.0)), (0.2,),
                          (0.3, 0.2, 0.1))
    quality = _panel(figure, "quality per cost")
    assert _top_edge_x(quality) == [1000.0]
    assert INFINITE_NOTE in _notes(quality)
    assert quality.get_yticks().size  # finite points too: the axis keeps its numbers


def test_a_sweep_of_equal_images_only_says_so_and_shows_no_made_up_psnr_axis():
    cells = [{"decay": d, "threshold": t, **_quality(1000, None)}
             for d in (0.1, 0.2) for t in (math.inf, 0.1)]
    figure = sweep_figure(_sweep_report(cells, (0.1, 0.2), _quality(1000, None)), (0.1, 0.2),
                          (math.inf, 0.1))
    quality = _panel(figure, "quality per cost")
    assert _top_edge_x(quality) == [1000.0] * 5  # 2 decays × 2 thresholds, the adaptive star
    assert INFINITE_NOTE in _notes(quality)
    assert quality.get_yticks().size == 0


def test_threshold_figure_keeps_the_threshold_whose_image_equals_the_reference():
    rows = [{"threshold": t, "error_aware": _quality(rays, psnr)}
            for t, rays, psnr in ((0.05, 2000, None), (0.2, 1500, 27.0), (0.3, 900, 20.0))]
    figure = threshold_figure({"scene": "s", "decay": 0.2, "adaptive": _quality(1200, None),
                               "rows": rows})
    psnr_axis = _panel(figure, "PSNR (dB)")
    edge = _top_edge_x(psnr_axis)
    assert 0.05 in edge  # the point, at its threshold
    assert [0.0, 1.0] == edge[-2:] or [0.0, 1.0] == edge[:2]  # the adaptive line, across
    # the adaptive renderer's infinite PSNR did not stretch the axis to 1 dB
    assert psnr_axis.get_ylim()[0] > 15.0
    rmse_axis = _panel(figure, "RMSE")
    assert not _top_edge_x(rmse_axis) and INFINITE_NOTE not in _notes(rmse_axis)


def test_resolution_and_curve_figures_keep_equal_images():
    rows = [{"size": size, "reference": _quality(4 * size, 0.0),
             "adaptive": _quality(size, 20.0), "error_aware": _quality(2 * size, psnr)}
            for size, psnr in ((16, None), (32, 30.0))]
    figure = resolution_figure({"scene": "s", "threshold": 0.1, "rows": rows})
    psnr_axis = _panel(figure, "PSNR (dB)")
    assert _top_edge_x(psnr_axis) == [16.0]

    point = {"steps": 100, "rays": 50, "ssim": 1.0}
    curves = {"EA d=0.2": {"points": [{**point, "psnr": None},
                                      {**point, "steps": 50, "rays": 20, "psnr": 25.0}]},
              "LOD": {"points": [{**point, "steps": 30, "rays": 10, "psnr": 12.0}]}}
    figure = curves_figure({"scene": "s", "cameras": {"top": {"kind": "perspective",
                                                               "curves": curves}}})
    steps_panel, rays_panel = figure.axes[:2]
    assert _top_edge_x(steps_panel) == [100.0] and _top_edge_x(rays_panel) == [50.0]
    assert not _top_edge_x(figure.axes[2])  # SSIM
