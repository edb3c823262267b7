"""``voxfield bake``, ``voxfield probes show`` and ``export-cubes``: options, a tiny end-to-end
bake, the PNG, cube faces that agree with the octree's own ray cast."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from voxfield import cli
from voxfield.errors import VoxfieldError
from voxfield.probes.probe_folder import open_probe_set
from voxfield.probes.probe_set import BakeOptions


@pytest.fixture
def run():
    return cli.main


def test_bake_options_parse(run):
    parser = cli.build_parser()
    args = parser.parse_args(["bake", "builtin:cornell", "--grid", "4x2x4", "--resolution",
                              "16", "--renderer", "lod", "--lod", "cone", "--scheduler",
                              "tcp://10.0.0.1:8786", "--out", "x", "--fresh", "--relocate"])
    assert (args.grid, args.resolution, args.renderer, args.lod) == ("4x2x4", 16, "lod", None)
    assert args.scheduler == "tcp://10.0.0.1:8786" and args.fresh and args.relocate
    defaults = parser.parse_args(["bake", "builtin:cornell", "--grid", "2x2x2"])
    assert defaults.scheduler == "threads" and defaults.out is None
    args = parser.parse_args(["probes", "show", "folder", "--out", "a.png", "--no-scene"])
    assert (args.folder, args.out, args.no_scene) == ("folder", "a.png", True)


DEFAULTS = BakeOptions()


@pytest.mark.parametrize(("chosen", "given", "note"), [
    (["--renderer", "lod"], ["--samples", str(DEFAULTS.samples)],
     "the lod radiance renderer takes no --samples (for reference); ignored"),
    (["--renderer", "reference"],
     ["--threshold", str(DEFAULTS.threshold), "--decay", str(DEFAULTS.decay)],
     "the reference radiance renderer takes no --threshold (for error-aware), --decay (for "
     "error-aware); ignored"),
    (["--renderer", "reference"], ["--lod", "cone", "--cone-scale", str(DEFAULTS.cone_scale)],
     "the reference radiance renderer takes no --lod (for lod/adaptive/error-aware), "
     "--cone-scale (for lod/error-aware); ignored"),
    (["--renderer", "lod", "--lod", "2"], ["--cone-scale", str(DEFAULTS.cone_scale)],
     "the lod radiance renderer reads --cone-scale only with --lod cone; ignored"),
    (["--lod", "0"], ["--threshold", str(DEFAULTS.threshold)],
     "the error-aware radiance renderer reads --threshold only with a --lod other than 0; "
     "ignored"),
])
def test_a_radiance_option_the_renderer_ignores_is_noted_at_its_default_too(chosen, given,
                                                                            note):
    """Each option ``given`` holds its default value: the notes compared values with the
    defaults, so ``--renderer lod --samples 4`` was ignored without a word while
    ``--samples 5`` was noted. Left out, nothing is noted and the options are the same."""
    from voxfield.cli.cmd_probes import _bake_options

    parser = cli.build_parser()
    base = ["bake", "builtin:cornell", "--grid", "2x1x1", *chosen]
    with pytest.warns(UserWarning) as notes:
        options = _bake_options(parser.parse_args([*base, *given]))
    assert [str(w.message) for w in notes] == [note]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _bake_options(parser.parse_args(base)) == options


def test_bad_arguments_exit_2(run, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        run(["bake", "builtin:cornell"])  # --grid is required
    assert exc.value.code == 2
    code = run(["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "7",
                "--out", str(tmp_path / "p"), "--quiet"])
    assert code == 2 and "resolution must be an even integer" in capsys.readouterr().err
    code = run(["probes", "show", str(tmp_path / "nothing"), "--quiet"])
    assert code == 2 and "no such probe-set folder" in capsys.readouterr().err


def test_a_refused_bake_says_one_line(run, tmp_path, capsys):
    """A probe standing in the Cornell box's wall draws a note; a bake refused for its
    --out, --lod or --channel said that note first and the refusal second (the scene was
    built and the grid checked for a bake that never ran); now the refusal alone. (Each
    run's grid is its own: a note repeated word for word is shown once a process.)"""
    def in_wall(spacing):
        return ["--grid", f"origin=0.5,16.5,16.5;spacing={spacing};counts=2,1,1",
                "--resolution", "8", "--quiet"]

    assert run(["bake", "builtin:cornell", *in_wall(15), "--out", str(tmp_path / "ok")]) == 0
    assert "stand inside solid voxels" in capsys.readouterr().err
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    refused = ["--out", str(tmp_path / "refused")]
    for spacing, extra, error in (
            (14, ["--out", str(a_file)], "is not a folder"),
            (13, [*refused, "--renderer", "lod", "--lod", "99"], "deeper than this octree"),
            (12, [*refused, "--channel", "noon"], "no channel 'noon'")):
        assert run(["bake", "builtin:cornell", *in_wall(spacing), *extra]) == 2
        lines = capsys.readouterr().err.splitlines()
        assert len(lines) == 1 and error in lines[0], lines
    assert not (tmp_path / "refused").exists()


def test_bake_and_show_end_to_end(run, tmp_path, capsys):
    out = tmp_path / "cornell"
    argv = ["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "8",
            "--renderer", "lod", "--lod", "0", "--scheduler", "serial", "--out", str(out)]
    assert run(argv) == 0
    text = capsys.readouterr().out
    assert "2 of 2 probes, 8² texels, lod" in text and "per texel: 1.000 rays" in text
    probes = open_probe_set(out)
    assert probes.count == 2 and np.isfinite(probes.distance).any()

    assert run(argv) == 0  # a re-run resumes: nothing left to bake
    assert "this run baked 0 and reused 2" in capsys.readouterr().out

    png = tmp_path / "show.png"
    study_page = tmp_path / "report.html"  # a study's page in the same folder stays its own
    study_page.write_text("a study's report")
    assert run(["probes", "show", str(out), "--out", str(png), "--size", "64"]) == 0
    with Image.open(png) as image:
        assert image.format == "PNG" and image.size[0] > 500
    assert "2 of 2 probes" in (tmp_path / "show.html").read_text(encoding="utf-8")
    assert study_page.read_text() == "a study's report"
    assert run(["probes", "show", str(out), "--no-scene", "--quiet"]) == 0
    assert (out / "show.png").is_file() and (out / "show.html").is_file()
    assert capsys.readouterr().err == ""
    # --size sizes the scene's render alone: with --no-scene it changed nothing, unsaid.
    assert run(["probes", "show", str(out), "--no-scene", "--size", "64", "--quiet"]) == 0
    assert capsys.readouterr().err.splitlines() == [
        "voxfield: note: probes show with --no-scene takes no --size (for the scene's overview "
        "render); ignored"]


def test_export_cubes_traces_faces_from_the_baked_scene(run, tmp_path):
    from voxfield.render.image_io import load_exr
    from voxfield.render.ray_query import trace
    from voxfield.svo.open import open_octree

    out = tmp_path / "probes"
    assert run(["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "8",
                "--renderer", "lod", "--lod", "0", "--scheduler", "serial", "--out", str(out),
                "--quiet"]) == 0
    assert run(["probes", "export-cubes", str(out), "--size", "6", "--quiet"]) == 0
    faces = sorted((out / "cubes").glob("*.exr"))
    assert len(faces) == 12
    probes = open_probe_set(out)
    octree = open_octree("builtin:cornell")
    for i in range(2):
        face = load_exr(out / "cubes" / f"probe_{i:05d}_posx.exr")
        assert face["RGB"].shape == (6, 6, 3) and face["Z"].shape == (6, 6)
        # The four pixels around the +x face's centre see nearly the +x axis distance.
        expected = trace(octree, probes.positions[i][None], [[1.0, 0.0, 0.0]]).t[0]
        assert np.min(np.abs(face["Z"][2:4, 2:4] - expected)) < 1.0


def test_export_cubes_refuses_another_scene_or_no_probe_in_one_line(run, tmp_path, capsys,
                                                                   monkeypatch):
    """Another scene printed a note that it was "drawing it anyway" before the error, and a
    set with every probe disabled "wrote 0 faces of 0 probes"."""
    from cli_output import one_error_line
    from voxfield import memory
    from voxfield.cli import cmd_probes

    out = tmp_path / "probes"
    assert run(["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "8",
                "--renderer", "lod", "--lod", "0", "--scheduler", "serial", "--out", str(out),
                "--quiet"]) == 0
    assert run(["probes", "export-cubes", str(out), "--scene", "builtin:sphere"]) == 2
    assert "not the scene these probes were baked from" in one_error_line(capsys)
    assert run(["probes", "export-cubes", str(out), "--scene", "builtin:nope"]) == 2
    assert one_error_line(capsys).startswith("voxfield: error: --scene builtin:nope: ")
    # probes show draws without a recorded scene that has gone, but a --scene the user
    # named and mistyped was a note and a lesser picture, exit 0
    picture = tmp_path / "show.png"
    assert run(["probes", "show", str(out), "--scene", "nope.vox", "--size", "16",
                "--out", str(picture)]) == 2
    assert one_error_line(capsys).startswith("voxfield: error: --scene nope.vox: ")
    assert not picture.exists()
    # A side past every camera's limit is refused as --size, not as an "image width".
    with pytest.raises(SystemExit):
        run(["probes", "show", str(out), "--size", "100000", "--out", str(picture)])
    assert "argument --size: " in capsys.readouterr().err

    # A face side past every camera's limit is refused by the parser too, and one the
    # machine cannot hold (six faces and a render: 4.1 GiB at 4096² against the 2 GiB a
    # machine is said to have here) before the scene opens or a folder is made; 16384²
    # faces began to render and were killed for memory.
    with pytest.raises(SystemExit):
        run(["probes", "export-cubes", str(out), "--size", "100000"])
    assert "argument --size: " in capsys.readouterr().err
    monkeypatch.setattr(memory, "physical_memory", lambda: 2 * 2**30)
    monkeypatch.setattr(cmd_probes, "_reopen_scene", None)  # must not be reached
    assert run(["probes", "export-cubes", str(out), "--size", "4096", "--quiet"]) == 2
    assert one_error_line(capsys) == (
        "voxfield: error: --size 4096: exporting a probe's six 4096×4096 cube faces needs "
        "about 4.1 GiB, over 80% of this machine's 2.0 GiB; give a smaller --size")
    assert not (out / "cubes").exists()
    monkeypatch.undo()

    def all_disabled(folder):
        probe_set = open_probe_set(folder)
        probe_set.enabled[:] = False
        return probe_set

    monkeypatch.setattr(cmd_probes, "open_probe_set", all_disabled)
    assert run(["probes", "export-cubes", str(out), "--quiet"]) == 2
    assert "every probe is disabled" in one_error_line(capsys)
    assert not (out / "cubes").exists()


def test_probes_show_takes_a_scene_or_none_not_both(run, capsys):
    with pytest.raises(SystemExit) as exc:
        run(["probes", "show", "folder", "--no-scene", "--scene", "builtin:sphere"])
    assert exc.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_bake_the_machine_cannot_finish_is_refused_before_any_probe(tmp_path, capsys,
                                                                      monkeypatch):
    """A finished bake assembles its whole set and writes the atlases from it (about 48
    bytes a texel at its peak): a 64×64×64 grid of 64² maps baked for over an hour and then
    needed some 48 GiB. On a machine said to hold 2 GiB, 27,000 probes of 64² (about 4.9
    GiB) are refused before the grid's notes, any probe or any folder; 8 probes bake."""
    from cli_output import one_error_line
    from voxfield import memory
    from voxfield.probes import folder_bake
    from voxfield.probes.bake import BakeOptions
    from voxfield.probes.grid import ProbeGrid
    from voxfield.svo.open import open_octree

    monkeypatch.setattr(memory, "physical_memory", lambda: 2 * 2**30)
    out = tmp_path / "probes"
    assert cli.main(["bake", "builtin:sphere", "--grid", "30x30x30", "--resolution", "64",
                     "--out", str(out)]) == 2
    assert one_error_line(capsys) == (
        "voxfield: error: 27,000 probes of 64² texels: assembling the finished set and its "
        "atlases needs about 4.9 GiB, over 80% of this machine's 2.0 GiB; bake fewer probes "
        "or a lower resolution")
    assert not out.exists()
    # The library's bake checks alike.
    octree = open_octree("builtin:sphere")
    grid = ProbeGrid((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), (30, 30, 30))
    with pytest.raises(VoxfieldError, match="27,000 probes of 64² texels"):
        folder_bake.bake_to_folder(octree, grid, BakeOptions(resolution=64), out)
    assert not out.exists()
    assert cli.main(["bake", "builtin:sphere", "--grid", "2x2x2", "--resolution", "64",
                     "--renderer", "lod", "--quiet", "--out", str(out)]) == 0


def test_a_bake_whose_probes_all_stand_in_the_ground_is_refused(tmp_path, capsys):
    """A flat DEM: the counted grid fits the box of a thin slab, every probe in the ground.
    The bake wrote 18 probes of zero distance and exited 0; with --relocate it wrote none
    and still exited 0."""
    dem = tmp_path / "flat.npy"
    np.save(dem, np.zeros((32, 32), np.float32))
    for relocating in ([], ["--relocate"]):
        out = tmp_path / f"probes{len(relocating)}"
        assert cli.main(["bake", str(dem), "--footprint", "32", "--grid", "3x2x3", "--resolution",
                     "8", "--quiet", *relocating, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("voxfield: error: 3x2x3: ")
        assert "surface:NXxNZ@H" in err[0]
        assert not out.exists()
    assert cli.main(["bake", str(dem), "--footprint", "32", "--grid", "surface:2x2@4",
                 "--resolution", "8", "--quiet", "--out", str(tmp_path / "above")]) == 0
