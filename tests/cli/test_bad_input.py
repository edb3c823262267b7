"""Edges a demanding user hits: bad output paths, closed pipes, nonsense option values and
file modes. Each ends in one ``voxfield: error:`` line and exit status 2, or is refused by
the option parser (status 2), never a traceback."""

from __future__ import annotations

import errno
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from cli_output import one_error_line
from voxfield.atomic import atomic_path, atomic_paths, check_writable
from voxfield.cli import main
from voxfield.cli.main import _note_warning
from voxfield.render import counter_maps

LIGHT = ["light", "builtin:pillars", "--times", "noon", "--sky-rays", "0", "--preview-size",
         "8", "--quiet"]


@pytest.fixture
def a_file(tmp_path):
    path = tmp_path / "afile.png"
    path.write_bytes(b"not a folder")
    return path


def test_output_under_a_file_is_one_line(a_file, capsys):
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet",
                 "--out", str(a_file / "x.png")]) == 2
    assert str(a_file) in one_error_line(capsys)
    # deeper down, the line names the file in the way, not the output
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet",
                 "--out", str(a_file / "sub" / "x.png")]) == 2
    assert one_error_line(capsys) == (f"voxfield: error: cannot use {a_file}: a part of the "
                                      "path is a file, not a folder")


def test_a_file_on_the_way_to_an_output_is_named_as_the_culprit(a_file):
    # mkdir's own "File exists" named the folder it could not make, not the file in the way
    for deep in (a_file / "x.png", a_file / "sub" / "deeper" / "x.png"):
        with pytest.raises(NotADirectoryError) as caught, atomic_path(deep):
            pass
        assert caught.value.filename == str(a_file)
        assert "is a file, not a folder" in str(caught.value)
    assert a_file.read_bytes() == b"not a folder"


@pytest.mark.parametrize("command, out, name", [
    (["render", "builtin:sphere", "--size", "8"], "cmd_render", "x.png"),
    (["build", "builtin:sphere"], "cmd_scenes", "x.npz"),
    (LIGHT, "cmd_light", "x.npz"),
    (["calibrate", "builtin:sphere", "--target-rays", "100"], "cmd_calibrate", "x.json"),
])
def test_an_unusable_output_fails_before_the_scene_loads(command, out, name, a_file, capsys,
                                                         monkeypatch):
    # A render or bake may take minutes: an output it could never write must end the
    # command before that work, not after it.
    def never(args):
        raise AssertionError("the scene was opened for an output that cannot be written")

    monkeypatch.setattr(f"voxfield.cli.{out}.open_octree", never)
    assert main([*command, "--quiet", "--out", str(a_file / name)]) == 2
    line = one_error_line(capsys)
    assert str(a_file) in line and "ending in" not in line


@pytest.mark.parametrize("command, out, wrong", [
    (["build", "builtin:sphere"], "cmd_scenes", "octree.png"),
    (["calibrate", "builtin:sphere", "--target-rays", "100"], "cmd_calibrate", "trail.png"),
    (LIGHT, "cmd_light", "lit.exr"),
    (["errors", "show", "51"], "cmd_errors", "mask.exr"),
])
def test_an_output_named_for_another_format_is_refused_first(command, out, wrong, tmp_path,
                                                             capsys, monkeypatch):
    """An octree written as ``octree.png``, a PNG as ``mask.exr``: whoever opens them next
    is misled."""
    def never(*args, **kwargs):
        raise AssertionError("the work began for an output that is refused")

    monkeypatch.setattr(f"voxfield.cli.{out}.open_octree" if out != "cmd_errors"
                        else "voxfield.cli.cmd_errors.load_error_table", never)
    assert main([*command, "--quiet", "--out", str(tmp_path / wrong)]) == 2
    assert "ending in ." in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_an_image_format_render_cannot_write_fails_before_the_scene_loads(
        tmp_path, capsys, monkeypatch):
    def never(args):
        raise AssertionError("the scene was opened for an image that cannot be written")

    monkeypatch.setattr("voxfield.cli.cmd_render.open_octree", never)
    assert main(["render", "builtin:sphere", "--quiet", "--out", str(tmp_path / "x.jpg")]) == 2
    assert "'.jpg'" in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_checking_an_output_leaves_nothing_behind(tmp_path):
    for target in (tmp_path / "a" / "b" / "x.png", tmp_path / "y.png"):
        assert check_writable(target) == target
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "x.png").mkdir()
    with pytest.raises(IsADirectoryError):
        check_writable(tmp_path / "x.png")


def test_a_missing_folder_that_cannot_be_made_is_refused_before_the_work(tmp_path,
                                                                         monkeypatch):
    """Missing folders are made and removed again: a refusal writing would meet shows
    before the work (a name too long, a link to nothing, no permission), naming the path."""
    long_name = tmp_path / "ok" / ("n" * 300) / "x.png"
    with pytest.raises(OSError) as refused:
        check_writable(long_name)
    assert refused.value.errno == errno.ENAMETOOLONG
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    with pytest.raises(OSError, match="link to nothing") as refused:
        check_writable(tmp_path / "dangling" / "x.png")
    assert refused.value.filename == str(tmp_path / "dangling")

    def no_permission(self, *args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", no_permission)
    with pytest.raises(PermissionError) as refused:
        check_writable(tmp_path / "new" / "x.png")
    assert "probe" not in str(refused.value)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling"]


@pytest.mark.parametrize("command", [
    ["render", "missing.vox", "--size", "8"],
    ["bake", "missing.vox", "--grid", "2"],
    ["build", "missing.vox"],
])
def test_a_command_refused_after_its_output_check_leaves_no_folders(
        command, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    name = {"render": "x.png", "bake": "probes", "build": "x.npz"}[command[0]]
    assert main([*command, "--quiet", "--out", f"new/deeper/{name}"]) == 2
    assert "missing.vox" in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_output_naming_a_folder_is_one_line(tmp_path, capsys):
    folder = tmp_path / "picture.png"
    folder.mkdir()
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet",
                 "--out", str(folder)]) == 2
    assert "folder" in one_error_line(capsys)


