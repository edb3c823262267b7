"""``view.png``: the view a study measured, so that a camera under the terrain or looking
past the scene shows before its numbers are read."""

from __future__ import annotations

import re

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from PIL import Image

from voxfield.render.image_io import shade_for_display
from voxfield.render.result import RenderResult
from voxfield.scene.voxel_scene import linear_to_srgb
from voxfield.studies.figures import Panel, contact_sheet, view_sheet
from voxfield.studies.threshold_study import run_threshold_study


def _result(colour, facing) -> RenderResult:
    result = RenderResult.allocate(6, 8, renderer="reference")
    result.image[:] = colour
    result.normal[:] = facing
    result.normal[:, :4] = 0.0  # a miss keeps its colour
    return result


def test_each_panel_is_its_reference_lit_for_display():
    references = {"a": _result((0.8, 0.2, 0.1), (0.0, 1.0, 0.0)),
                  "b": _result((0.1, 0.5, 0.9), (1.0, 0.0, 0.0))}
    figure = view_sheet(references, title="t")
    shown = [ax for ax in figure.axes if ax.images]
    assert [ax.get_title() for ax in shown] == ["a (lit for display)", "b (lit for display)"]
    for ax, result in zip(shown, references.values(), strict=True):
        expected = linear_to_srgb(shade_for_display(result))
        assert np.allclose(np.asarray(ax.images[0].get_array()), expected, atol=1e-6)
        # the lit half differs from the missed half, which keeps the albedo
        assert not np.allclose(expected[:, 4:], linear_to_srgb(result.image[:, 4:]))


def test_a_threshold_study_shows_its_view_in_its_report(tmp_path):
    from voxfield.render.camera import preset_camera
    from voxfield.scene.loaders import load_scene
    from voxfield.svo import build_octree

    octree = build_octree(load_scene("builtin:pillars"))
    camera = preset_camera("top", *octree.voxel_bounds, size=16)
    run_threshold_study(octree, camera, tmp_path, thresholds=(0.1, 0.2))
    with Image.open(tmp_path / "view.png") as view:
        pixels = np.asarray(view.convert("L"))
    assert pixels.std() > 5  # the scene, not one flat colour
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    labels = re.findall(r"<figcaption>([^<]*)</figcaption>", html)
    assert labels and labels[0].lower().startswith("view"), labels


def test_a_long_title_stays_on_a_narrow_sheet_and_clear_of_its_panels():
    """A one-panel sheet (``light``'s preview of one sun) cut its title at both sides."""
    title = "terrain:desert: baked sun and sky light from above, north (-z) up, " * 2
    figure = contact_sheet([Panel("noon", np.zeros((4, 4, 3)))], columns=1, title=title)
    canvas = FigureCanvasAgg(figure)  # text extents in display pixels
    canvas.draw()
    renderer = canvas.get_renderer()
    box = figure._suptitle.get_window_extent(renderer)
    width, height = figure.bbox.width, figure.bbox.height
    assert 0.0 <= box.x0 and box.x1 <= width and box.y1 <= height
    panel_top = max(ax.get_tightbbox(renderer).y1 for ax in figure.axes if ax.images)
    assert box.y0 >= panel_top  # the title's lines sit above the panel's own title
