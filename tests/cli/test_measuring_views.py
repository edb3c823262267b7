"""The view the measuring commands (``compare``, ``sweep``, ``calibrate``, ``study thresholds``,
``study lighting``, ``study normalisation``) take by default: ``--camera auto``, as ``render``
takes it. Their old default, ``top``, looked at a room such as the Cornell box from above its
ceiling: every pixel saw the one white roof, and the renderers compared differed in outlines
alone."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from voxfield.cli import main
from voxfield.cli.main import build_parser
from voxfield.cli.options import open_octree, scene_camera, study_camera, with_camera
from voxfield.render import render_lod

MEASURING = (["compare"], ["sweep"], ["calibrate", "--target-rays", "100"],
             ["study", "thresholds"], ["study", "lighting"], ["study", "normalisation"])


def _parsed(command: list[str], scene: str) -> argparse.Namespace:
    footprint = ["--footprint", "64"] if scene.startswith("terrain:") else []
    words = command[1:2] if command[0] == "study" else []  # the study's name
    rest = command[len(words) + 1:]
    return build_parser(command[0]).parse_args(
        [command[0], *words, scene, *rest, "--size", "16", *footprint])


@pytest.mark.parametrize("command", MEASURING, ids=lambda c: " ".join(c[:2]))
@pytest.mark.parametrize(("scene", "preset"), [("builtin:pillars", "orbit"),
                                               ("terrain:desert", "top")])
def test_the_default_view_is_the_one_render_takes(command, scene, preset):
    """Top over a terrain (the EA thesis's view), from around anything else."""
    args = _parsed(command, scene)
    octree = open_octree(args)
    assert args.camera == "auto"
    expected = scene_camera(with_camera(args, preset), octree)
    render_view = scene_camera(_parsed(["render", "--out", "unused.png"], scene), octree)
    assert study_camera(args, octree).params.tolist() == expected.params.tolist()
    assert render_view.params.tolist() == expected.params.tolist()


def _view_of_the_box(octree, view) -> tuple[float, float, int]:
    """The shares of a Cornell box view's pixels showing its red and its green wall, and how
    many face orientations its pixels show."""
    result = render_lod(octree, view, lod=0)
    image = result.image.reshape(-1, 3)
    red = np.mean((image[:, 0] > 3 * image[:, 1]) & (image[:, 0] > 0.05))
    green = np.mean((image[:, 1] > 2 * image[:, 0]) & (image[:, 1] > 0.05))
    hit = result.hit_count.reshape(-1) > 0
    faces = np.unique(np.round(result.normal.reshape(-1, 3)[hit]), axis=0)
    return float(red), float(green), len(faces)


def test_a_room_is_measured_where_its_colours_are_seen(tmp_path):
    """The Cornell box from above is its roof (every pixel faces up; its coloured walls are
    a pixel's edge); the default view sees its red and green walls and more faces than one,
    and the comparison names the view it took, not ``auto``."""
    args = _parsed(["compare"], "builtin:cornell")
    args.size = 64
    octree = open_octree(args)
    red, green, faces = _view_of_the_box(octree, scene_camera(with_camera(args, "top"), octree))
    assert faces == 1 and red < 0.05 and green < 0.05
    red, green, faces = _view_of_the_box(octree, study_camera(args, octree))
    assert faces >= 3 and red > 0.05 and green > 0.05

    out = tmp_path / "compare"
    assert main(["compare", "builtin:cornell", "--size", "16", "--quiet", "--out",
                 str(out)]) == 0
    report = json.loads((out / "results.json").read_text())
    assert report["camera"]["label"] == "orbit"


def test_each_scene_of_a_normalisation_study_gets_its_own_view(monkeypatch, tmp_path):
    """A terrain beside a model: the terrain is looked down on and the model from around,
    whichever is named first (the first scene's kind decided every view)."""
    import voxfield.cli.cmd_study as cmd_study

    seen = {}

    def capture(scenes, out, **_):
        seen.update(scenes)
        return {"normalisation": 1.0}

    monkeypatch.setattr(cmd_study, "run_normalisation_study", capture)
    for order in (("builtin:pillars", "terrain:desert"), ("terrain:desert", "builtin:pillars")):
        seen.clear()
        assert main(["study", "normalisation", *order, "--footprint", "64", "--size", "16",
                     "--quiet", "--out", str(tmp_path / "n")]) == 0
        for spec, preset in (("builtin:pillars", "orbit"), ("terrain:desert", "top")):
            octree, view = seen[spec]
            args = _parsed(["study", "normalisation"], spec)
            expected = scene_camera(with_camera(args, preset), octree)
            assert np.array_equal(view.params, expected.params)