@pytest.mark.parametrize("command, name", [
    (["render", "builtin:sphere", "--size", "8"], "picture.png"),
    (["build", "builtin:sphere"], "octree.npz"),
    (["errors", "show", "51"], "mask.png"),
    (["calibrate", "builtin:sphere", "--target-rays", "100"], "trail.json"),
])
def test_an_output_that_is_a_pipe_or_device_is_refused_and_kept(command, name, tmp_path,
                                                                capsys):
    """``--out /dev/null`` as root renamed a file over the device: /dev/null became a plain
    file. A pipe stands in for it (any user can make one)."""
    pipe = tmp_path / name
    os.mkfifo(pipe)
    assert main([*command, "--quiet", "--out", str(pipe)]) == 2
    line = one_error_line(capsys)
    assert str(pipe) in line and "not a file" in line
    assert stat.S_ISFIFO(pipe.stat().st_mode)
    assert [p.name for p in tmp_path.iterdir()] == [name]


@pytest.mark.parametrize("argv, words", [
    (["render", "builtin:sphere", "--sise", "8", "--out", "x.png"],
     "unrecognized arguments: --sise 8"),
    (["rendr"], "invalid choice: 'rendr'"),
    (["render", "builtin:sphere", "--size", "0"], "argument --size"),
    (["study"], "required: STUDY"),
    (["study", "curves", "builtin:sphere", "--lods", "2,2"], "see `voxfield study curves"),
])
def test_the_parser_speaks_in_one_line_naming_the_help(argv, words, capsys):
    """argparse printed its usage block above the error: several lines where any other bad
    input gets one."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    line = one_error_line(capsys)
    assert words in line and line.endswith("--help`)")


def test_voxfield_alone_lists_its_commands(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: voxfield") and "probe-render" in out


def test_output_name_too_long_is_one_line(tmp_path, capsys):
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet",
                 "--out", str(tmp_path / ("x" * 300 + ".png"))]) == 2
    assert "too long" in one_error_line(capsys)


def test_bake_into_a_file_is_one_line(a_file, capsys):
    assert main(["bake", "builtin:cornell", "--grid", "1x1x1", "--resolution", "8",
                 "--quiet", "--out", str(a_file / "pb")]) == 2
    one_error_line(capsys)


def test_light_onto_a_folder_is_one_line_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "lit.npz").mkdir()
    assert main([*LIGHT, "--out", str(tmp_path / "lit.npz")]) == 2
    one_error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lit.npz"]


def test_a_failed_octree_write_leaves_no_report_previews_or_temporary_file(
        tmp_path, capsys, monkeypatch):
    # The octree is written by a thread while the previews render: its failure must still
    # end the command with one line, before the report or a preview is written.
    def fail(octree, path):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("voxfield.cli.cmd_light.write_octree_file", fail)
    assert main([*LIGHT, "--out", str(tmp_path / "lit.npz")]) == 2
    assert "disk is full" in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_light_interrupted_while_its_previews_render_keeps_the_old_outputs(
        tmp_path, capsys, monkeypatch):
    # all or nothing: the octree, its report and the previews of one bake belong together
    out = tmp_path / "lit.npz"
    assert main([*LIGHT, "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert {"lit.npz", "lit.json", "lit_noon.png", "lit.png"} <= set(before)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("voxfield.cli.cmd_light.render_previews", interrupted)
    assert main([*LIGHT, "--seed", "5", "--out", str(out)]) == 130
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders anyway")
def test_read_only_folder_is_one_line(tmp_path, capsys):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert main(["render", "builtin:sphere", "--size", "8", "--quiet",
                     "--out", str(folder / "x.png")]) == 2
        one_error_line(capsys)
    finally:
        folder.chmod(0o755)


def test_a_closed_pipe_is_one_line():
    proc = subprocess.run(
        f"{sys.executable} -m voxfield scenes | head -c 10", shell=True,
        capture_output=True, text=True, timeout=120)
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip() == "" or proc.stderr.strip().startswith("voxfield: error:")


@pytest.mark.parametrize("argv", [
    ["render", "builtin:sphere", "--out", "x.png", "--seed", "99999999999999999999"],
    ["render", "builtin:sphere", "--out", "x.png", "--seed", "-1"],
    ["render", "builtin:sphere", "--out", "x.png", "--fov", "0"],
    ["render", "builtin:sphere", "--out", "x.png", "--fov", "nan"],
    ["render", "builtin:sphere", "--out", "x.png", "--size", "100000"],
    ["info", "mesh.obj", "--mesh-resolution", "100000"],
    ["errors", "show", "12", "--threshold", "nan"],
    ["errors", "build", "--directions", "100000000"],
    ["calibrate", "builtin:pillars", "--target-psnr", "nan"],
    ["calibrate", "builtin:pillars", "--target-rays", "10", "--iterations", "100000000"],
    ["info", "dem:jacksboro", "--vertical-scale", "-5"],
    ["sweep", "builtin:sphere", "--thresholds", "0.1,nan"],
])
def test_nonsense_values_are_refused_by_the_parser(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


def test_an_unknown_scheduler_writes_nothing(tmp_path, capsys):
    out = tmp_path / "probes"
    assert main(["bake", "builtin:cornell", "--grid", "1x1x1", "--resolution", "8", "--quiet",
                 "--scheduler", "nowhere", "--out", str(out)]) == 2
    assert "scheduler" in one_error_line(capsys)
    assert not (out / "probes.json").exists()


def test_a_recipe_refuses_a_vertical_scale(capsys):
    assert main(["info", "terrain:mountain", "--vertical-scale", "2", "--quiet"]) == 2
    assert "vertical-scale" in one_error_line(capsys)


def test_outputs_respect_the_umask_and_keep_an_existing_mode(tmp_path):
    previous = os.umask(0o022)
    try:
        fresh = tmp_path / "fresh.json"
        with atomic_path(fresh) as tmp:
            tmp.write_text("{}")
        assert stat.S_IMODE(fresh.stat().st_mode) == 0o644
        kept = tmp_path / "kept.json"
        kept.write_text("old")
        kept.chmod(0o640)
        with atomic_path(kept) as tmp:
            tmp.write_text("new")
        assert stat.S_IMODE(kept.stat().st_mode) == 0o640 and kept.read_text() == "new"
    finally:
        os.umask(previous)


def test_rendered_images_are_0644_under_umask_022(tmp_path):
    previous = os.umask(0o022)
    try:
        out = tmp_path / "s.png"
        assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--out", str(out)]) == 0
        assert stat.S_IMODE(out.stat().st_mode) == 0o644
    finally:
        os.umask(previous)


def test_a_one_pixel_tiff_says_what_a_dem_needs(tmp_path, capsys):
    path = tmp_path / "tiny.tif"
    Image.fromarray(np.zeros((1, 1), np.int16)).save(path)
    assert main(["info", str(path), "--quiet"]) == 2
    assert "2×2" in one_error_line(capsys)


def test_gltf_with_broken_json_says_so(tmp_path, capsys):
    path = tmp_path / "broken.gltf"
    path.write_text("{ not json")
    assert main(["info", str(path), "--quiet"]) == 2
    assert "not valid glTF" in one_error_line(capsys)


def test_a_mesh_vertex_at_infinity_or_1e300_gets_no_arithmetic_notes(tmp_path, capsys):
    """An infinite vertex printed five "invalid value" notes before its error; one at 1e300
    four "overflow" notes before a correct voxelization."""
    triangle = "v 0 0 0\nv {x} 0 0\nv 0 1 0\nf 1 2 3\n"
    (tmp_path / "inf.obj").write_text(triangle.format(x="inf"))
    assert main(["info", str(tmp_path / "inf.obj"), "--quiet"]) == 2
    assert "vertex 2 is at inf 0 0" in one_error_line(capsys)
    (tmp_path / "huge.obj").write_text(triangle.format(x="1e300"))
    assert main(["info", str(tmp_path / "huge.obj"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_damaged_scene_files_are_one_plain_line(tmp_path, capsys):
    """Each named the reading library's internals (``IndexError: list index out of range``,
    ``claims 0 + -2147483648 bytes``); now one line of plain words each."""
    import tifffile

    tifffile.imwrite(tmp_path / "whole.tif", np.zeros((8, 8), np.int16))
    files = {
        "cut.ply": b"ply\nformat ascii 1.0\nelement vertex 3\n",
        "cut.tif": (tmp_path / "whole.tif").read_bytes()[:8],
        "huge.vox": b"VOX " + (150).to_bytes(4, "little") + b"MAIN" + bytes(4)
        + (0x80000000).to_bytes(4, "little"),
        "empty.gltf": b'{"asset": {"version": "2.0"}, "meshes": [{"primitives": '
                      b'[{"attributes": {"POSITION": 0}}]}]}',
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
        assert main(["info", str(tmp_path / name), "--quiet"]) == 2
        line = one_error_line(capsys)
        assert "Error" not in line and "-2147483648" not in line, line


def test_library_warnings_are_one_plain_note(capsys):
    _note_warning(UserWarning("model 3 is missing"), UserWarning, "x.py", 1)
    assert capsys.readouterr().err == "voxfield: note: model 3 is missing\n"


def test_values_with_a_leading_minus_reach_their_own_check(tmp_path, capsys):
    """Coordinates and specs may start with '-': argparse alone would call them options."""
    assert main(["render", "builtin:sphere", "--eye", "-10,20,30", "--target", "8,8,8",
                 "--size", "8", "--quiet", "--out", str(tmp_path / "eye.png")]) == 0
    assert (tmp_path / "eye.png").is_file()
    assert main(["bake", "builtin:cornell", "--grid", "-1x2x2", "--quiet",
                 "--out", str(tmp_path / "pb")]) == 2
    assert "-1x2x2" in one_error_line(capsys)
    assert not (tmp_path / "pb").exists()


def test_a_gpu_seen_only_through_numbas_own_cuda_target_is_no_gpu(monkeypatch):
    # Numba's deprecated CUDA target sees the GPU but cannot compile the kernels: without
    # numba-cuda, --device cuda must end in the one-line "no CUDA GPU", not a traceback.
    import numba
    from numba import cuda

    from voxfield.render import device

    monkeypatch.setattr(numba.config, "ENABLE_CUDASIM", False)
    monkeypatch.setattr(cuda, "is_available", lambda: True)
    monkeypatch.setattr(device, "numba_cuda_installed", lambda: False)
    assert not device.cuda_available()
    monkeypatch.setattr(device, "numba_cuda_installed", lambda: True)
    assert device.cuda_available()


def test_cuda_without_a_gpu_or_for_a_cpu_only_renderer_is_one_line(tmp_path, capsys,
                                                                   monkeypatch):
    from voxfield.render import device

    monkeypatch.setattr(device, "cuda_available", lambda: False)  # even on a GPU machine
    out = tmp_path / "x.png"
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--device", "cuda",
                 "--out", str(out)]) == 2
    assert "no CUDA GPU" in one_error_line(capsys)
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--device", "cuda",
                 "--renderer", "error-aware", "--out", str(out)]) == 2
    assert "CPU only" in one_error_line(capsys)
    assert not out.exists()
    # probe-render: the light field needs the GPU; the baselines run on the CPU only.
    probes = tmp_path / "probes"
    assert main(["probe-render", str(probes), "--quiet", "--device", "cuda",
                 "--out", str(out)]) == 2
    assert "no CUDA GPU" in one_error_line(capsys)
    assert main(["probe-render", str(probes), "--quiet", "--device", "cuda", "--method",
                 "environment", "--out", str(out)]) == 2
    assert "CPU only" in one_error_line(capsys)
    assert not out.exists()


def test_a_straight_down_eye_and_target_render(tmp_path):
    """No option sets the up vector, so a vertical --eye/--target view must pick its own."""
    out = tmp_path / "down.png"
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--eye", "8,100,8",
                 "--target", "8,0,8", "--out", str(out)]) == 0
    assert out.is_file()


@pytest.mark.parametrize("extra, words", [
    (["--camera", "orbit", "--eye", "1,2,3", "--target", "0,0,0"], "give one of them"),
    (["--camera", "ortho-top", "--fov", "10"], "no field of view"),
    (["--camera", "cube", "--fov", "10"], "no field of view"),
])
def test_options_that_contradict_each_other_are_one_line(extra, words, tmp_path, capsys):
    """Once accepted, with one of them silently ignored."""
    out = tmp_path / "x.png"
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", *extra,
                 "--out", str(out)]) == 2
    assert words in one_error_line(capsys)
    assert not out.exists()


@pytest.mark.parametrize("argv, words", [
    (["info", "terrain:mountain", "--footprint", "1"], "2 or more"),
    (["render", "builtin:sphere", "--fov", "1e-300", "--out", "x.png"], "at least 0.01"),
])
def test_the_parser_states_the_range_the_work_needs(argv, words, capsys):
    """A footprint of 1 passed the parser's 1..16384 and failed later with 2..16384."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert words in capsys.readouterr().err


