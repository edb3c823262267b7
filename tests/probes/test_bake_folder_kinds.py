"""A bake writes into a new or empty folder, or a probe set, never among other files: a
user's own ``probe_00000.npz`` was overwritten (and deleted by ``--fresh``), and a study's
folder took a probe set beside its results. A study likewise refuses a probe set's folder."""

from __future__ import annotations

from voxfield import cli
from voxfield.probes.probe_folder import open_probe_set

BAKE = ["--grid", "2x1x1", "--resolution", "8", "--renderer", "lod", "--quiet"]


def bake(folder, *extra) -> int:
    return cli.main(["bake", "builtin:sphere", *BAKE, "--out", str(folder), *extra])


def test_a_folder_of_other_files_is_refused_and_left_as_it_was(tmp_path, capsys):
    folder = tmp_path / "mine"
    folder.mkdir()
    own = {"probe_00000.npz": b"the user's own probe", "notes.txt": b"keep me"}
    for name, data in own.items():
        (folder / name).write_bytes(data)
    for extra in ([], ["--fresh"]):
        assert bake(folder, *extra) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert "no probes.json" in err and "not a probe set" in err and "--out" in err
        assert "notes.txt" in err and "probe_00000.npz" in err
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == own


def test_new_empty_and_probe_set_folders_are_baked(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / ".probes.abc.tmp.json").write_text("")  # what a write stopped part-way leaves
    for folder in (tmp_path / "new", empty):
        assert bake(folder) == 0, capsys.readouterr().err
        assert open_probe_set(folder).count == 2
    # A probe set's own folder is resumed, and --fresh starts it over.
    assert bake(empty) == 0 and bake(empty, "--fresh") == 0
    assert open_probe_set(empty).count == 2


def test_a_bake_and_a_study_keep_out_of_each_other_s_folders(tmp_path, capsys):
    study = tmp_path / "study"
    assert cli.main(["compare", "builtin:sphere", "--size", "16", "--out", str(study),
                     "--quiet"]) == 0
    before = sorted(p.name for p in study.iterdir())
    assert bake(study) == 2
    err = capsys.readouterr().err
    assert "more but no probes.json" in err and "not a probe set" in err
    assert sorted(p.name for p in study.iterdir()) == before

    probes = tmp_path / "probes"
    assert bake(probes) == 0
    before = sorted(p.name for p in probes.iterdir())
    assert cli.main(["compare", "builtin:sphere", "--size", "16", "--out", str(probes),
                     "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "holds a probe set" in err and "--out" in err
    assert sorted(p.name for p in probes.iterdir()) == before
