"""A study's item cache holding JSON that ``StudyFolder`` never wrote (an array, null, an
object of another shape) is stale like an empty or truncated item: recomputed, never a
traceback."""

from __future__ import annotations

import json

import numpy as np
import pytest

from voxfield.cli import main
from voxfield.render.result import RenderResult
from voxfield.studies.report import StudyFolder

NOT_ITEMS = ["[]", "null", "0", '"data"']


def _one_item(folder: StudyFolder):
    (path,) = folder.items_dir.glob("*.json")
    return path


@pytest.mark.parametrize("text", NOT_ITEMS)
def test_a_value_item_of_another_shape_is_recomputed(tmp_path, text):
    calls = []

    def compute():
        calls.append(1)
        return {"psnr": 30.0}

    first = StudyFolder(tmp_path, study="sweep").value_item("quality", {"k": 1}, compute)
    assert first == {"psnr": 30.0}
    _one_item(StudyFolder(tmp_path, study="sweep")).write_text(text + "\n")
    again = StudyFolder(tmp_path, study="sweep")
    assert again.value_item("quality", {"k": 1}, compute) == {"psnr": 30.0}
    assert len(calls) == 2 and again.computed == ["quality"] and again.reused == []
    # ... and the rewritten item is trusted next time.
    third = StudyFolder(tmp_path, study="sweep")
    assert third.value_item("quality", {"k": 1}, compute) == {"psnr": 30.0}
    assert len(calls) == 2 and third.reused == ["quality"]


def _edit_record(path, **changes) -> None:
    record = json.loads(path.read_text())
    record.update(changes)
    path.write_text(json.dumps(record))


@pytest.mark.parametrize("changes", [
    {"data": []},                      # well formed, data of the wrong type
    {"data": {"psnr": 99.0}},          # well formed, a value edited by hand
    {"digest": "0" * 32},              # a damaged digest
    {"digest": None},                  # a record from before digests
])
def test_a_record_this_folder_did_not_write_is_recomputed(tmp_path, changes):
    calls = []

    def compute():
        calls.append(1)
        return {"psnr": 30.0, "per_channel": [1.5, 2.25e-7], "nested": {"1": None}}

    first = StudyFolder(tmp_path, study="sweep").value_item("quality", {"k": 1}, compute)
    path = _one_item(StudyFolder(tmp_path, study="sweep"))
    untouched = StudyFolder(tmp_path, study="sweep")
    assert untouched.value_item("quality", {"k": 1}, compute) == first
    assert untouched.reused == ["quality"] and len(calls) == 1
    _edit_record(path, **changes)
    again = StudyFolder(tmp_path, study="sweep")
    assert again.value_item("quality", {"k": 1}, compute) == first
    assert again.computed == ["quality"] and len(calls) == 2


def _render():
    h, w = 2, 3
    return RenderResult(
        image=np.full((h, w, 3), 0.5, np.float32), depth=np.ones((h, w), np.float32),
        normal=np.zeros((h, w, 3), np.float32), ray_count=np.ones((h, w), np.int32),
        hit_count=np.ones((h, w), np.int32), steps=np.full((h, w), 7, np.int64),
        finest_lod=np.zeros((h, w), np.int8), seconds=1.0, renderer="stub")


@pytest.mark.parametrize("text", [
    "null",
    # A well-formed record whose metadata is not an object, or that lists too few arrays.
    '{"item": "reference", "data": [], "arrays": ["depth", "finest_lod", "hit_count", '
    '"image", "normal", "ray_count", "steps"]}',
    '{"item": "reference", "data": {}, "arrays": ["image"]}',
])
def test_a_render_item_of_another_shape_is_recomputed(tmp_path, text):
    calls = []

    def render():
        calls.append(1)
        return _render()

    for method in ("render_item", "render_batch"):
        out = tmp_path / method
        StudyFolder(out, study="sweep").render_item("reference", {"k": 1}, render)
        _one_item(StudyFolder(out, study="sweep")).write_text(text)
        folder = StudyFolder(out, study="sweep")
        if method == "render_item":
            result = folder.render_item("reference", {"k": 1}, render)
        else:
            (result,) = folder.render_batch([("reference", {"k": 1}, lambda _: render())])
        assert folder.computed == ["reference"] and folder.reused == []
        assert result.renderer == "stub" and int(result.steps.sum()) == 7 * 6
    assert len(calls) == 4


@pytest.mark.parametrize("item, text", [("quality_adaptive", "[]"), ("reference", "null")])
def test_compare_resumes_past_an_item_of_another_shape(tmp_path, capsys, item, text):
    command = ["compare", "builtin:pillars", "--size", "8", "--quiet", "--out", str(tmp_path)]
    assert main(command) == 0
    (path,) = (tmp_path / "items").glob(f"{item}-*.json")
    path.write_text(text + "\n")
    assert main(command) == 0
    assert capsys.readouterr().err == ""
    assert isinstance(json.loads(path.read_text()), dict)  # rewritten