@pytest.mark.parametrize("scene, words", [("", "no scene named"), (".", "a folder")])
def test_an_empty_scene_name_or_a_folder_says_so(scene, words, tmp_path, capsys):
    assert main(["info", scene, "--quiet"]) == 2
    assert words in one_error_line(capsys)


def test_minus_infinity_reaches_its_own_check(tmp_path, capsys):
    """``-inf`` was taken for an option ("expected one argument"); the parser's coordinate
    check refuses it by name."""
    with pytest.raises(SystemExit) as exc:
        main(["render", "builtin:sphere", "--size", "8", "--quiet", "--eye", "-inf,1,1",
              "--target", "0,0,0", "--out", str(tmp_path / "x.png")])
    assert exc.value.code == 2
    assert "-inf" in one_error_line(capsys)


def test_an_image_and_its_counter_maps_appear_together_or_not_at_all(tmp_path, monkeypatch,
                                                                    capsys):
    """A full disk while writing the LOD map left the image behind without its maps, and the
    message named no file."""
    real_save_png = counter_maps.save_png

    def full_disk_for_the_lod_map(image, path, **kwargs):
        if "_lod" in Path(path).name:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as Pillow raises it
        return real_save_png(image, path, **kwargs)

    monkeypatch.setattr(counter_maps, "save_png", full_disk_for_the_lod_map)
    out = tmp_path / "c.png"
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--counters",
                 "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert "the disk is full" in line and "c_lod.png" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_an_exr_the_disk_has_no_room_for_is_one_line(tmp_path, monkeypatch, capsys):
    """OpenEXR reports a full disk as a RuntimeError with the system's text: a traceback."""
    openexr = pytest.importorskip("OpenEXR")

    class FullDiskFile:
        def __init__(self, *args, **kwargs):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            raise RuntimeError(f"Failed to write pixel data to image file \"{path}\". "
                               f"{os.strerror(errno.ENOSPC)}")

    monkeypatch.setattr(openexr, "File", FullDiskFile)
    out = tmp_path / "big.exr"
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert "the disk is full" in line and str(out) in line
    assert list(tmp_path.iterdir()) == []


