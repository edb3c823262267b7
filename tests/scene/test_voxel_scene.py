"""VoxelScene invariants, composition, colour transfer functions and the scene loader dispatch."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import DataNotFoundError, SceneFormatError, VoxfieldError
from voxfield.scene.builtin import BUILTIN_SCENES, builtin_scene, cornell, menger, pillars, sphere
from voxfield.scene.loaders import load_scene
from voxfield.scene.npz_io import load_scene_npz, save_scene
from voxfield.scene.shadow_box import shadow_box
from voxfield.scene.voxel_scene import VoxelScene, compose, linear_to_srgb, srgb_to_linear
from voxfield.svo import build_octree


def cube(offset=(0, 0, 0), n=2, color=(1.0, 0.0, 0.0)):
    coords = np.argwhere(np.ones((n, n, n), bool)) + np.asarray(offset)
    return VoxelScene(coords, np.tile(color, (len(coords), 1)))


def test_validation_rejects_bad_arrays():
    with pytest.raises(VoxfieldError, match="N×3"):
        VoxelScene(np.zeros((4, 2), int), np.zeros((4, 3)))
    with pytest.raises(VoxfieldError, match="integers"):
        VoxelScene(np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(VoxfieldError, match="match"):
        VoxelScene(np.zeros((2, 3), int), np.zeros((3, 3)))
    with pytest.raises(VoxfieldError, match="NaN"):
        VoxelScene(np.zeros((1, 3), int), np.full((1, 3), np.nan))


def test_albedo_outside_zero_to_one_is_refused_with_a_hint_for_8_bit_colours():
    """8-bit colours (0..255) were built as white without a word; light and emission, which
    may exceed 1, are kept."""
    coords = np.array([[0, 0, 0], [1, 0, 0]])
    with pytest.raises(VoxfieldError, match=r"color is linear albedo in \[0, 1\], got values "
                       r"0\.\.255 \(8-bit sRGB\? give voxfield\.scene\.srgb_to_linear"):
        VoxelScene(coords, np.array([[255, 128, 0], [0, 0, 0]], np.uint8))
    with pytest.raises(VoxfieldError, match=r"got values -0\.1\.\.0\.5$"):
        VoxelScene(coords, [[-0.1, 0.5, 0.5], [0.0, 0.0, 0.0]])
    bright = VoxelScene(coords, np.ones((2, 3)), emission=np.full((2, 3), 40.0),
                        channels={"noon": np.full((2, 3), 3.5)})
    assert bright.emission.max() == 40.0 and bright.channels["noon"].max() == 3.5


def test_dedupe_keeps_the_last_voxel_given():
    scene = VoxelScene(np.array([[0, 0, 0], [1, 1, 1], [0, 0, 0]]),
                       np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]]))
    d = scene.dedupe()
    assert len(d) == 2
    assert d.color[(d.coords == 0).all(axis=1)].tolist() == [[0, 0, 1]]


def test_compose_places_scenes_at_offsets_and_later_parts_win():
    a = cube(color=(1, 0, 0))
    b = VoxelScene(np.array([[0, 0, 0]]), np.array([[0, 1, 0]]), emission=np.ones((1, 3)))
    world = compose([(a, (0, 0, 0)), (b, (1, 1, 1)), (a, (10, 0, 0))])
    assert len(world) == 16
    lo, hi = world.bounds
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [12, 2, 2]
    at = world.color[(world.coords == [1, 1, 1]).all(axis=1)]
    assert at.tolist() == [[0, 1, 0]]
    assert world.emission is not None and world.emission.sum() == 3  # only b emits


def test_srgb_transfer_round_trips_and_hits_known_points():
    x = np.linspace(0, 1, 101, dtype=np.float32)
    assert np.allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-6)
    assert np.isclose(srgb_to_linear(np.float32(0.5)), 0.2140, atol=1e-4)


def test_menger_sponge_has_twenty_to_the_level_voxels():
    for level in (1, 2, 3):
        assert len(menger(level)) == 20**level


def test_every_builtin_builds_a_nonempty_scene():
    for name in BUILTIN_SCENES:
        scene = builtin_scene(name)
        assert len(scene) > 0 and len(scene.dedupe()) == len(scene)
    with pytest.raises(VoxfieldError, match="choose one of"):
        builtin_scene("nope")


# pillars(32.5) was a NumPy broadcasting error, menger(2.0) a TypeError, sphere(True) empty.
@pytest.mark.parametrize(("make", "message"), [
    (lambda: pillars(32.5), "pillars scene's size must be an integer ≥ 8"),
    (lambda: pillars(4), "pillars scene's size must be an integer ≥ 8"),
    (lambda: menger(2.0), "menger level must be an integer in 1..5"),
    (lambda: menger(6), "menger level must be an integer in 1..5"),
    (lambda: sphere(True), "sphere radius must be an integer ≥ 1"),
    (lambda: cornell(16.0), "Cornell box's size must be an integer ≥ 8"),
    (lambda: shadow_box(256.0), "multiple of 32"),
])
def test_builtin_sizes_must_be_whole(make, message):
    with pytest.raises(VoxfieldError, match=message):
        make()


def test_scene_npz_round_trip_and_loader_dispatch(tmp_path):
    scene = VoxelScene(np.array([[0, 1, 2]]), np.array([[0.1, 0.2, 0.3]]),
                       emission=np.array([[1.0, 1.0, 1.0]]), channels={"noon": np.ones((1, 3))})
    path = save_scene(scene, tmp_path / "s.npz")
    for loaded in (load_scene_npz(path), load_scene(str(path))):
        assert np.array_equal(loaded.coords, scene.coords)
        assert np.array_equal(loaded.color, scene.color)
        assert set(loaded.channels) == {"noon"} and loaded.emission is not None
    with pytest.raises(DataNotFoundError):
        load_scene(str(tmp_path / "missing.vox"))
    (tmp_path / "x.stl").write_text("solid")
    with pytest.raises(SceneFormatError, match="unknown scene format"):
        load_scene(str(tmp_path / "x.stl"))
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(SceneFormatError):
        load_scene(str(tmp_path / "bad.npz"))


def test_dedupe_works_across_the_full_coordinate_range():
    far = 2**21 - 1
    scene = VoxelScene(np.array([[0, 0, 0], [far, far, far], [0, 0, 0]]), np.eye(3))
    d = scene.dedupe()
    assert len(d) == 2 and d.color[(d.coords == 0).all(axis=1)].tolist() == [[0, 0, 1]]


def test_coordinates_too_far_to_subtract_are_refused():
    """±2^62 wrapped round when subtracted (a misleading "duplicate voxels" at build, a
    ValueError from dedupe), and uint64 coordinates past 2^63 became negative ones."""
    from voxfield.scene.voxel_scene import MAX_COORDINATE

    for coords in (np.array([[-(2**62), 0, 0], [2**62, 0, 0]]),
                   np.array([[2**63 + 5, 0, 0]], np.uint64)):
        with pytest.raises(VoxfieldError, match="within ±2"):
            VoxelScene(coords, np.full((len(coords), 3), 0.5))
    edge = VoxelScene(np.array([[-MAX_COORDINATE, 0, 0], [MAX_COORDINATE, 0, 0],
                                [MAX_COORDINATE, 0, 0]]), np.eye(3))
    assert len(edge.dedupe()) == 2
    with pytest.raises(VoxfieldError, match="at most"):
        build_octree(edge.dedupe())


@pytest.mark.parametrize("offset, words", [
    ((-1.7, 0, 0), "moves whole voxels"), ((0.5, 0, 0), "moves whole voxels"),
    ((np.nan, 0, 0), "finite"), ((1e20, 0, 0), r"within ±2\^61"), (("3", 0, 0), "three whole"),
    ((1, 2), "three whole"),
])
def test_an_offset_that_is_not_whole_voxels_is_refused(offset, words):
    """A fraction was truncated toward zero (-1.7 moved by -1, 0.5 not at all), a NaN or a
    huge offset raised NumPy's or Python's own errors, and a string was taken."""
    scene = VoxelScene(np.array([[1, 2, 3]]), np.full((1, 3), 0.5))
    with pytest.raises(VoxfieldError, match=words):
        scene.translated(offset)
    with pytest.raises(VoxfieldError, match=words):
        compose([(scene, offset)])


@pytest.mark.parametrize("parts", [["scene"], [("scene",)], [("scene", (0, 0, 0), 1)],
                                   [((0, 0, 0), "scene")]])
def test_compose_takes_scene_offset_pairs_and_says_so(parts):
    """``compose([scene])`` raised Python's "cannot unpack non-iterable VoxelScene"."""
    scene = VoxelScene(np.array([[1, 2, 3]]), np.full((1, 3), 0.5))
    given = [tuple(scene if item == "scene" else item for item in part)
             if isinstance(part, tuple) else scene for part in parts]
    with pytest.raises(VoxfieldError, match=r"compose takes \(scene, offset\) pairs; part 0"):
        compose(given)


def test_a_whole_offset_of_any_number_type_moves_the_voxels():
    scene = VoxelScene(np.array([[1, 2, 3]]), np.full((1, 3), 0.5))
    for offset in ((2, 0, -3), (2.0, 0.0, -3.0), np.array([2, 0, -3], np.int16)):
        assert scene.translated(offset).coords.tolist() == [[3, 2, 0]]


@pytest.mark.parametrize("field", ["emission", "channel"])
def test_negative_light_is_refused_when_the_scene_is_made(field):
    """Such a scene built and saved, and its octree file was then refused on load."""
    coords = np.zeros((1, 3), np.int32)
    light = np.array([[0.5, -1.0, 0.0]], np.float32)
    given = {"emission": light} if field == "emission" else {"channels": {"noon": light}}
    with pytest.raises(VoxfieldError, match="is light, never negative, got values down to -1"):
        VoxelScene(coords, np.full((1, 3), 0.5, np.float32), **given)
    ok = {k: (np.abs(v) if k == "emission" else {"noon": np.abs(light) * 4})
          for k, v in given.items()}
    VoxelScene(coords, np.full((1, 3), 0.5, np.float32), **ok)  # bright light is fine
