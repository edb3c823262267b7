"""Option values outside what the library can use are refused by the parser (exit 2, one
line) with the library's own range, before any work: ``probe-render --step``, ``errors
build --resolution``; and a table built with ``errors build`` must be named ``.npz``."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from cli_output import one_error_line
from voxfield.cli import main
from voxfield.error_table.table import raycast_errors
from voxfield.errors import VoxfieldError
from voxfield.lightfield.trace import LightFieldOptions
from voxfield.probes.probe_set import BakeOptions
from voxfield.render.camera import Camera

BUILDERS = [("build", "build_error_table"), ("build-lighting", "build_lighting_error_table")]


def _refused_by_the_parser(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err
    return " ".join(err.split())


def _library_takes_step(step: float) -> bool:
    try:
        LightFieldOptions(marcher="march3d", step=step)
    except VoxfieldError:
        return False
    return True


def test_probe_render_takes_exactly_the_steps_the_library_takes(tmp_path, capsys):
    # The folder does not exist: a step the parser takes ends on it, one line; a step it
    # refuses is refused first, with the range, before anything is opened.
    out = tmp_path / "p.png"
    for step in ["1e-6", "1e-30", "1e308", "2", "1.0000001", "0.000244", "0", "-1", "nan",
                 "inf", str(1 / 4096), "0.25", "1"]:
        argv = ["probe-render", str(tmp_path / "none"), "--marcher", "march3d", "--step",
                step, "--out", str(out)]
        expected = 1 / 4096 <= float(step) <= 1  # 4096: LightFieldOptions' default cap
        assert _library_takes_step(float(step)) == expected, step
        if expected:
            assert main(argv) == 2
            assert "no such probe-set folder" in one_error_line(capsys)
        else:
            err = _refused_by_the_parser(argv, capsys)
            assert "--step" in err and "0.000244141..1 voxels" in err, err
        assert not out.exists()


@pytest.mark.parametrize("flag", ["--epsilon-value", "--epsilon-k", "--epsilon-front",
                                  "--refine-window"])
def test_hit_options_take_exactly_the_values_the_library_takes(flag, tmp_path, capsys):
    """A value the library refuses was refused after the probes were opened, in its own
    field's name ("epsilon_value must be a distance >= 0"); now by the parser, by flag."""
    field = flag[2:].replace("-", "_")
    for value in ["0", "0.5", "1e6", "-1", "nan", "inf", "-inf"]:
        try:
            LightFieldOptions(**{field: float(value)})
            takes = True
        except VoxfieldError:
            takes = False
        argv = ["probe-render", str(tmp_path / "none"), flag, value,
                "--out", str(tmp_path / "p.png")]
        if takes:
            assert main(argv) == 2
            assert "no such probe-set folder" in one_error_line(capsys), value
        else:
            err = _refused_by_the_parser(argv, capsys)
            assert f"argument {flag}:" in err and field not in err, err


def test_a_run_refused_for_its_probes_prints_the_error_alone(tmp_path, capsys):
    """The note on options the render does not read came before the error about the
    folder: two lines where the run did nothing (``--epsilon-k`` under the default footprint
    epsilon, ``--step`` under the hierarchical marcher)."""
    assert main(["probe-render", str(tmp_path / "none"), "--epsilon-k", "4", "--step", "0.5",
                 "--out", str(tmp_path / "p.png")]) == 2
    assert "no such probe-set folder" in one_error_line(capsys)


def test_probe_render_help_states_the_step_range(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["probe-render", "--help"])
    assert exc.value.code == 0
    assert "step in voxels, 0.000244141..1" in " ".join(capsys.readouterr().out.split())


def _library_takes_resolution(n: int) -> bool:
    # No directions: a resolution the library takes fails on them instead, before any cast.
    try:
        raycast_errors(np.zeros((0, 3)), resolution=n)
    except VoxfieldError as exc:
        return "resolution" not in str(exc)
    raise AssertionError("no directions were accepted")


@pytest.mark.parametrize("action, builder", BUILDERS)
def test_errors_build_takes_exactly_the_resolutions_the_library_takes(
        action, builder, tmp_path, capsys, monkeypatch):
    def reached(**kwargs):
        raise VoxfieldError("parsed")

    monkeypatch.setattr(f"voxfield.cli.cmd_errors.{builder}", reached)
    for n in (0, 1, 2, 3, 4096, 4097):
        argv = ["errors", action, "--resolution", str(n), "--out", str(tmp_path / "t.npz")]
        if _library_takes_resolution(n):
            assert main(argv) == 2
            assert "parsed" in one_error_line(capsys)
        else:
            assert "--resolution" in _refused_by_the_parser(argv, capsys)
    assert [n for n in (1, 2, 4096, 4097) if _library_takes_resolution(n)] == [2, 4096]