def test_a_staged_file_that_fails_is_reported_for_its_target_and_none_appear(tmp_path):
    first, second = tmp_path / "a.txt", tmp_path / "b.txt"
    with pytest.raises(OSError) as caught, atomic_paths([first, second]) as (a, b):
        a.write_text("written")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(b))  # as open() names it
    assert caught.value.filename == str(second)
    assert list(tmp_path.iterdir()) == []
    with atomic_paths([first, second]) as (a, b):
        a.write_text("1")
        b.write_text("2")
    assert first.read_text() + second.read_text() == "12"


def test_a_view_of_nothing_is_refused_by_a_study_before_its_renders(capsys, monkeypatch,
                                                                   tmp_path):
    """calibrate "calibrated" a view of empty sky: every render equals the reference, so
    any threshold met any PSNR target."""
    def never(*args, **kwargs):
        raise AssertionError("the calibration rendered a view of nothing")

    monkeypatch.setattr("voxfield.cli.cmd_calibrate.calibrate_threshold", never)
    away = ["--eye", "32,1000,32", "--target", "32,2000,32", "--size", "16"]
    assert main(["calibrate", "builtin:pillars", "--target-psnr", "20", *away, "--quiet"]) == 2
    assert "meets nothing of the scene" in one_error_line(capsys)
    assert main(["render", "builtin:pillars", *away, "--renderer", "lod", "--out",
                 str(tmp_path / "sky.png")]) == 0
    assert "voxfield: note: the view from (32.0, 1000.0, 32.0) meets nothing" in \
        capsys.readouterr().err


