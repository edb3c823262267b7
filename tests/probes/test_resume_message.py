"""Resuming a bake into a folder baked with other settings: the refusal reads as English and
names every difference."""

from __future__ import annotations

import pytest

from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_folder import ProbeSetMismatchError
from voxfield.probes.probe_set import BakeOptions
from voxfield.scene.builtin import cornell
from voxfield.svo.build import build_octree

OPTIONS = BakeOptions(resolution=4, renderer="lod", lod=0)


def test_a_mismatched_folder_says_what_differs_in_one_sentence(tmp_path, octree):
    lo, hi = octree.voxel_bounds
    grid = ProbeGrid.fit(lo, hi, (1, 1, 1))
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    other_grid = ProbeGrid.fit(lo, hi, (2, 1, 1))
    other_scene = build_octree(cornell(12))
    tail = "; use another --out, or --fresh to discard them"
    cases = [
        (octree, grid, BakeOptions(resolution=8, renderer="lod", lod=0),
         "with other bake options (resolution)"),
        (octree, other_grid, OPTIONS, "on another probe grid"),
        (other_scene, grid, OPTIONS, "from another scene (or colour channel)"),
        (octree, other_grid, BakeOptions(resolution=8, renderer="lod", lod=1),
         "on another probe grid and with other bake options (lod, resolution)"),
        (other_scene, other_grid, BakeOptions(resolution=8, renderer="lod", lod=0),
         "from another scene (or colour channel), on another probe grid and with other "
         "bake options (resolution)"),
    ]
    for scene, probe_grid, options, what in cases:
        with pytest.raises(ProbeSetMismatchError) as exc:
            bake_to_folder(scene, probe_grid, options, tmp_path, scheduler="serial")
        assert str(exc.value) == f"{tmp_path} holds probes baked {what}{tail}"
