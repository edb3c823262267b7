"""A folder named like a study's report file or figure (``report.html/``) was met only when
the report was published: every render ran, then the study failed. ``StudyFolder`` refuses
it as the folder is opened, for every study, with one line naming the path."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import voxfield.cli.cmd_study
import voxfield.studies
from cli_output import one_error_line
from voxfield.cli.main import main
from voxfield.studies.report import REPORT_FILES, STAGING, STUDY_FIGURES, StudyFolder

STUDIES = sorted({*STUDY_FIGURES, "study normalisation", "study probe-resolution"})


def _never(*args, **kwargs):
    raise AssertionError("the study's work began in a folder it cannot publish into")


@pytest.mark.parametrize("study", STUDIES)
def test_every_output_name_taken_by_a_folder_is_refused_as_the_folder_opens(tmp_path, study):
    for name in (*REPORT_FILES, *STUDY_FIGURES.get(study, ())):
        out = tmp_path / name.replace(".", "_")
        (out / name).mkdir(parents=True)
        with pytest.raises(IsADirectoryError) as caught:
            StudyFolder(out, study=study)
        assert caught.value.filename == str(out / name)
    # A file where the item cache or the staging folder goes.
    for name in ("items", STAGING):
        out = tmp_path / f"file{name}"
        out.mkdir()
        (out / name).write_text("not a folder")
        with pytest.raises(NotADirectoryError) as caught:
            StudyFolder(out, study=study)
        assert caught.value.filename == str(out / name)


def test_a_folder_named_like_another_study_s_figure_is_not_in_the_way(tmp_path):
    (tmp_path / "sweep.png").mkdir()
    StudyFolder(tmp_path, study="study thresholds")  # writes no sweep.png
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.png"]


@pytest.mark.parametrize("study, in_the_way, first_work", [
    ("thresholds", "report.html", "voxfield.studies.threshold_study.render_reference"),
    # The lighting study bakes a scene without lit channels before the study opens its
    # folder: the folder was checked only after the bake.
    ("lighting", "contact_sheet.png", "voxfield.cli.cmd_study.bake_sun_lighting"),
])
def test_the_command_line_refuses_it_before_any_work(study, in_the_way, first_work, tmp_path,
                                                     capsys, monkeypatch):
    out = tmp_path / "s"
    (out / in_the_way).mkdir(parents=True)
    monkeypatch.setattr(first_work, _never)
    assert main(["study", study, "builtin:pillars", "--size", "16", "--quiet",
                 "--out", str(out)]) == 2
    assert f"cannot use {out / in_the_way}: " in one_error_line(capsys)
    if study == "thresholds":
        assert sorted(p.name for p in out.iterdir()) == ["report.html"]


def _unconditional_calls(node):
    """The calls in ``node``'s body, leaving out those under an ``if``."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.If | ast.IfExp | ast.FunctionDef | ast.Lambda):
            continue
        if isinstance(child, ast.Call):
            yield child
        yield from _unconditional_calls(child)


def _written_names(module: Path) -> dict[str, set[str]]:
    """Per study a module opens a folder for, the fixed names the opening function writes."""
    found: dict[str, set[str]] = {}
    for func in ast.walk(ast.parse(module.read_text())):
        if not isinstance(func, ast.FunctionDef):
            continue
        studies = [kw.value.value for call in ast.walk(func) if isinstance(call, ast.Call)
                   and getattr(call.func, "id", None) == "StudyFolder"
                   for kw in call.keywords
                   if kw.arg == "study" and isinstance(kw.value, ast.Constant)]
        names = {call.args[0].value for call in _unconditional_calls(func)
                 if getattr(call.func, "attr", None) in (
                     "write_figure", "write_png", "write_json", "write_text")
                 and call.args and isinstance(call.args[0], ast.Constant)}
        for study in studies:
            found.setdefault(study, set()).update(names)
    return found


def test_the_table_of_figures_names_what_each_study_writes():
    """The checked names come from a table: it must follow the studies' own writers."""
    modules = [*Path(voxfield.studies.__file__).parent.glob("*.py"),
               Path(voxfield.cli.cmd_study.__file__)]
    sources: dict[str, str] = {}  # per study, the modules that open its folder
    for module in modules:
        for study, names in _written_names(module).items():
            assert names - set(REPORT_FILES) <= set(STUDY_FIGURES.get(study, ())), study
            sources[study] = sources.get(study, "") + module.read_text()
    assert set(sources) == set(STUDIES)
    for study, figures in STUDY_FIGURES.items():
        for figure in figures:  # a figure renamed in its study, not in the table
            assert f'"{figure}"' in sources[study], (study, figure)