@pytest.mark.parametrize(("eye", "target", "words"), [
    ("32,-3,32", "40,-3,40", "is under the scene's surface"),  # below the pillars' floor
    ("0.5,0.5,0.5", "10,10,10", "is inside a voxel"),  # in the floor's corner voxel
])
def test_render_draws_a_buried_camera_with_a_note(eye, target, words, capsys, tmp_path):
    """The studies refuse these views; render draws them and says why they look odd."""
    out = tmp_path / "buried.png"
    assert main(["render", "builtin:pillars", "--eye", eye, "--target", target, "--renderer",
                 "lod", "--size", "16", "--out", str(out), "--quiet"]) == 0
    assert out.exists()
    err = capsys.readouterr().err
    assert err.startswith("voxfield: note: the camera at (") and words in err


@pytest.mark.parametrize("name", ["x.vox", "x.npz", "x.npy", "x.hgt", "x.obj"])
def test_a_pipe_or_device_named_as_a_scene_is_one_line_not_a_hang(name, tmp_path, capsys):
    pipe = tmp_path / name
    os.mkfifo(pipe)  # reading it would wait for a writer for ever
    assert main(["info", str(pipe), "--quiet"]) == 2
    assert "pipe" in one_error_line(capsys)
    zero = tmp_path / f"zero{Path(name).suffix}"
    zero.symlink_to("/dev/zero")  # reading it would fill the memory
    assert main(["info", str(zero), "--quiet"]) == 2
    one_error_line(capsys)


def test_a_texture_that_is_a_pipe_is_skipped_with_a_note(tmp_path):
    from voxfield.scene.mesh import load_mesh

    os.mkfifo(tmp_path / "t.png")
    (tmp_path / "t.mtl").write_text("newmtl T\nKd 1 0 0\nmap_Kd t.png\n")
    (tmp_path / "t.obj").write_text("mtllib t.mtl\nusemtl T\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                    "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    with pytest.warns(UserWarning, match="pipe, device or folder"):
        mesh = load_mesh(tmp_path / "t.obj")
    np.testing.assert_allclose(mesh.face_color, [[1, 0, 0]])


def test_gltf_json_nested_past_python_s_recursion_limit_is_one_line(tmp_path, capsys):
    (tmp_path / "deep.gltf").write_text("[" * 200_000)
    assert main(["info", str(tmp_path / "deep.gltf"), "--quiet"]) == 2
    assert "not valid glTF" in one_error_line(capsys)


def test_an_output_that_is_a_link_is_written_through_it(tmp_path):
    target = tmp_path / "real.png"
    target.write_bytes(b"old")
    link = tmp_path / "link.png"
    link.symlink_to(target)
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--out", str(link)]) == 0
    assert link.is_symlink() and target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_link_to_a_missing_folder_is_refused_as_open_refuses_it(tmp_path, capsys):
    """Writing through such a link made the folders it pointed into, wherever that was;
    ``open()`` refuses it (ENOENT), and so does every output check, before the work."""
    from voxfield.atomic import atomic_path, check_writable

    link = tmp_path / "link.png"
    link.symlink_to(tmp_path / "nowhere" / "deep" / "x.png")
    with pytest.raises(FileNotFoundError):
        open(link, "wb")  # noqa: SIM115 - the oracle: what the OS does with the link
    for write in (check_writable, lambda path: atomic_path(path).__enter__()):
        with pytest.raises(FileNotFoundError, match="whose folder does not exist"):
            write(link)
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--out", str(link)]) == 2
    assert "it is a link to" in one_error_line(capsys)
    assert not (tmp_path / "nowhere").exists() and link.is_symlink()


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write read-only files anyway")
def test_a_read_only_output_is_one_line_and_kept(tmp_path, capsys):
    kept = tmp_path / "kept.png"
    kept.write_bytes(b"keep me")
    kept.chmod(0o444)
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--out", str(kept)]) == 2
    assert "read-only" in one_error_line(capsys)
    assert kept.read_bytes() == b"keep me"


def test_build_onto_its_own_scene_file_is_refused(tmp_path, capsys):
    from voxfield.scene.builtin import builtin_scene
    from voxfield.scene.npz_io import save_scene

    scene = save_scene(builtin_scene("sphere"), tmp_path / "scene.npz")
    data = scene.read_bytes()
    assert main(["build", str(scene), "--quiet", "--out", str(scene)]) == 2
    assert "names the scene it reads" in one_error_line(capsys)
    assert scene.read_bytes() == data
    # a lit octree may be lit again in place: it is read whole before it is replaced
    lit = tmp_path / "lit.npz"
    assert main([*LIGHT, "--out", str(lit)]) == 0
    assert main(["light", str(lit), "--times", "evening", "--sky-rays", "0", "--no-preview",
                 "--quiet", "--out", str(lit)]) == 0


@pytest.mark.parametrize("renderer", ["reference", "lod", "error-aware", "adaptive"])
def test_options_another_renderer_takes_are_noted_not_silently_dropped(renderer, tmp_path,
                                                                      capsys):
    out = str(tmp_path / "x.png")
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--renderer", renderer,
                 "--out", out]) == 0
    assert capsys.readouterr().err == ""  # the defaults: nothing to say
    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--renderer", renderer,
                 "--reuse-parent", "--out", out]) == 0
    err = capsys.readouterr().err
    if renderer == "error-aware":
        assert err == ""
    else:
        assert err.strip() == (f"voxfield: note: the {renderer} renderer takes no "
                               "--reuse-parent (for error-aware); ignored")