@pytest.mark.parametrize("action", ["build", "build-lighting"])
def test_errors_help_states_the_resolution_range(action, capsys):
    with pytest.raises(SystemExit):
        main(["errors", action, "--help"])
    assert "rays per direction, 2..4096" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("action, builder", BUILDERS)
def test_errors_build_writes_only_npz_and_says_so_first(action, builder, tmp_path, capsys,
                                                       monkeypatch):
    calls = []

    def count(**kwargs):
        calls.append(kwargs)
        raise VoxfieldError("cast")

    monkeypatch.setattr(f"voxfield.cli.cmd_errors.{builder}", count)
    for name in ["x.png", "x", "x.npz.tmp"]:
        assert main(["errors", action, "--quiet", "--out", str(tmp_path / name)]) == 2
        assert ".npz" in one_error_line(capsys)
        assert calls == [], "the table was ray-cast for an output it cannot be written as"
    assert list(tmp_path.iterdir()) == []
    assert main(["errors", action, "--quiet", "--out", str(tmp_path / "t.NPZ")]) == 2
    assert "cast" in one_error_line(capsys) and len(calls) == 1


@pytest.mark.parametrize("argv, words", [
    (["sweep", "builtin:pillars", "--decays", "0.1,0.1"], "0.1 is given twice"),
    (["study", "thresholds", "builtin:pillars", "--thresholds", "0.2,0.3,0.2"],
     "0.2 is given twice"),
    (["study", "resolution", "builtin:pillars", "--sizes", "32,32"], "32 is given twice"),
    (["study", "curves", "builtin:pillars", "--lods", "2,2"], "2 is given twice"),
    (["study", "curves", "builtin:pillars", "--cameras", "top,top"], "top is given twice"),
    (["study", "probes", "builtin:cornell", "--probe-counts", "2x2x2,2x2x2"],
     "is given twice"),
    (["study", "lighting", "builtin:pillars", "--channels", "albedo,albedo"],
     "albedo is given twice"),
    (["study", "lighting", "builtin:pillars", "--channels", ""], "expected names"),
    (["study", "probes", "builtin:cornell", "--marchers", ","], "expected names"),
])
def test_a_list_option_with_a_repeat_or_nothing_in_it_is_refused(argv, words, capsys):
    """A repeated knob rendered the same row twice and, in a curve, passed the "two values"
    check as two points that are one; an empty list quietly meant the defaults."""
    err = _refused_by_the_parser([*argv, "--out", "unused"], capsys)
    assert words in err, err


@pytest.mark.parametrize("argv", [
    ["sweep", "builtin:pillars", "--decays", "-0.5"],
    ["study", "curves", "builtin:pillars", "--decays", "0.1,-0.2"],
    ["sweep", "builtin:pillars", "--decays", "inf"],
    ["render", "builtin:pillars", "--renderer", "error-aware", "--decay", "-1"],
    ["compare", "builtin:pillars", "--decay", "-0.1"],
    ["bake", "builtin:cornell", "--grid", "1", "--decay", "-1"],
    ["bake", "builtin:cornell", "--grid", "1", "--threshold", "nan"],
    ["bake", "builtin:cornell", "--grid", "1", "--cone-scale", "0"],
])
def test_a_negative_decay_is_refused_before_the_work(argv, capsys):
    """The children's error weighs in with a decay of at least 0; the sweep refused -0.5
    only after it had rendered its reference and adaptive cells."""
    _refused_by_the_parser([*argv, "--out", "unused"], capsys)


def test_a_negative_threshold_is_taken_and_refines_everywhere(tmp_path):
    """A negative threshold is a setting (refine even where a node's error is zero), not a
    mistake; its help says so."""
    from voxfield.cli.options import threshold_arg

    assert threshold_arg("-1") == -1.0 and threshold_arg("inf") == math.inf
    out = tmp_path / "x.png"
    assert main(["render", "builtin:pillars", "--renderer", "error-aware", "--size", "8",
                 "--quiet", "--threshold", "-1", "--out", str(out)]) == 0


