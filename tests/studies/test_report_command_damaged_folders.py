"""``voxfield report`` on a study folder that lost files or holds values of the wrong kind.

It wrote a page that lacked a deleted figure or cost map without a word, and titled a page
with Python's repr of a scene of ``[1, 2]``. Now a value of the wrong kind is one
``voxfield: error:`` line (status 2); a file the page should show and cannot is a note
naming it, and a card on the page that says it is missing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from cli_output import one_error_line
from voxfield.cli import main

TABLES = "# A study\n\n| a |\n|---|\n| 1 |\n"


def _png(path, value: int = 90) -> None:
    Image.fromarray(np.full((4, 4, 3), value, np.uint8)).save(path)


def _folder(tmp_path, results, *, markdown: str | None = TABLES, mark=None, pngs=()):
    """A study folder made by hand: results.json (an object, or text as it is), results.md,
    the study mark ``study.json`` and the PNGs named."""
    folder = tmp_path / "study"
    folder.mkdir()
    text = results if isinstance(results, str) else json.dumps(results)
    (folder / "results.json").write_text(text, encoding="utf-8")
    if markdown is not None:
        (folder / "results.md").write_text(markdown, encoding="utf-8")
    if mark is not None:
        (folder / "study.json").write_text(json.dumps(mark), encoding="utf-8")
    for name in pngs:
        _png(folder / name)
    return folder


def _report(folder, capsys) -> tuple[str, list[str]]:
    """The page written, and the notes printed on the way."""
    assert main(["report", str(folder), "--quiet"]) == 0
    notes = capsys.readouterr().err.strip().splitlines()
    assert all(line.startswith("voxfield: note: ") for line in notes), notes
    return (folder / "report.html").read_text(encoding="utf-8"), notes


def _refused(folder, capsys) -> str:
    assert main(["report", str(folder), "--quiet"]) == 2
    assert not (folder / "report.html").exists()
    return one_error_line(capsys)


def _comparison(**changes) -> dict:
    entry = {"name": "fast", "image": "fast.png", "reference": "reference.png",
             "reference_name": "reference", "summary": "2 rays/px",
             "maps": {"rays cast per pixel": "fast_rays.png"}}
    return {**entry, **changes}


def test_a_whole_folder_makes_no_note(tmp_path, capsys):
    """What the mark and the study expect is all there: nothing to say."""
    folder = _folder(tmp_path, {"scene": "s"}, pngs=("sweep.png", "view.png"),
                     mark={"study": "sweep", "report": ["report.html", "results.json",
                                                         "results.md", "sweep.png", "view.png"]})
    html, notes = _report(folder, capsys)
    assert notes == [] and "missing" not in html
    assert html.count("data:image/png;base64,") == 2


def test_a_figure_the_last_report_showed_but_the_folder_lost_is_a_note_and_a_card(tmp_path,
                                                                                  capsys):
    folder = _folder(tmp_path, {"scene": "s"}, pngs=("view.png",),
                     mark={"study": "sweep", "report": ["report.html", "results.json",
                                                         "results.md", "sweep.png", "view.png",
                                                         "extra.png"]})
    html, notes = _report(folder, capsys)
    assert notes == [f"voxfield: note: {folder}: extra.png, sweep.png are missing from the "
                     "folder; the page marks each as missing"]
    assert "extra (missing: extra.png is not in the folder)" in html
    assert "sweep (missing: sweep.png is not in the folder)" in html
    assert html.count("data:image/svg+xml,") == 2 and "<table>" in html


def test_the_figures_a_study_always_draws_are_expected_from_its_mark(tmp_path, capsys):
    """A mark without its report list (a stopped first run) still names the study."""
    folder = _folder(tmp_path, {"scene": "s"}, mark={"study": "study thresholds"})
    html, notes = _report(folder, capsys)
    assert len(notes) == 1 and "view.png, thresholds.png are missing" in notes[0]
    assert "missing: thresholds.png" in html and "missing: view.png" in html


def test_nothing_but_missing_figures_is_refused_naming_them(tmp_path, capsys):
    folder = _folder(tmp_path, {}, markdown=None, mark={"study": "sweep"})
    line = _refused(folder, capsys)
    assert "nothing to report" in line and "(view.png, sweep.png missing)" in line


@pytest.mark.parametrize("mark", ["junk{", json.dumps(["sweep"]),
                                  json.dumps({"study": 3, "report": ["../outside.png", 4]})])
def test_an_odd_mark_expects_nothing_outside_the_folder(tmp_path, capsys, mark):
    folder = _folder(tmp_path, {"scene": "s"}, pngs=("view.png",))
    (folder / "study.json").write_text(mark, encoding="utf-8")
    _png(tmp_path / "outside.png")
    html, notes = _report(folder, capsys)
    assert notes == [] and "missing" not in html


def test_a_cost_map_gone_is_a_note_and_a_card(tmp_path, capsys):
    folder = _folder(tmp_path, {"study": "compare", "comparisons": [_comparison()]},
                     pngs=("fast.png", "reference.png"))
    html, notes = _report(folder, capsys)
    assert notes == [f"voxfield: note: {folder}: cost map fast_rays.png is missing from the "
                     "folder; the page marks it as missing"]
    assert "rays cast per pixel (missing: fast_rays.png is not in the folder)" in html


def test_an_image_results_json_lists_but_the_folder_lost_is_a_note(tmp_path, capsys):
    folder = _folder(tmp_path, {"study": "compare", "comparisons": [_comparison(maps=None)],
                                "images": {"fast": "fast.png", "steps": "fast_steps.png"}},
                     pngs=("fast.png", "reference.png"))
    html, notes = _report(folder, capsys)
    assert len(notes) == 1 and "fast_steps.png is missing from the folder" in notes[0]
    assert "missing: fast_steps.png" in html


def test_a_comparison_without_its_image_is_refused_naming_it(tmp_path, capsys):
    folder = _folder(tmp_path, {"comparisons": [_comparison()]}, pngs=("reference.png",))
    line = _refused(folder, capsys)
    assert "fast.png: the image of comparison 'fast' in results.json is missing" in line


def test_a_missing_results_md_is_a_note(tmp_path, capsys):
    folder = _folder(tmp_path, {"scene": "s"}, markdown=None, pngs=("view.png",))
    _, notes = _report(folder, capsys)
    assert notes == [f"voxfield: note: {folder}: no results.md; the page has no tables"]


@pytest.mark.parametrize("name", ["results.json", "results.md"])
def test_a_results_file_that_is_a_folder_is_refused(tmp_path, capsys, name):
    folder = _folder(tmp_path, {"scene": "s"}, pngs=("view.png",))
    (folder / name).unlink()
    (folder / name).mkdir()
    line = _refused(folder, capsys)
    assert f"{folder / name}: a folder, not" in line


@pytest.mark.parametrize("results, says", [
    ({"study": {"a": 1}}, '"study" is an object, not a string'),
    ({"scene": [1, 2]}, '"scene" is a list, not a name or an object'),
    ('{"scene": NaN}', '"scene" is a number, not a name or an object'),
    ({"scene": {"name": 5}}, 'the scene\'s "name" is a number, not a string'),
    ({"scene": {"name": "s", "voxels": [3]}}, 'the scene\'s "voxels" is a list'),
    ({"scene": {"name": "s", "voxels": 2.5}}, 'the scene\'s "voxels" is a number, not a whole'),
    ({"camera": {"width": [1]}}, 'the camera\'s "width" is a list, not a number of pixels'),
    ({"camera": {"width": 8, "height": 0}}, 'the camera\'s "height" is a number, not a number'),
    ({"camera": {"width": 8, "label": 7}}, 'the camera\'s "label" is a number, not a string'),
    ({"images": ["a.png"]}, '"images" is a list, not an object of file names'),
    ({"images": {"a": 5}}, "image 'a' is a number, not a file name"),
    ({"comparisons": [_comparison(name={"x": 1})]}, 'a comparison\'s "name" is an object'),
    ({"comparisons": [_comparison(image=5)]},
     "the image of comparison 'fast' is a number, not a file name"),
    ({"comparisons": [_comparison(reference=None)]},
     "the reference of comparison 'fast' is null, not a file name"),
    ({"comparisons": [_comparison(reference_name=3)]},
     "comparison 'fast''s \"reference_name\" is a number, not a string"),
    ({"comparisons": [_comparison(summary=[1])]},
     "comparison 'fast''s \"summary\" is a list, not a string"),
    ({"comparisons": [_comparison(maps=[])]},
     "the maps of comparison 'fast' are a list, not an object"),
    ({"comparisons": [_comparison(maps={"rays": 4})]},
     "the map 'rays' of comparison 'fast' is a number, not a file name"),
])
def test_values_of_the_wrong_kind_are_one_line(tmp_path, capsys, results, says):
    folder = _folder(tmp_path, results, pngs=("fast.png", "reference.png", "fast_rays.png"))
    line = _refused(folder, capsys)
    assert f"{folder / 'results.json'}: " in line and says in line, line