@pytest.mark.parametrize("renderer, enabling, unread, note", [
    ("lod", [], ["--spp-side", "3"], "the lod renderer takes no --spp-side (for reference)"),
    ("lod", ["--lod", "2"], ["--cone-scale", "4"],
     "the lod renderer reads --cone-scale only with --lod cone"),
    ("error-aware", ["--base-lod", "1"], ["--cone-scale", "4"],
     "the error-aware renderer reads --cone-scale only with --base-lod cone"),
    ("error-aware", [], ["--bright-ratio", "3", "--colour-to-voxels"],
     "the error-aware renderer reads --bright-ratio only with --lighting-aware, "
     "--colour-to-voxels only with a --colour-term above 0"),
    ("error-aware", ["--base-lod", "0"], ["--threshold", "-1", "--decay", "3",
                                         "--refinements", "1"],
     "the error-aware renderer reads --threshold, --decay and --refinements only with a "
     "--base-lod other than 0"),
    ("error-aware", ["--base-lod", "0"], ["--encoding", "sh", "--reuse-parent",
                                         "--lighting-aware", "--bright-ratio", "3",
                                         "--context-aware", "--colour-term", "1",
                                         "--colour-to-voxels"],
     "the error-aware renderer reads --encoding, --reuse-parent, --lighting-aware, "
     "--bright-ratio, --context-aware, --colour-term and --colour-to-voxels only with a "
     "--base-lod other than 0"),
])
def test_options_the_renderer_reads_only_with_another_setting_are_noted(
        renderer, enabling, unread, note, tmp_path, capsys):
    """Each rendered the same image as without it, and said nothing (``--spp-side`` was
    counted as the lod renderer's own, through a field the command line never sets)."""
    base = ["render", "builtin:sphere", "--size", "16", "--quiet", "--renderer", renderer,
            *enabling]
    plain, given = tmp_path / "plain.png", tmp_path / "given.png"
    assert main([*base, "--out", str(plain)]) == 0
    assert capsys.readouterr().err == ""
    assert main([*base, *unread, "--out", str(given)]) == 0
    assert capsys.readouterr().err == f"voxfield: note: {note}; ignored\n"
    assert plain.read_bytes() == given.read_bytes()


@pytest.mark.parametrize("renderer, enabling, note", [
    ("reference", [], "the reference renderer takes no --threshold (for error-aware)"),
    ("error-aware", ["--base-lod", "0"],
     "the error-aware renderer reads --threshold only with a --base-lod other than 0"),
])
def test_an_option_given_at_its_default_is_noted_as_any_other(renderer, enabling, note,
                                                              tmp_path, capsys):
    """The notes compared values with the defaults: ``--threshold`` given at its default
    was ignored without a word, at any other value noted."""
    from voxfield.render.error_aware import ErrorAwareOptions

    assert main(["render", "builtin:sphere", "--size", "8", "--quiet", "--renderer", renderer,
                 *enabling, "--threshold", str(ErrorAwareOptions.threshold),
                 "--out", str(tmp_path / "x.png")]) == 0
    assert capsys.readouterr().err == f"voxfield: note: {note}; ignored\n"


@pytest.mark.parametrize("renderer", ["error-aware", "adaptive"])
def test_a_default_base_lod_the_scene_is_too_shallow_for_says_it_is_the_default(
        renderer, tmp_path, capsys):
    """A two-voxel scene has LODs 0..1: the renderer refused "base LOD … got 2", a value
    the user never typed."""
    scene = tmp_path / "two.npz"
    np.savez(scene, coords=np.array([[0, 0, 0], [1, 1, 1]], np.int32),
             color=np.full((2, 3), 0.5, np.float32))
    common = ["render", str(scene), "--size", "8", "--quiet", "--renderer", renderer,
              "--out", str(tmp_path / "x.png")]
    assert main(common) == 2
    assert "--base-lod 2 (the default) is coarser than" in one_error_line(capsys)
    assert main([*common, "--base-lod", "3"]) == 2
    assert "--base-lod 3 is coarser than" in one_error_line(capsys)
    assert main([*common, "--base-lod", "1"]) == 0


