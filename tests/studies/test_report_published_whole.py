"""A study folder's report files describe one run at every moment. A rerun wrote
results.json, results.md and its figures one by one and report.html last, so one stopped
part way left the new tables beside the old page and figures; and a figure the earlier run
wrote and this one did not stayed and was shown on the new page as this run's."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

import voxfield.studies.report as report
import voxfield.studies.threshold_study as threshold_study
from voxfield.cli import main
from voxfield.studies.report import STAGING, STUDY_MARK, StudyFolder


def _files(folder) -> dict[str, bytes]:
    """Every file the folder shows a reader (items and the mark aside)."""
    return {p.name: p.read_bytes() for p in folder.iterdir()
            if p.is_file() and p.name != STUDY_MARK}


def _run(root, number: int, figures=("view.png",), publish: bool = True) -> StudyFolder:
    folder = StudyFolder(root, study="sweep")
    folder.write_json("results.json", {"study": "sweep", "scene": f"run {number}"})
    folder.write_text("results.md", f"# run {number}\n\n| run |\n|---|\n| {number} |\n")
    for name in figures:
        folder.write_png(name, np.full((4, 4, 3), number / 10, np.float32))
    if publish:
        folder.publish_report()
    return folder


def test_a_run_stopped_before_publishing_leaves_the_earlier_report_whole(tmp_path):
    _run(tmp_path, 1)
    before = _files(tmp_path)
    assert set(before) == {"results.json", "results.md", "view.png", "report.html"}
    assert "run 1" in before["report.html"].decode()
    _run(tmp_path, 2, publish=False)
    assert _files(tmp_path) == before
    _run(tmp_path, 3)
    after = _files(tmp_path)
    assert set(after) == set(before) and not (tmp_path / STAGING).exists()
    assert "run 3" in after["report.html"].decode() and "run 2" not in after["report.html"].decode()
    assert json.loads(after["results.json"])["scene"] == "run 3"


def test_a_figure_the_new_run_did_not_draw_is_removed_not_shown(tmp_path):
    _run(tmp_path, 1, figures=("view.png", "error_aware_reuse.png"))
    _run(tmp_path, 2, figures=("view.png",))
    assert not (tmp_path / "error_aware_reuse.png").exists()
    assert "error aware reuse" not in (tmp_path / "report.html").read_text()
    mark = json.loads((tmp_path / STUDY_MARK).read_text())
    assert mark == {"study": "sweep",
                    "report": ["report.html", "results.json", "results.md", "view.png"]}


def test_a_file_the_report_never_wrote_is_kept(tmp_path):
    (tmp_path / "notes.png").write_bytes(b"the user's own")
    _run(tmp_path, 1)
    _run(tmp_path, 2, figures=())
    assert (tmp_path / "notes.png").read_bytes() == b"the user's own"
    assert not (tmp_path / "view.png").exists()


def test_a_publish_stopped_part_way_shows_no_page_and_is_undone_next(tmp_path, monkeypatch):
    _run(tmp_path, 1, figures=("view.png",))
    real = os.replace
    moved = []

    def stop_after_one(src, dst):  # of the moves out of staging (every write renames)
        if Path(src).parent.name == STAGING and Path(dst).parent.name != STAGING:
            if moved:
                raise KeyboardInterrupt
            moved.append(dst)
        real(src, dst)

    monkeypatch.setattr(report.os, "replace", stop_after_one)
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, 2, figures=("view.png", "extra.png"))
    monkeypatch.setattr(report.os, "replace", real)
    assert not (tmp_path / "report.html").exists()  # no page beside half-moved tables
    _run(tmp_path, 3, figures=("view.png",))
    assert set(_files(tmp_path)) == {"results.json", "results.md", "view.png", "report.html"}
    assert "run 3" in (tmp_path / "report.html").read_text()


def test_a_mark_naming_paths_outside_the_folder_removes_nothing_there(tmp_path):
    outside = tmp_path / "keep.png"
    outside.write_bytes(b"x")
    study = tmp_path / "study"
    _run(study, 1)
    mark = json.loads((study / STUDY_MARK).read_text())
    mark["report"] += ["../keep.png", str(outside), "items"]
    (study / STUDY_MARK).write_text(json.dumps(mark))
    (study / "items").mkdir(exist_ok=True)
    _run(study, 2)
    assert outside.read_bytes() == b"x" and (study / "items").is_dir()


def _thresholds(out, thresholds: str) -> list[str]:
    return ["study", "thresholds", "builtin:sphere", "--size", "16", "--thresholds",
            thresholds, "--quiet", "--out", str(out)]


def test_the_command_line_stopped_while_drawing_keeps_the_old_report(tmp_path, monkeypatch,
                                                                      capsys):
    out = tmp_path / "study"
    assert main(_thresholds(out, "0.1,0.2")) == 0
    before = _files(out)
    assert {"results.json", "results.md", "thresholds.png", "view.png",
            "report.html"} <= set(before)

    def stopped(report):
        raise KeyboardInterrupt

    monkeypatch.setattr(threshold_study, "_figure", stopped)
    assert main(_thresholds(out, "0.3")) == 130
    assert "interrupted" in capsys.readouterr().err
    assert _files(out) == before  # results.json was already the new run's
    monkeypatch.undo()
    assert main(_thresholds(out, "0.3")) == 0
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert [r["threshold"] for r in rows] == [0.3]
    assert ">0.3<" in (out / "report.html").read_text().replace(" ", "")
