"""Saved voxel scenes (``.npz``) written by other tools: repeated positions and channel names
an octree cannot keep are met at the file, which is named (``voxfield.scene.npz_io``)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from voxfield.cli import main
from voxfield.errors import SceneFormatError, VoxfieldError
from voxfield.scene.loaders import load_scene
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

#: Five voxels, two positions listed twice: (0, 0, 0) three times, (1, 1, 1) once.
COORDS = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 1, 1], [0, 0, 0]], np.int32)
COLOR = np.linspace(0.1, 0.9, 15, dtype=np.float32).reshape(5, 3)


def test_repeated_positions_are_merged_with_a_note_the_last_listed_kept(tmp_path):
    """They reached the octree build, whose error named no file and told the user to call
    ``.dedupe()``; the other readers merge overlaps, the last listed winning."""
    path = tmp_path / "repeats.npz"
    np.savez(path, coords=COORDS, color=COLOR, channel_noon=COLOR[::-1])
    with pytest.warns(UserWarning, match=re.escape(
            f"{path}: 2 of its 5 voxels repeat positions listed earlier in the file; the last "
            "listed at each position was kept")):
        scene = load_scene(str(path))
    last = {}  # position -> row of the last voxel listed there, worked out row by row
    for row, position in enumerate(map(tuple, COORDS.tolist())):
        last[position] = row
    assert len(scene) == len(last) == 3
    for coords, color, noon in zip(scene.coords, scene.color, scene.channels["noon"],
                                   strict=True):
        row = last[tuple(coords.tolist())]
        assert color.tolist() == COLOR[row].tolist()
        assert noon.tolist() == COLOR[::-1][row].tolist()
    assert build_octree(scene).voxel_count == 3


@pytest.mark.filterwarnings("default::UserWarning")  # the CLI prints it as a note
def test_the_command_line_builds_a_scene_file_with_repeats(tmp_path, capsys):
    path = tmp_path / "repeats.npz"
    np.savez(path, coords=COORDS, color=COLOR)
    assert main(["info", str(path)]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"voxfield: note: {path}: 2 of its 5 voxels repeat positions")
    assert "dedupe" not in err


def test_a_scene_without_repeats_loads_without_a_note(tmp_path):
    path = tmp_path / "plain.npz"
    np.savez(path, coords=COORDS[:2], color=COLOR[:2])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(load_scene(str(path))) == 2


def test_a_scene_built_in_code_with_repeats_is_refused_with_their_count():
    scene = VoxelScene(COORDS, COLOR, name="mine")
    repeats = len(COORDS) - len(np.unique(COORDS, axis=0))
    with pytest.raises(VoxfieldError, match=rf"scene 'mine' holds {repeats:,} duplicate "
                       r"voxel\(s\), at positions already taken; its \.dedupe\(\) keeps the "
                       "last at each"):
        build_octree(scene)


@pytest.mark.parametrize("name", ["a b", "color", "x" * 65])
def test_a_channel_name_an_octree_cannot_keep_is_refused_naming_the_file(tmp_path, name):
    """``'a b'`` passed the loader and failed the build with a message naming no file."""
    path = tmp_path / "channels.npz"
    np.savez(path, coords=COORDS[:2], color=COLOR[:2], **{f"channel_{name}": COLOR[:2]})
    with pytest.raises(SceneFormatError, match=re.escape(f"{path}: channel ")):
        load_scene(str(path))
    with pytest.raises(VoxfieldError, match="channel"):  # the scene's own rule, in code too
        VoxelScene(COORDS[:2], COLOR[:2], channels={name: COLOR[:2]})


def test_the_command_line_names_the_file_with_the_bad_channel(tmp_path, capsys):
    path = tmp_path / "channels.npz"
    np.savez(path, coords=COORDS[:2], color=COLOR[:2], **{"channel_a b": COLOR[:2]})
    for command in (["info", str(path)], ["render", str(path), "--size", "8", "--quiet",
                                          "--out", str(tmp_path / "x.png")]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err == (f"voxfield: error: {path}: channel name 'a b' must be 1-64 letters, "
                       "digits, '_' or '-'\n")
    assert not (tmp_path / "x.png").exists()
