"""Without --out, sweep writes where its help says and as the other studies do:
out/sweep_SCENE, SCENE the built-in's or recipe's name or the file's stem, path-safe. It
wrote out/sweep_builtin_sphere beside compare's out/compare_sphere, and kept a file's spaces."""

from __future__ import annotations

import types
from pathlib import Path

import pytest

from voxfield.cli import cmd_compare, cmd_sweep
from voxfield.cli.main import main


@pytest.mark.parametrize(("scene", "folder"), [
    ("builtin:sphere", "sphere"), ("terrain:desert", "desert"),
    ("/data/my scene.vox", "my_scene"),
])
def test_sweep_and_compare_pick_the_same_folder_name(monkeypatch, scene, folder):
    written = {}
    octree = types.SimpleNamespace(depth=6, name="s")
    for module, runner in ((cmd_sweep, "run_sweep"), (cmd_compare, "run_compare")):
        monkeypatch.setattr(module, "open_octree", lambda args: octree)
        monkeypatch.setattr(module, "check_measured_channel", lambda *a: None)
        monkeypatch.setattr(module, "study_camera", lambda args, octree: None)
        monkeypatch.setattr(module, runner, lambda o, v, out, _m=module, **k:
                            written.setdefault(_m.__name__, Path(out)))
    for command in ("sweep", "compare"):
        assert main([command, scene, "--quiet"]) == 0
    assert written["voxfield.cli.cmd_sweep"] == Path("out") / f"sweep_{folder}"
    assert written["voxfield.cli.cmd_compare"] == Path("out") / f"compare_{folder}"
