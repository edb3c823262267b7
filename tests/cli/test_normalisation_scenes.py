"""study normalisation measures each scene it is given once, and says so where one repeats."""

from __future__ import annotations

import numpy as np

from cli_output import one_error_line
from voxfield.cli import cmd_study
from voxfield.cli.main import main
from voxfield.render.adaptive import window_variance


def _never(*args, **kwargs):
    raise AssertionError("opened a scene before refusing the list")


def test_a_scene_given_twice_to_the_normalisation_study_is_refused(monkeypatch, capsys,
                                                                   tmp_path):
    """Its scenes were kept by name: the second copy replaced the first, and the study said
    '1 scene(s)' for the two the user named, without a word."""
    monkeypatch.setattr(cmd_study, "open_octree", _never)
    assert main(["study", "normalisation", "builtin:sphere", "builtin:cornell",
                 "builtin:sphere", "--out", str(tmp_path / "n")]) == 2
    assert "builtin:sphere given twice" in one_error_line(capsys)


def test_a_one_pixel_view_is_refused_before_any_scene_opens(monkeypatch, capsys, tmp_path):
    """One pixel has no 3×3 neighbourhood: the study rendered every scene's first pass and
    then blamed 'empty or flat images'. Two pixels a side have one, and are measured."""
    monkeypatch.setattr(cmd_study, "open_octree", _never)
    assert main(["study", "normalisation", "builtin:sphere", "--size", "1",
                 "--out", str(tmp_path / "n")]) == 2
    assert one_error_line(capsys) == (
        "voxfield: error: --size 1: the variance is measured over each pixel's 3×3 "
        "neighbourhood, which a one-pixel image does not have")
    # Whatever colour a lone pixel has, its window holds itself alone; two pixels a side
    # already differ.
    assert window_variance(np.array([[0.7]]), np.ones((1, 1), bool)).max() == 0.0
    assert window_variance(np.array([[0.7, 0.1], [0.2, 0.9]]), np.ones((2, 2), bool)).min() > 0
