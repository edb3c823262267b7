"""Which ``.npz`` a scene argument is (``scene.loaders.npz_kind``): voxfield's own files that
are no scene are refused by name, where any ``.npz`` without octree or scene arrays was read
as a DEM (a probe file's distance map became a terrain without a word)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import voxfield.error_table
from cli_output import one_error_line
from voxfield.cli import main
from voxfield.errors import SceneFormatError
from voxfield.scene.loaders import npz_kind
from voxfield.svo.open import open_octree

TABLES = Path(voxfield.error_table.__file__).parent / "data"


def probe_file(path: Path) -> Path:
    """One probe's file as a bake writes it: three maps and its record."""
    np.savez_compressed(path, radiance=np.zeros((8, 8, 3), np.float16),
                        distance=np.full((8, 8), 3.5, np.float32),
                        normal=np.zeros((8, 8, 2), np.int16),
                        record=np.array(json.dumps({"file": path.name})))
    return path


def test_a_probe_file_is_refused_as_a_scene_not_read_as_a_terrain(tmp_path):
    path = probe_file(tmp_path / "probe_00000.npz")
    with pytest.raises(SceneFormatError, match="one probe of a baked probe set"):
        open_octree(str(path))


@pytest.mark.parametrize("name", ["error_table.npz", "lighting_error_table.npz"])
def test_an_error_table_is_refused_as_a_scene_naming_what_it_is(name):
    with pytest.raises(SceneFormatError, match=r"a voxfield error table \(voxfield-"):
        open_octree(str(TABLES / name))


def test_the_command_line_says_so_in_one_line(tmp_path, capsys):
    path = probe_file(tmp_path / "probe_00003.npz")
    assert main(["info", str(path)]) == 2
    assert "not a scene" in one_error_line(capsys)


def test_an_octree_file_missing_its_arrays_is_still_an_octree(tmp_path):
    """Its header names the octree format: the octree reader, not the DEM reader, says what
    it lacks."""
    path = tmp_path / "damaged.npz"
    header = json.dumps({"format": "voxfield-octree", "version": 1}).encode()
    np.savez(path, header=np.frombuffer(header, np.uint8), level_offsets=np.zeros(2))
    assert npz_kind(path) == "octree"


def test_a_dem_with_an_array_named_header_is_still_a_dem(tmp_path):
    path = tmp_path / "dem.npz"
    np.savez(path, elevation=np.arange(64.0).reshape(8, 8), header=np.arange(5))
    assert npz_kind(path) == "dem"
    np.savez(path, elevation=np.arange(64.0).reshape(8, 8),
             header=np.frombuffer(b'["a list"]', np.uint8))
    assert npz_kind(path) == "dem"