def test_compare_notes_the_error_aware_options_base_lod_0_does_not_read(tmp_path, capsys):
    """Its error-aware+reuse row came out as the plain one, without the note render gives."""
    import json

    common = ["compare", "builtin:sphere", "--size", "16", "--quiet"]
    assert main([*common, "--base-lod", "0", "--threshold", "0.3", "--reuse-parent",
                 "--out", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == (
        "voxfield: note: the error-aware renderer reads --threshold and --reuse-parent only "
        "with a --base-lod other than 0; ignored\n")
    rows = json.loads((tmp_path / "a" / "results.json").read_text())["rows"]
    costs = {row["renderer"]: (row["cost"]["rays"], row["cost"]["traversal_steps"],
                               row["quality"]) for row in rows}
    assert costs["error-aware+reuse"] == costs["error-aware"]
    assert main([*common, "--threshold", "0.3", "--reuse-parent",
                 "--out", str(tmp_path / "b")]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv", [
    ["compare", "builtin:cornell", "--channel", "emission"],
    ["study", "thresholds", "builtin:cornell", "--channel", "emission", "--thresholds", "0.1"],
    ["calibrate", "builtin:cornell", "--channel", "emission", "--target-rays", "300"],
])
def test_a_channel_brighter_than_1_is_refused_before_any_render(argv, tmp_path, capsys):
    """The metrics take [0, 1]: these failed after every render (their folder written),
    advising a tone map no option offers. builtin:cornell's lamp voxels emit up to 4."""
    out = tmp_path / ("out.json" if argv[0] == "calibrate" else "out")
    assert main([*argv, "--size", "16", "--out", str(out)]) == 2
    assert one_error_line(capsys) == (
        "voxfield: error: channel 'emission' holds colours up to 4; PSNR, RMSE and SSIM "
        "take linear colours in [0, 1]: measure another channel")
    assert not out.exists()


def test_options_read_with_their_setting_are_not_noted(tmp_path, capsys):
    for argv in (["--renderer", "lod", "--cone-scale", "4"],
                 ["--renderer", "error-aware", "--base-lod", "cone", "--cone-scale", "2"],
                 ["--renderer", "error-aware", "--lighting-aware", "--bright-ratio", "3"],
                 ["--renderer", "error-aware", "--colour-term", "0.5", "--colour-to-voxels"],
                 ["--renderer", "reference", "--spp-side", "3"]):
        assert main(["render", "builtin:sphere", "--size", "8", "--quiet", *argv,
                     "--out", str(tmp_path / "x.png")]) == 0
        assert capsys.readouterr().err == "", argv


@pytest.mark.parametrize("argv, same_image", [
    (["calibrate", "builtin:pillars", "--target-rays", "2000", "--iterations", "4"],
     "every --threshold renders the same image"),
    (["sweep", "builtin:pillars", "--thresholds", "0.5,0.2", "--decays", "0.2"],
     "every --thresholds/--decays cell renders the same image"),
    (["study", "thresholds", "builtin:pillars", "--thresholds", "0.5,0.2"],
     "every --thresholds value renders the same image"),
    (["study", "lighting", "builtin:pillars", "--times", "noon"],
     "the lighting-aware renders are the error-aware ones"),
])
def test_varying_the_refinement_from_base_lod_0_is_refused_before_any_work(argv, same_image,
                                                                           tmp_path, capsys):
    """From LOD 0 there is nothing finer: calibrate reported the threshold its bisection
    stopped at, and the studies' rows came out identical, without a word (the lighting
    study's error-aware and lighting-aware rows alike, after a sun bake)."""
    out = tmp_path / "out"
    assert main([*argv, "--size", "32", "--base-lod", "0", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"voxfield: error: --base-lod 0: the error-aware renderer has nothing "
                   f"finer than LOD 0 to refine into, so {same_image}; give a base LOD of 1 "
                   "or more, or cone")
    assert not out.exists()


def test_a_bake_notes_a_cone_scale_its_fixed_lod_does_not_read(tmp_path, capsys):
    common = ["bake", "builtin:sphere", "--grid", "1x1x1", "--resolution", "4", "--quiet",
              "--renderer", "lod"]
    assert main([*common, "--lod", "2", "--cone-scale", "4", "--out", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == ("voxfield: note: the lod radiance renderer reads "
                                       "--cone-scale only with --lod cone; ignored\n")
    assert main([*common, "--cone-scale", "4", "--out", str(tmp_path / "b")]) == 0
    assert capsys.readouterr().err == ""
    assert main([*common[:-1], "error-aware", "--lod", "0", "--threshold", "0.3", "--decay",
                 "1", "--out", str(tmp_path / "c")]) == 0
    assert capsys.readouterr().err == ("voxfield: note: the error-aware radiance renderer "
                                       "reads --threshold and --decay only with a --lod other "
                                       "than 0; ignored\n")


@pytest.mark.parametrize("command", [
    ["info"],
    ["render", "--size", "8", "--out", "view.png"],
    ["light", "--times", "noon", "--sky-rays", "0", "--no-preview", "--out", "lit.npz"],
])
def test_build_options_given_with_a_saved_octree_are_noted(command, tmp_path, capsys,
                                                           monkeypatch):
    """A saved octree is drawn as it was built: ``render lit.npz --vertical-scale 3`` drew
    the saved relief without a word."""
    monkeypatch.chdir(tmp_path)
    assert main(["build", "builtin:sphere", "--quiet", "--out", "saved.npz"]) == 0
    name, *rest = command
    assert main([name, "saved.npz", *rest, "--quiet"]) == 0
    assert capsys.readouterr().err == ""  # no build option given: nothing to say
    assert main([name, "saved.npz", *rest, "--quiet", "--vertical-scale", "3",
                 "--lod-colour", "mean", "--mesh-resolution", "256"]) == 0
    assert capsys.readouterr().err == (
        "voxfield: note: saved.npz, a saved octree, takes no --vertical-scale (for DEMs), "
        "--lod-colour (for a scene being built); ignored\n")


def test_build_options_a_scene_kind_does_not_read_are_noted(tmp_path, capsys, monkeypatch):
    """``render builtin:sphere --footprint 4096`` drew the sphere as ever without a word;
    each kind of scene names the build options it does not read, and only those."""
    monkeypatch.chdir(tmp_path)
    np.save("hills.npy", np.add.outer(np.arange(16.0), np.arange(16.0)))
    render = ["render", "--size", "8", "--quiet", "--out", "view.png"]
    assert main([*render[:1], "builtin:sphere", *render[1:], "--lod-colour", "mean",
                 "--colour-storage", "float32"]) == 0
    assert capsys.readouterr().err == ""  # a built scene reads both
    assert main([*render[:1], "builtin:sphere", *render[1:], "--footprint", "64",
                 "--mesh-resolution", "128"]) == 0
    assert capsys.readouterr().err == (
        "voxfield: note: builtin:sphere, a built-in scene, takes no --mesh-resolution (for "
        "meshes), --footprint (for terrains and DEMs); ignored\n")
    assert main([*render[:1], "hills.npy", *render[1:], "--footprint", "16",
                 "--vertical-scale", "2", "--dem-fit", "crop"]) == 0
    assert capsys.readouterr().err == ""  # a DEM reads all three
    assert main([*render[:1], "hills.npy", *render[1:], "--footprint", "16",
                 "--mesh-resolution", "64"]) == 0
    assert capsys.readouterr().err == (
        "voxfield: note: hills.npy, a DEM, takes no --mesh-resolution (for meshes); "
        "ignored\n")


def test_a_study_of_several_scenes_notes_the_build_options_none_of_them_reads(tmp_path,
                                                                              capsys):
    np.save(tmp_path / "hills.npy", np.add.outer(np.arange(16.0), np.arange(16.0)))
    hills = str(tmp_path / "hills.npy")
    study = ["study", "normalisation", "builtin:pillars", hills, "--size", "8", "--quiet",
             "--footprint", "16"]
    assert main([*study, "--out", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == ""  # the DEM reads the footprint the pillars do not
    assert main([*study, "--mesh-resolution", "64", "--out", str(tmp_path / "b")]) == 0
    assert capsys.readouterr().err == (
        f"voxfield: note: none of the scenes builtin:pillars, {hills} takes --mesh-resolution "
        "(for meshes); ignored\n")


def test_a_probe_render_notes_the_build_options_its_saved_scene_does_not_read(tmp_path,
                                                                              capsys):
    saved, probes = str(tmp_path / "saved.npz"), str(tmp_path / "p")
    assert main(["build", "builtin:sphere", "--quiet", "--out", saved]) == 0
    assert main(["bake", saved, "--grid", "1x1x1", "--resolution", "4", "--quiet",
                 "--out", probes]) == 0
    capsys.readouterr()
    assert main(["probe-render", probes, "--scene", saved, "--footprint", "64", "--size", "8",
                 "--method", "environment", "--quiet",
                 "--out", str(tmp_path / "view.exr")]) == 0
    assert capsys.readouterr().err == (
        f"voxfield: note: {saved}, a saved octree, takes no --footprint (for terrains and "
        "DEMs); ignored\n")


def test_a_bake_notes_the_options_its_radiance_renderer_does_not_take(tmp_path, capsys):
    assert main(["bake", "builtin:sphere", "--grid", "1x1x1", "--resolution", "4",
                 "--samples", "3", "--quiet", "--out", str(tmp_path / "p")]) == 0
    assert capsys.readouterr().err.strip() == (
        "voxfield: note: the error-aware radiance renderer takes no --samples (for "
        "reference); ignored")


def test_a_probe_render_over_its_own_probe_set_s_files_is_refused(tmp_path, capsys):
    probes = tmp_path / "p"
    assert main(["bake", "builtin:sphere", "--grid", "1x1x1", "--resolution", "4",
                 "--quiet", "--out", str(probes)]) == 0
    atlas = (probes / "radiance.exr").read_bytes()
    assert main(["probe-render", str(probes), "--size", "8", "--quiet", "--method",
                 "environment", "--out", str(probes / "radiance.exr")]) == 2
    assert "probe set it reads" in one_error_line(capsys)
    link = tmp_path / "view.exr"  # written through, a link is the file it names
    link.symlink_to(probes / "radiance.exr")
    assert main(["probe-render", str(probes), "--size", "8", "--quiet", "--method",
                 "environment", "--out", str(link)]) == 2
    assert "probe set it reads" in one_error_line(capsys)
    assert (probes / "radiance.exr").read_bytes() == atlas
    # beside the probes, under a name of its own, a render is welcome
    assert main(["probe-render", str(probes), "--size", "8", "--quiet", "--method",
                 "environment", "--out", str(probes / "view.exr")]) == 0
