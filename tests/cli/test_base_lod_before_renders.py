"""A --base-lod the scene's octree has no level for is refused before the first render.

The renderers refused it, but only once reached: a sweep or study of a small scene (a
one-voxel .npz has depth 1) rendered its 4×4 reference first, which takes minutes on a
large view, and then failed on the default --base-lod 2."""

from __future__ import annotations

import types

import pytest

from cli_output import one_error_line
from voxfield.cli import cmd_calibrate, cmd_compare, cmd_study, cmd_sweep
from voxfield.cli.main import main

SHALLOW = types.SimpleNamespace(depth=1, name="one_voxel")


def _never(*args, **kwargs):
    raise AssertionError("rendered before refusing the base LOD")


@pytest.mark.parametrize(("module", "runner", "argv"), [
    (cmd_sweep, "run_sweep", ["sweep"]),
    (cmd_compare, "run_compare", ["compare"]),
    (cmd_calibrate, "calibrate_threshold", ["calibrate", "--target-rays", "100"]),
    (cmd_study, "run_threshold_study", ["study", "thresholds"]),
    (cmd_study, "run_lighting_study", ["study", "lighting"]),
    (cmd_study, "run_curves_study", ["study", "curves"]),
    (cmd_study, "run_normalisation_study", ["study", "normalisation"]),
])
def test_a_base_lod_past_the_octree_is_refused_before_rendering(
        monkeypatch, capsys, tmp_path, module, runner, argv):
    monkeypatch.setattr(module, "open_octree", lambda *a, **k: SHALLOW)
    if hasattr(module, "check_measured_channel"):  # it reads a real octree's colours
        monkeypatch.setattr(module, "check_measured_channel", lambda *a: None)
    monkeypatch.setattr(module, runner, _never)
    monkeypatch.setattr(cmd_study, "bake_sun_lighting", _never)
    out = tmp_path / ("out.json" if module is cmd_calibrate else "out")
    assert main([*argv, "scene.npz", "--out", str(out), "--quiet"]) == 2
    line = one_error_line(capsys)
    assert "--base-lod 2" in line and "'one_voxel'" in line and "0..1" in line
    assert not out.exists()
