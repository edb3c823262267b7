"""Image files: EXR round-trips float32 exactly, PNG is sRGB-encoded, writes are atomic."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from voxfield.errors import VoxfieldError
from voxfield.render.image_io import load_exr, save_exr, save_png


def test_exr_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.random((7, 5, 3)).astype(np.float32)
    z = rng.random((7, 5)).astype(np.float32) * 100
    z[0, 0] = np.inf
    save_exr({"RGB": rgb, "Z": z}, tmp_path / "a.exr")
    back = load_exr(tmp_path / "a.exr")
    assert np.array_equal(back["RGB"], rgb) and np.array_equal(back["Z"], z)


def test_png_is_srgb_encoded(tmp_path):
    linear = np.full((2, 2, 3), 0.2158605, np.float32)  # sRGB 128/255
    save_png(linear, tmp_path / "g.png")
    assert np.all(np.asarray(Image.open(tmp_path / "g.png")) == 128)
    assert not list(tmp_path.glob("*.tmp")) and len(list(tmp_path.iterdir())) == 1


def test_png_rejects_bad_shapes(tmp_path):
    with pytest.raises(VoxfieldError):
        save_png(np.zeros((2, 2, 5)), tmp_path / "x.png")
