"""The command line: images written, one-line errors with exit status 2 (every command's help
and one run of each: ``test_every_command``)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from voxfield.cli import main
from voxfield.render.image_io import load_exr


def test_render_png_exr_and_counters(tmp_path, capsys):
    png = tmp_path / "a.png"
    assert main(["render", "builtin:sphere", "--size", "32", "--camera", "orbit",
                 "--out", str(png), "--counters", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    image = np.asarray(Image.open(png))
    assert image.shape == (32, 32, 3) and image.max() > 0
    summary = json.loads((tmp_path / "a_summary.json").read_text())
    assert summary["rays"] == 32 * 32 * 16
    for name in ("a_steps.png", "a_lod.png", "a_rays.png"):
        assert (tmp_path / name).exists()
    exr = tmp_path / "b.exr"
    assert main(["render", "builtin:sphere", "--size", "16", "--renderer", "lod", "--lod", "1",
                 "--out", str(exr)]) == 0
    channels = load_exr(exr)
    assert channels["RGB"].shape == (16, 16, 3) and channels["Z"].shape == (16, 16)
    assert "Mrays/s" in capsys.readouterr().out


@pytest.mark.parametrize("renderer", ["error-aware", "adaptive"])
def test_adaptive_renderers_from_the_command_line(renderer, tmp_path):
    out = tmp_path / f"{renderer}.png"
    assert main(["render", "builtin:pillars", "--renderer", renderer, "--size", "24",
                 "--camera", "top", "--counters", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((tmp_path / f"{renderer}_summary.json").read_text())
    assert summary["renderer"] == renderer and summary["covered_pixels"] > 0


def test_calibrate_writes_its_trail(tmp_path, capsys):
    out = tmp_path / "cal.json"
    assert main(["calibrate", "builtin:pillars", "--target-rays", "2000", "--size", "24",
                 "--iterations", "4", "--out", str(out)]) == 0
    data = json.loads(out.read_text(), parse_constant=_not_json)
    assert data["rays"] <= 2000 and len(data["trail"]) >= 4
    assert "threshold" in capsys.readouterr().out
    # A ray budget renders no reference: no PSNR is written, where a null one would read as
    # an image equal to the reference (what null means in every study's results).
    assert "psnr" not in data and not any("psnr" in entry for entry in data["trail"])


@pytest.mark.parametrize(("psnr", "shown"), [(math.inf, ", PSNR ∞ dB"), (31.234, ", PSNR 31.23 dB"),
                                              (math.nan, "")])
def test_calibrate_prints_the_psnr_it_reached(monkeypatch, capsys, psnr, shown):
    """An image equal to the reference meets every PSNR target (its PSNR is infinite, as the
    sphere's at 32² and threshold 0.125): the summary left it out as for a ray budget (NaN,
    nothing measured)."""
    from voxfield.cli import cmd_calibrate
    from voxfield.studies.calibrate import Calibration

    monkeypatch.setattr(cmd_calibrate, "open_octree", lambda args: None)
    monkeypatch.setattr(cmd_calibrate, "check_measured_channel", lambda *a: None)
    monkeypatch.setattr(cmd_calibrate, "study_camera", lambda args, octree: None)
    monkeypatch.setattr(cmd_calibrate, "calibrate_threshold", lambda *a, **k: Calibration(
        0.125, 5712, 29464, psnr, {"psnr": 30.0}, [{}]))
    assert main(["calibrate", "builtin:sphere", "--target-psnr", "30"]) == 0
    assert capsys.readouterr().out == (
        f"threshold 0.1250 (decay 0.2): 5,712 rays, 29,464 steps{shown}; "
        "1 renders\n")


def _not_json(constant: str):
    """Python reads NaN and Infinity; JSON has neither, and other readers refuse them."""
    raise AssertionError(f"{constant} in a file that should be JSON")


def test_sweep_prints_a_cell_equal_to_the_reference(tmp_path, capsys):
    """Its PSNR is infinite (null in results.json); printing it ended in a traceback. (The
    sphere from above, where every LOD's colour is the reference's.)"""
    assert main(["sweep", "builtin:sphere", "--size", "32", "--decays", "0.1", "--thresholds",
                 "0.1", "--camera", "top", "--out", str(tmp_path / "sweep")]) == 0
    report = json.loads((tmp_path / "sweep" / "results.json").read_text())
    assert report["closest_to_adaptive"][0]["psnr"] is None
    assert "t=0.1 → " in (out := capsys.readouterr().out) and "equal to the reference" in out


def test_info_and_build_round_trip(tmp_path, capsys):
    assert main(["info", "builtin:menger", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["voxels"] == 20**3 and info["depth"] == 5
    assert info["nodes_per_level"][0] == 1 and sum(info["nodes_per_level"]) == info["nodes"]
    saved = tmp_path / "m.npz"
    assert main(["build", "builtin:menger", "--out", str(saved), "--quiet"]) == 0
    assert main(["info", str(saved), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["nodes"] == info["nodes"]


@pytest.mark.parametrize(
    "argv",
    [
        ["render", "no/such/file.vox", "--out", "x.png"],
        ["render", "builtin:nothing", "--out", "x.png"],
        ["render", "builtin:sphere", "--camera", "sideways", "--out", "x.png"],
        ["render", "builtin:sphere", "--renderer", "lod", "--lod", "40", "--out", "x.png"],
        ["render", "builtin:sphere", "--eye", "0,0,0", "--target", "0,0,0", "--out", "x.png"],
        ["render", "builtin:sphere", "--size", "8", "--out", "x.bmp"],
        ["render", "builtin:sphere", "--renderer", "error-aware", "--refinements", "9",
         "--out", "x.png"],
        ["info", "data.unknown"],
    ],
)
def test_bad_input_is_one_line_and_exit_two(argv, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if argv[1] == "data.unknown":
        (tmp_path / "data.unknown").write_text("x")
    proc = subprocess.run([sys.executable, "-m", "voxfield", *argv],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert lines[-1].startswith("voxfield: error:") and "Traceback" not in proc.stderr


def test_errors_build_small_table_then_info_and_show(tmp_path, capsys):
    table = tmp_path / "t.npz"
    assert main(["errors", "build", "--directions", "32", "--resolution", "32",
                 "--oct-resolution", "8", "--out", str(table), "--quiet"]) == 0
    assert main(["errors", "info", "--table", str(table)]) == 0
    out = capsys.readouterr().out
    assert "32 Fibonacci directions" in out and "22 of 256" in out
    png = tmp_path / "m.png"
    assert main(["errors", "show", "0x0f", "--table", str(table), "--out", str(png)]) == 0
    assert Image.open(png).size[0] > 500


def test_errors_info_describes_a_lighting_table_and_each_command_names_the_other_kind(
        tmp_path, capsys):
    """``errors info --table`` on a lighting table said it "is not an error table; make one
    with `voxfield errors build`"; it now describes it. ``errors show``, which pictures an
    error table's masks, names the kind it was given; a folder is said to be a folder."""
    lighting = tmp_path / "lighting.npz"
    assert main(["errors", "build-lighting", "--resolution", "4", "--oct-resolution", "4",
                 "--seed", "3", "--out", str(lighting), "--quiet"]) == 0
    assert main(["errors", "info", "--table", str(lighting)]) == 0
    out = capsys.readouterr().out.strip()
    # 6,050 configurations: each mask's non-empty bright subsets but the whole mask
    # (sum over masks of 2^popcount - 2, masks of one child having none)
    assert out == ("lighting error table: 6,050 bright-flag configurations in 224 symmetry "
                   "classes, octahedral maps 4², 4² rays per texel, seed 3")
    assert main(["errors", "info", "--table", str(lighting), "--report"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "is a lighting error table" in err
    assert main(["errors", "show", "7", "--table", str(lighting),
                 "--out", str(tmp_path / "m.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("is a lighting error table, not an error table")
    assert not (tmp_path / "m.png").exists()
    folder = tmp_path / "tables.npz"
    folder.mkdir()
    for command in (["errors", "info"], ["errors", "show", "7"]):
        assert main([*command, "--table", str(folder)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.endswith("is a folder, not an error table file"), err


def test_errors_commands_reject_bad_input(tmp_path, capsys):
    assert main(["errors", "info", "--table", str(tmp_path / "none.npz")]) == 2
    assert "voxfield errors build" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["errors", "show", "256"])
    assert exc.value.code == 2


def test_corrupt_octree_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    np.savez(bad, header=np.frombuffer(b"{}", np.uint8), child_mask=np.zeros(3, np.uint8))
    assert main(["info", str(bad)]) == 2
    assert "octree" in capsys.readouterr().err


def test_png_is_shaded_by_default_and_metrics_images_are_not(tmp_path):
    """People look at PNGs, so they get the key light; ``--albedo`` gives the flat channel,
    and EXR (linear, what the metrics read) stays unshaded unless ``--shade`` asks."""
    from voxfield.render.camera import orbit_camera
    from voxfield.render.primary import render_reference
    from voxfield.scene.voxel_scene import linear_to_srgb
    from voxfield.svo.open import open_octree

    common = ["render", "builtin:sphere", "--size", "24", "--camera", "orbit", "--quiet"]
    paths = {name: tmp_path / name for name in ("shaded.png", "albedo.png", "plain.exr",
                                                "shaded.exr")}
    assert main([*common, "--out", str(paths["shaded.png"])]) == 0
    assert main([*common, "--albedo", "--out", str(paths["albedo.png"])]) == 0
    assert main([*common, "--out", str(paths["plain.exr"])]) == 0
    assert main([*common, "--shade", "--out", str(paths["shaded.exr"])]) == 0

    octree = open_octree("builtin:sphere")
    lo, hi = octree.voxel_bounds
    albedo = render_reference(octree, orbit_camera(lo, hi, size=24)).image
    flat = np.asarray(Image.open(paths["albedo.png"]), np.float64) / 255
    np.testing.assert_allclose(flat, linear_to_srgb(albedo), atol=1 / 255 + 1e-6)
    np.testing.assert_array_equal(load_exr(paths["plain.exr"])["RGB"], albedo)
    shaded = np.asarray(Image.open(paths["shaded.png"]), np.float64) / 255
    hit = albedo.sum(axis=2) > 0
    assert np.abs(shaded - flat)[hit].mean() > 0.02  # the light changes what we see
    assert (load_exr(paths["shaded.exr"])["RGB"][hit] <= albedo[hit] + 1e-6).all()
    with pytest.raises(SystemExit) as exc:  # the parser refuses both at once
        main([*common, "--shade", "--albedo", "--out", str(tmp_path / "x.png")])
    assert exc.value.code == 2


def test_python_dash_m_voxfield_is_the_command(capsys):
    """Where the environment's scripts are not on the PATH, `python -m voxfield` is how one
    runs the tool; it said "No module named voxfield.__main__"."""
    run = subprocess.run([sys.executable, "-m", "voxfield", "scenes"], capture_output=True,
                         text=True, timeout=300)
    assert main(["scenes"]) == 0
    assert run.returncode == 0 and run.stdout == capsys.readouterr().out
    assert "builtin:" in run.stdout


def test_render_looks_at_a_terrain_from_above_and_at_anything_else_from_the_side(tmp_path):
    """`render bunny.obj` showed the bunny from straight above and a Cornell box its roof:
    the default view was the EA thesis's terrain camera for every scene."""
    from PIL import Image

    dem = tmp_path / "hill.npy"
    np.save(dem, np.outer(np.hanning(24), np.hanning(24)).astype(np.float32) * 8)
    saved = {}
    for scene in ("terrain:desert", "builtin:cornell"):  # an octree keeps its scene's name
        saved[scene] = tmp_path / f"{scene.replace(':', '_')}.npz"
        assert main(["build", scene, "--footprint", "32", "--quiet", "--out",
                     str(saved[scene])]) == 0
    for scene, preset in (("builtin:pillars", "orbit"), ("builtin:cornell", "orbit"),
                          (str(dem), "top"), ("terrain:desert", "top"),
                          (str(saved["terrain:desert"]), "top"),
                          (str(saved["builtin:cornell"]), "orbit")):
        images = []
        for camera in ([], ["--camera", preset]):
            out = tmp_path / f"{len(camera)}.png"
            assert main(["render", scene, "--footprint", "32", "--size", "12", "--quiet",
                         "--renderer", "lod", "--lod", "0", *camera, "--out", str(out)]) == 0
            images.append(np.asarray(Image.open(out)))
        assert np.array_equal(*images), scene


def test_errors_build_without_out_says_it_replaces_the_packaged_table(tmp_path, capsys,
                                                                      monkeypatch):
    """A trial build without --out replaced the table every error-aware render reads
    without a word; the packaged table is stood in for by a temporary file here."""
    from voxfield.cli import cmd_errors

    shipped = tmp_path / "shipped.npz"
    monkeypatch.setattr(cmd_errors, "DEFAULT_TABLE", shipped)
    assert main(["errors", "build", "--directions", "16", "--resolution", "16",
                 "--oct-resolution", "8", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"voxfield: note: no --out: the table built replaces the one "
                          f"voxfield ships ({shipped})") and shipped.is_file()
    assert main(["errors", "build", "--directions", "16", "--resolution", "16",
                 "--oct-resolution", "8", "--quiet", "--out", str(tmp_path / "t.npz")]) == 0
    assert capsys.readouterr().err == ""


def test_errors_build_quiet_still_prints_the_report_it_was_asked_for(tmp_path, capsys):
    """``--quiet --report`` printed nothing: the fit report sat under ``not --quiet``."""
    assert main(["errors", "build", "--directions", "16", "--resolution", "16",
                 "--oct-resolution", "8", "--quiet", "--report",
                 "--out", str(tmp_path / "t.npz")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("fit against ") and "sh" in out and "oct" in out
    assert "wrote" not in out  # the quiet part stays quiet
