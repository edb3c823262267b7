"""A study folder holds one study: its report shows every figure in the folder, so a second
study written into it showed the first one's figures under its own title. Another study is
refused before its work; the same study resumes as before."""

from __future__ import annotations

import json

import pytest

from cli_output import one_error_line
from voxfield.cli.main import main
from voxfield.errors import VoxfieldError
from voxfield.studies.report import STUDY_MARK, StudyFolder


def test_a_folder_is_claimed_by_its_first_output_and_refused_to_another_study(tmp_path):
    folder = StudyFolder(tmp_path / "s", study="study thresholds")
    assert not (tmp_path / "s").exists()  # nothing written, nothing claimed
    folder.write_text("results.md", "# thresholds\n")
    assert json.loads((tmp_path / "s" / STUDY_MARK).read_text()) == {
        "study": "study thresholds"}
    with pytest.raises(VoxfieldError, match="voxfield study thresholds.*another --out"):
        StudyFolder(tmp_path / "s", study="sweep")
    again = StudyFolder(tmp_path / "s", study="study thresholds", fresh=True)
    assert again.value_item("x", {"k": 1}, lambda: {"v": 1}) == {"v": 1}


def test_a_folder_an_older_version_wrote_or_a_damaged_mark_is_claimed_anew(tmp_path):
    (tmp_path / "results.json").write_text("{}")
    (tmp_path / STUDY_MARK).write_text("[not, json")
    StudyFolder(tmp_path, study="sweep").write_json("results.json", {"a": 1})
    assert json.loads((tmp_path / STUDY_MARK).read_text()) == {"study": "sweep"}


def test_the_command_line_refuses_a_second_study_before_its_renders(tmp_path, capsys,
                                                                    monkeypatch):
    out = tmp_path / "norm"
    assert main(["study", "normalisation", "builtin:pillars", "--size", "16", "--quiet",
                 "--out", str(out)]) == 0
    before = sorted(p.name for p in out.iterdir())

    def never(*args, **kwargs):
        raise AssertionError("the probe study's work began in a folder it cannot use")

    monkeypatch.setattr("voxfield.cli.cmd_study.probe_resolution_study", never)
    assert main(["study", "probe-resolution", "builtin:pillars", "--grid", "1x1x1",
                 "--resolutions", "8", "--quiet", "--out", str(out)]) == 2
    assert "voxfield study normalisation" in one_error_line(capsys)
    assert sorted(p.name for p in out.iterdir()) == before
    assert main(["study", "normalisation", "builtin:pillars", "--size", "16", "--quiet",
                 "--out", str(out)]) == 0


def test_a_folder_that_cannot_be_written_is_refused_before_the_work(tmp_path, capsys,
                                                                     monkeypatch):
    """A study into a path under a file rendered everything, then failed at its first
    output; it is refused as its folder is opened, and nothing is left behind."""
    (tmp_path / "notes.txt").write_text("a file, not a folder")
    out = tmp_path / "notes.txt" / "sweep"
    with pytest.raises(NotADirectoryError):
        StudyFolder(out, study="sweep")

    def never(*args, **kwargs):
        raise AssertionError("the sweep began its renders in a folder it cannot write")

    monkeypatch.setattr("voxfield.studies.sweep.render_reference", never)
    assert main(["sweep", "builtin:pillars", "--size", "8", "--quiet", "--out", str(out)]) == 2
    assert f"cannot use {tmp_path / 'notes.txt'}: a part of the path is a file" in \
        one_error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
