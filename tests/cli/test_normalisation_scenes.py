"""study normalisation measures each scene it is given once, and says so where one repeats."""

from __future__ import annotations

from cli_output import one_error_line
from voxfield.cli import cmd_study
from voxfield.cli.main import main


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
