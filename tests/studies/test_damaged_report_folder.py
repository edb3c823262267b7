"""``voxfield report`` on a damaged study folder: one ``voxfield: error:`` line saying what
is wrong and exit status 2, never a traceback; odd but harmless values still make a page."""

from __future__ import annotations

import json

import pytest

from cli_output import one_error_line
from voxfield.cli import main
from voxfield.errors import VoxfieldError
from voxfield.studies.html_report import write_html_report


def _folder(tmp_path, results, markdown: bytes | None = b"# A study\n\n| a |\n|---|\n| 1 |\n"):
    folder = tmp_path / "study"
    folder.mkdir()
    text = results if isinstance(results, str) else json.dumps(results)
    (folder / "results.json").write_text(text, encoding="utf-8")
    if markdown is not None:
        (folder / "results.md").write_bytes(markdown)
    return folder


def _report_error(folder, capsys) -> str:
    assert main(["report", str(folder), "--quiet"]) == 2
    return one_error_line(capsys)


def test_a_results_md_that_is_not_utf8_is_one_line(tmp_path, capsys):
    folder = _folder(tmp_path, {"study": "compare"}, markdown=bytes(range(128, 256)) * 3)
    line = _report_error(folder, capsys)
    assert "results.md" in line and "utf-8" in line
    assert not (folder / "report.html").exists()
    (folder / "results.md").unlink()  # none at all, and no figure: nothing to show
    with pytest.raises(VoxfieldError, match="nothing to report"):
        write_html_report(folder)


@pytest.mark.parametrize("depth", [2_000, 100_000])
def test_deeply_nested_results_are_one_line(tmp_path, capsys, depth):
    folder = _folder(tmp_path, '{"rows": ' + "[" * depth + "]" * depth + "}")
    line = _report_error(folder, capsys)
    assert "results.json" in line and "nested too deeply" in line


def test_truncated_deeply_nested_results_are_one_line(tmp_path, capsys):
    folder = _folder(tmp_path, '{"rows": ' + "[" * 100_000)
    assert "results.json" in _report_error(folder, capsys)


@pytest.mark.parametrize("comparisons, says", [
    ("x", '"comparisons" is a string, not a list'),
    ({"name": "a"}, '"comparisons" is an object, not a list'),
    (3, '"comparisons" is a number, not a list'),
    (["x"], "a comparison entry is a string, not an object"),
    ([[1, 2]], "a comparison entry is a list, not an object"),
    ([{"name": "a", "image": "a.png"}], "a comparison entry lacks reference"),
    ([{"image": "a.png"}], "a comparison entry lacks name, reference"),
    ([{"name": "a", "image": "a.png", "reference": "r.png", "maps": 5}],
     "the maps of comparison 'a' are a number, not an object"),
    ([{"name": "a", "image": "a.png", "reference": "r.png", "maps": "ab"}],
     "the maps of comparison 'a' are a string, not an object"),
    ([{"name": "a", "image": "a\u0000.png", "reference": "r.png"}],
     "which is not a file in the study folder"),
])
def test_malformed_comparisons_say_what_is_wrong(tmp_path, capsys, comparisons, says):
    folder = _folder(tmp_path, {"study": "compare", "comparisons": comparisons})
    line = _report_error(folder, capsys)
    assert says in line and "results.json" in line, line
    with pytest.raises(VoxfieldError, match="results.json"):
        write_html_report(folder)


def test_null_comparisons_and_odd_scene_values_still_make_a_page(tmp_path):
    folder = _folder(tmp_path, {"study": "compare", "comparisons": None,
                                "scene": {"name": "s", "voxels": "many"},
                                "camera": {"width": 4}})
    html = write_html_report(folder).read_text(encoding="utf-8")
    assert "many voxels" in html and "<table>" in html


def test_a_figure_that_is_no_png_is_left_out_with_a_note(tmp_path, capsys):
    """It was embedded as it was: a broken image on the page."""
    import numpy as np
    from PIL import Image

    folder = _folder(tmp_path, {"study": "thresholds"})
    (folder / "thresholds.png").write_text("x")
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(folder / "cut.png")
    (folder / "cut.png").write_bytes((folder / "cut.png").read_bytes()[:40])
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(folder / "good.png")
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(folder / "jpeg.png", format="JPEG")
    assert main(["report", str(folder), "--quiet"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and all("left out of the report" in line for line in err), err
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == 1 and ">good<" in html.replace(" ", "")


@pytest.mark.parametrize("markdown", [None, b"", b"  \n"])
def test_a_folder_with_nothing_to_show_is_refused(tmp_path, capsys, markdown):
    """A results.json of {} beside nothing else made a page of a title alone, exit 0."""
    folder = _folder(tmp_path, {}, markdown)
    assert "nothing to report: no comparisons in results.json, no results.md and no PNG " \
           "figures" in _report_error(folder, capsys)
    assert not (folder / "report.html").exists()


def test_a_figure_results_md_shows_but_the_folder_lost_is_a_note(tmp_path, capsys):
    """A deleted figure left a broken image in the page without a word; the rest of the
    page is still written."""
    folder = _folder(tmp_path, {"study": "thresholds"},
                     b"# A study\n\n![curve](curve.png)\n\n![gone](gone.png) ![gone](gone.png)\n")
    import numpy as np
    from PIL import Image

    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(folder / "curve.png")
    assert main(["report", str(folder), "--quiet"]) == 0
    err = capsys.readouterr().err.strip()
    assert err == (f"voxfield: note: {folder / 'results.md'} shows gone.png, missing from the "
                   "folder; the page shows a broken image there")
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == 1
