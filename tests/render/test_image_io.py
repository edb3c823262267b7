"""Image files: EXR round-trips float32 exactly, PNG is sRGB-encoded, writes are atomic."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from voxfield.errors import VoxfieldError
from voxfield.render.image_io import load_exr, save_exr, save_png, shade_for_display
from voxfield.svo import open_octree, save_octree


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


@pytest.mark.parametrize(("save", "name", "suffix"), [
    (lambda path: save_png(np.zeros((2, 2, 3)), path), "a.jpg", ".png"),
    (lambda path: save_exr({"Z": np.zeros((2, 2))}, path), "a.png", ".exr"),
    (lambda path: save_octree(open_octree("builtin:sphere"), path), "o.vox", ".npz"),
])
def test_a_writer_refuses_a_name_of_another_format_and_writes_nothing(save, name, suffix,
                                                                       tmp_path):
    """A PNG saved as ``a.jpg`` or an octree as ``o.vox`` is misread by every reader that
    goes by the name (``voxfield render o.vox`` parsed the octree as MagicaVoxel)."""
    with pytest.raises(VoxfieldError, match=rf"{name}: save_\w+ writes \{suffix} files"):
        save(tmp_path / name)
    assert list(tmp_path.iterdir()) == []
    save(tmp_path / f"upper{suffix.upper()}")  # the case of the suffix does not matter
    assert [p.name for p in tmp_path.iterdir()] == [f"upper{suffix.upper()}"]


def test_display_shading_darkens_faces_by_their_normal_and_keeps_the_rest():
    """The key light scales each face's colour by at most 1, by a factor that depends on its
    normal; a pixel without a normal (a miss, a probe's environment answer) keeps its own."""
    rng = np.random.default_rng(3)
    image = rng.random((6, 4, 3)).astype(np.float32)
    axes = np.eye(3)[rng.integers(0, 3, (6, 4))] * rng.choice([-1.0, 1.0], (6, 4, 1))
    axes[0] = 0.0  # the first row has no normal
    shaded = shade_for_display(SimpleNamespace(image=image, normal=axes.astype(np.float32)))
    np.testing.assert_array_equal(shaded[0], image[0])
    factor = shaded[1:] / image[1:]
    assert np.all(factor <= 1.0 + 1e-6) and np.all(factor >= 0.35 - 1e-6)
    np.testing.assert_allclose(factor, factor[..., :1].repeat(3, axis=-1), rtol=1e-5)
    normals, which = np.unique(axes[1:].reshape(-1, 3), axis=0, return_inverse=True)
    per_pixel = factor[..., 0].reshape(-1)
    for k in range(len(normals)):  # one factor per normal, whatever the colour
        np.testing.assert_allclose(per_pixel[which.reshape(-1) == k],
                                   per_pixel[which.reshape(-1) == k][0], rtol=1e-5)
    assert len(np.unique(per_pixel.round(5))) > 1


def test_an_empty_or_inconsistent_image_is_refused_in_one_line(tmp_path):
    """PIL's "cannot write empty image", and an EXR error naming the temporary file."""
    with pytest.raises(VoxfieldError, match="shape"):
        save_png(np.zeros((0, 0, 3)), tmp_path / "empty.png")
    with pytest.raises(VoxfieldError, match="no channels"):
        save_exr({}, tmp_path / "none.exr")
    with pytest.raises(VoxfieldError, match=r"RGB \(2, 2, 3\), Z \(3, 2\)"):
        save_exr({"RGB": np.zeros((2, 2, 3)), "Z": np.zeros((3, 2))}, tmp_path / "odd.exr")
    assert list(tmp_path.iterdir()) == []


def test_a_png_says_how_many_pixels_were_not_a_number(tmp_path):
    """NaN is written black, as a miss would be; the warning tells the two apart. Infinite
    values clamp as any bright or dark value does, without a word."""
    image = np.full((4, 5, 3), 0.5, np.float32)
    image[1, 2, 0] = np.nan
    image[3, 4] = np.nan
    image[0, 0] = np.inf
    with pytest.warns(UserWarning, match=r"^2 of 20 pixels are not a number \(NaN\)"):
        save_png(image, tmp_path / "nan.png")
    written = np.asarray(Image.open(tmp_path / "nan.png"))
    assert written[1, 2, 0] == 0 and np.all(written[3, 4] == 0)
    assert np.all(written[0, 0] == 255) and written[1, 2, 1] == written[2, 2, 1] > 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        save_png(np.nan_to_num(image, nan=0.25), tmp_path / "finite.png")