def _command_parsers(parser, name="voxfield"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _command_parsers(sub, f"{name} {sub_name}")
    yield name, parser


def test_every_command_s_help_names_the_camera_it_uses_by_default():
    """`study probes --help` said "(default top)" over a default of room, which fails on a
    terrain: the user was told the wrong view."""
    from voxfield.cli.main import build_parser

    seen = 0
    for name, parser in _command_parsers(build_parser()):
        for action in parser._actions:
            if action.dest == "camera":
                seen += 1
                assert f"(default {action.default}:" in action.help, name
    assert seen >= 10


@pytest.mark.parametrize(("argv", "prefix"), [
    (["study", "resolution", "builtin:sphere", "--sizes", "8,16", "--size", "32"], "--size"),
    (["sweep", "builtin:sphere", "--threshold", "0.1"], "--threshold"),
    (["render", "builtin:sphere", "--siz", "16", "--out", "unused.png"], "--siz"),
])
def test_an_option_is_never_taken_for_another_it_begins(argv, prefix, capsys):
    """argparse's abbreviations took ``--size 32`` for ``--sizes 32``: the resolution study
    measured one size of those asked for and exited 0. A prefix of an option is refused."""
    message = _refused_by_the_parser(argv, capsys)
    assert f"unrecognized arguments: {prefix}" in message


@pytest.mark.parametrize(("argv", "option"), [
    (["compare", "builtin:sphere", "--size", "6"], "--size 6"),
    (["sweep", "builtin:sphere", "--size", "6"], "--size 6"),
    (["calibrate", "builtin:sphere", "--target-psnr", "20", "--size", "6"], "--size 6"),
    (["study", "thresholds", "builtin:sphere", "--size", "6"], "--size 6"),
    (["study", "lighting", "builtin:sphere", "--size", "6"], "--size 6"),
    (["study", "probes", "builtin:sphere", "--size", "5"], "--size 5"),
    (["study", "resolution", "builtin:sphere", "--sizes", "4,8,2"], "--sizes 2,4"),
    (["study", "probe-resolution", "builtin:sphere", "--resolutions", "4,8"],
     "--resolutions 4"),
])
def test_a_side_too_small_for_ssim_is_refused_before_any_work(argv, option, tmp_path, capsys):
    """SSIM's 7×7 window: these commands rendered (a probe study baked and cached) at the
    sizes asked for, then stopped at the first measurement with a message naming no option."""
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    message = one_error_line(capsys)
    assert message.startswith(f"voxfield: error: {option}: ") and "7×7" in message
    assert not out.exists()


def test_probe_render_compare_refuses_a_side_too_small_for_ssim_before_any_work(tmp_path,
                                                                              capsys):
    """``probe-render --compare --size 6`` wrote its image, then stopped at the comparison;
    without --compare nothing is measured and the size is the user's to choose."""
    out = tmp_path / "p.png"
    assert main(["probe-render", str(tmp_path / "probes"), "--scene", "builtin:sphere",
                 "--compare", "--size", "6", "--out", str(out)]) == 2
    message = one_error_line(capsys)
    assert message.startswith("voxfield: error: --size 6: ") and "7×7" in message
    assert not out.exists()
    assert main(["probe-render", str(tmp_path / "probes"), "--size", "6",
                 "--out", str(out)]) == 2
    assert "--size" not in one_error_line(capsys)  # refused for the missing folder alone


def test_a_ray_count_target_needs_no_ssim(tmp_path, capsys):
    """``calibrate --target-rays`` measures no image: a 6² view is calibrated."""
    assert main(["calibrate", "builtin:sphere", "--target-rays", "60", "--size", "6",
                 "--iterations", "2", "--quiet", "--out", str(tmp_path / "c.json")]) == 0


@pytest.mark.parametrize("vector", ["1e308,1e308,1e308", "0,2e12,0", "nan,1,1"])
def test_a_camera_beyond_any_scene_is_refused_by_the_parser(vector, capsys):
    """``--eye 1e308,...`` printed NumPy's overflow warnings as notes and wrote an empty
    image, exit 0; a coordinate must be finite and within ``MAX_COORDINATE``."""
    message = _refused_by_the_parser(["render", "builtin:sphere", "--eye", vector, "--target",
                                      "0,0,0", "--out", "unused.png"], capsys)
    assert "argument --eye: expected finite coordinates within ±1e+12 voxels" in message
    assert "overflow" not in message


def test_an_image_the_machine_cannot_hold_is_refused_before_it_renders(tmp_path, capsys,
                                                                       monkeypatch):
    """``render --size 16384`` (within the option's range) ran for minutes on a 23 GiB
    machine and was killed for memory, exit 137 without a word. On a machine said to hold
    2 GiB a 4096² render (about 3 GiB) is refused, and a 512² one (48 MiB) renders."""
    from voxfield import memory

    monkeypatch.setattr(memory, "physical_memory", lambda: 2 * 2**30)
    out = tmp_path / "big.png"
    assert main(["render", "builtin:sphere", "--size", "4096", "--out", str(out)]) == 2
    message = one_error_line(capsys)
    assert "--size 4096: a 4096×4096 render needs about 3.0 GiB" in message
    assert "this machine's 2.0 GiB" in message and not out.exists()
    assert main(["render", "builtin:sphere", "--size", "512", "--quiet", "--out", str(out)]) == 0


def _camera_takes_side(side: int) -> bool:
    try:
        Camera.look_at((0, 0, 5), (0, 0, 0), width=side)
    except VoxfieldError:
        return False
    return True


def _bake_takes_side(side: int) -> bool:
    try:
        BakeOptions(resolution=side)
    except VoxfieldError:
        return False
    return True


@pytest.mark.parametrize("argv, option, library_takes", [
    (["study", "resolution"], "--sizes", _camera_takes_side),
    (["study", "probe-resolution"], "--resolutions", _bake_takes_side),
    (["study", "probes"], "--resolutions", _bake_takes_side),
])
def test_a_study_s_side_list_takes_exactly_the_sides_the_library_takes(
        argv, option, library_takes, tmp_path, capsys, monkeypatch):
    """A side no camera or bake takes (``--sizes 99999999``) was refused only after the scene
    loaded (minutes, where the kernels compiled first); the parser refuses it now, and a side
    the library takes goes on to the missing scene file. The machine is said to hold 1 TiB,
    so that no side here meets the memory refusal."""
    from voxfield import memory

    monkeypatch.setattr(memory, "physical_memory", lambda: 2**40)
    missing = str(tmp_path / "none.vox")
    for side in [16, 64, 65, 2048, 2050, 16384, 16385, 99999999]:
        sides = f"32,{side}" if side != 32 else "16,32"
        expected = library_takes(side) and library_takes(32)
        full = [*argv, missing, option, sides, "--out", str(tmp_path / "out")]
        if expected:
            assert main(full) == 2
            assert "none.vox" in one_error_line(capsys), side
        else:
            err = _refused_by_the_parser(full, capsys)
            assert option in err and str(side) in err, err
        assert not (tmp_path / "out").exists()


def test_a_resolution_study_too_large_for_the_machine_is_refused_before_its_scene(
        tmp_path, capsys, monkeypatch):
    from voxfield import memory

    monkeypatch.setattr(memory, "physical_memory", lambda: 2 * 2**30)
    assert main(["study", "resolution", str(tmp_path / "none.vox"), "--sizes", "64,4096",
                 "--out", str(tmp_path / "out")]) == 2
    message = one_error_line(capsys)
    assert message.startswith("voxfield: error: --sizes 4096: a 4096×4096 render needs"), message


def test_a_probe_study_too_large_for_the_machine_is_refused_before_its_bakes(
        tmp_path, capsys, monkeypatch):
    """A 200³ probe-count grid baked until the machine killed the study for memory, without
    a word; ``bake`` refused the same grid in two seconds. On a machine said to hold 2 GiB,
    40³ probes of 32² texels (about 3 GiB finished) are refused."""
    from voxfield import memory
    from voxfield.studies import probe_study

    monkeypatch.setattr(memory, "physical_memory", lambda: 2 * 2**30)
    monkeypatch.setattr(probe_study, "bake_probes", None)  # must not be reached
    out = tmp_path / "study"
    assert main(["study", "probes", "builtin:pillars", "--resolutions", "8,16",
                 "--probe-counts", "2x2x2,40x40x40", "--count-resolution", "32",
                 "--size", "16", "--quiet", "--out", str(out)]) == 2
    assert one_error_line(capsys).startswith(
        "voxfield: error: 64,000 probes of 32² texels: assembling the finished set")
    assert not out.exists()


@pytest.mark.parametrize("side", ["7", "1", "4096", "8,16"])
def test_a_probe_study_s_count_resolution_is_checked_by_the_parser(side, tmp_path, capsys):
    """``--count-resolution 7`` was refused once the scene had loaded; ``--resolutions 7``
    by the parser, with the bake's rule, which both now share."""
    err = _refused_by_the_parser(["study", "probes", str(tmp_path / "none.vox"),
                                  "--count-resolution", side], capsys)
    assert "--count-resolution" in err and (side in err or "one map side" in err), err
