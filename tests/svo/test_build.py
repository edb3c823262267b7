"""Octree build against a brute-force level grid, plus file round trips and invariants."""

from __future__ import annotations

import json
import pickle
import re
from dataclasses import replace

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.errors import OctreeFormatError, VoxfieldError
from voxfield.kernels.node_descriptor import FIRST_CHILD_SHIFT, SOLID_BIT
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree, load_octree, morton_encode, save_octree
from voxfield.svo.io import validate_octree
from voxfield.svo.octree import Octree


def _brute_force_levels(scene: VoxelScene, depth: int):
    """Per LOD: dict from node corner (in node units) to mean of its children's colours."""
    pairs = zip(scene.coords, scene.color, strict=True)
    levels = [{tuple(c): col.astype(np.float64) for c, col in pairs}]
    for _ in range(depth):
        groups: dict[tuple, list] = {}
        for key, col in levels[-1].items():
            groups.setdefault(tuple(k >> 1 for k in key), []).append(col)
        levels.append({k: np.mean(v, axis=0) for k, v in groups.items()})
    return levels


def test_morton_code_interleaves_x_y_z():
    coords = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 5, 6], [2**20, 0, 0]])
    got = morton_encode(coords)
    expected = []
    for x, y, z in coords:
        code = 0
        for bit in range(21):
            code |= ((int(x) >> bit) & 1) << (3 * bit)
            code |= ((int(y) >> bit) & 1) << (3 * bit + 1)
            code |= ((int(z) >> bit) & 1) << (3 * bit + 2)
        expected.append(code)
    assert got.tolist() == expected


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_levels_match_brute_force_occupancy_and_means(seed):
    scene = random_scene(seed, n=300, size=13)
    octree = build_octree(scene, colour_storage="float32")
    normalized = scene.normalized()
    levels = _brute_force_levels(normalized, octree.depth)
    for lod, expected in enumerate(levels):
        level = octree.depth - lod
        sl = octree.level_slice(level)
        coords = octree.node_coords(level)
        got = {tuple(c): col for c, col in zip(coords, octree.color[sl], strict=True)}
        assert set(got) == set(expected)
        for key, col in expected.items():
            np.testing.assert_allclose(got[key], col, rtol=1e-5, atol=1e-6)
        narrow = octree.node_coords(level, np.int32)
        assert narrow.dtype == np.int32 and np.array_equal(narrow, coords)


def test_child_pointers_and_masks_describe_children():
    octree = build_octree(random_scene(3))
    validate_octree(octree)
    coords = octree.all_node_coords()
    for level in range(octree.depth):
        sl = octree.level_slice(level)
        for node in range(sl.start, sl.stop):
            mask = int(octree.child_mask[node])
            first = int(octree.first_child[node])
            for octant in range(8):
                if mask >> octant & 1:
                    child = first + bin(mask & ((1 << octant) - 1)).count("1")
                    bits = [octant & 1, octant >> 1 & 1, octant >> 2]
                    expected = coords[node] * 2 + bits
                    assert coords[child].tolist() == expected.tolist()


def test_scene_is_moved_to_the_origin_and_depth_covers_extent():
    scene = VoxelScene(np.array([[-5, 10, 3], [4, 10, 3]]), np.ones((2, 3)))
    octree = build_octree(scene)
    assert octree.scene_origin.tolist() == [-5, 10, 3]
    assert octree.depth == 4  # extent 10 needs a 16^3 root
    lo, hi = octree.voxel_bounds
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [10, 1, 1]


def test_single_voxel_still_has_a_root_above_it():
    octree = build_octree(VoxelScene(np.array([[7, 7, 7]]), np.ones((1, 3))))
    assert octree.depth == 1 and octree.nodes_per_level() == [1, 1]


def test_bad_scenes_are_rejected():
    with pytest.raises(VoxfieldError, match="no voxels"):
        build_octree(VoxelScene(np.zeros((0, 3), int), np.zeros((0, 3))))
    dup = VoxelScene(np.array([[1, 1, 1], [1, 1, 1]]), np.ones((2, 3)))
    with pytest.raises(VoxfieldError, match="duplicate"):
        build_octree(dup)
    # A channel named for the albedo or the emission replaced it without a word: the
    # scene refuses it when made (and the build a scene that slips past that).
    for name, words in (("color", "is the albedo"), ("emission", "is the emission")):
        with pytest.raises(VoxfieldError, match=words):
            VoxelScene(np.array([[0, 0, 0]]), np.full((1, 3), 0.5),
                       emission=np.zeros((1, 3)), channels={name: np.ones((1, 3))})
        scene = VoxelScene(np.array([[0, 0, 0]]), np.full((1, 3), 0.5),
                           emission=np.zeros((1, 3)), channels={"fine": np.ones((1, 3))})
        object.__setattr__(scene, "channels", {name: scene.channels["fine"]})
        with pytest.raises(VoxfieldError, match=words):
            build_octree(scene)


def test_recolouring_checks_a_colour_for_every_node():
    """A short colour array rendered memory past its end (values of 1e33, NaN pixels)."""
    octree = build_octree(random_scene(3, 200))
    n, inner = octree.node_count, octree.inner_count
    for attributes in ({"color": np.zeros((1, 3), np.float32)},
                       {"color": np.zeros((n, 3), np.float64)},
                       {"color": np.zeros((n,), np.uint8)},
                       {"lit": [[0.0, 0.0, 0.0]] * n}):
        with pytest.raises(VoxfieldError, match="attribute"):
            octree.recoloured(attributes=attributes)
    with pytest.raises(VoxfieldError, match="directional colours"):
        octree.recoloured(facing=np.zeros((inner, 6, 3), np.uint8))
    same = octree.recoloured(attributes={"color": np.zeros((n, 3), np.float32),
                                         "lit": np.zeros(n, np.uint32)})
    assert same.node_count == n


def test_save_load_round_trip(tmp_path):
    scene = random_scene(4)
    scene = VoxelScene(scene.coords, scene.color, emission=scene.color * 2, name="r")
    octree = build_octree(scene)
    path = save_octree(octree, tmp_path / "r.npz")
    loaded = load_octree(path)
    assert loaded.depth == octree.depth and loaded.name == "r"
    for name in ("descriptors", "level_offsets", "voxel_box", "scene_origin"):
        assert np.array_equal(getattr(loaded, name), getattr(octree, name))
    assert set(loaded.attributes) == {"color", "emission"}
    assert np.array_equal(loaded.attributes["emission"], octree.attributes["emission"])
    assert not list(tmp_path.glob("*.tmp"))
    # built again, the same scene writes the same bytes (no build time in the header)
    again = save_octree(build_octree(scene), tmp_path / "again.npz")
    assert again.read_bytes() == path.read_bytes()


def test_corrupt_octree_files_give_clear_errors(tmp_path):
    octree = build_octree(random_scene(5))
    good = save_octree(octree, tmp_path / "good.npz").read_bytes()
    with pytest.raises(OctreeFormatError, match="no such"):
        load_octree(tmp_path / "missing.npz")
    with pytest.raises(OctreeFormatError, match="a folder, not an octree file"):
        load_octree(tmp_path)
    for cut in (10, len(good) // 2, len(good) - 5):
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(good[:cut])
        with pytest.raises(OctreeFormatError):
            load_octree(bad)
    # Another kind of file under the name: NumPy's words were pickle advice.
    misnamed = tmp_path / "model.npz"
    misnamed.write_bytes(b"VOX \x96\x00\x00\x00MAIN")
    with pytest.raises(OctreeFormatError, match="not a NumPy .npz file") as caught:
        load_octree(misnamed)
    assert "pickle" not in str(caught.value)
    np.save(tmp_path / "one.npy", np.zeros(3))  # one array where an archive belongs
    (tmp_path / "one.npy").rename(misnamed)
    with pytest.raises(OctreeFormatError, match=r"not a NumPy .npz file \(a single-array"):
        load_octree(misnamed)
    # Structurally wrong but readable: a child pointer past the end.
    broken = tmp_path / "broken.npz"
    descriptors = octree.descriptors.copy()
    descriptors[0] += (octree.node_count + 5) << FIRST_CHILD_SHIFT
    save_octree(replace(octree, descriptors=descriptors), broken)
    with pytest.raises(OctreeFormatError, match="child pointers"):
        load_octree(broken)
    # A voxel box outside the root cube (an Octree refuses to hold one: written by hand).
    outside = _saved_with(octree, tmp_path / "outside.npz",
                          voxel_box=np.array([[0, 0, 0], [octree.size + 1] * 3]))
    with pytest.raises(OctreeFormatError, match="voxel box outside"):
        load_octree(outside)
    short = _saved_with(octree, tmp_path / "short.npz",
                        attr_color=octree.attributes["color"][:10])
    with pytest.raises(OctreeFormatError, match="short.npz: .*attribute 'color' has shape"):
        load_octree(short)


def _saved_with(octree, path, **arrays):
    """``octree``'s file with some of its arrays replaced, as a damaged file holds them."""
    save_octree(octree, path)
    with np.load(path) as data:
        stored = {name: data[name] for name in data.files}
    with open(path, "wb") as f:
        np.savez(f, **{**stored, **arrays})
    return path



def _with_header(octree, path, **changes):
    """``octree``'s file with its JSON header changed (a key set to None is dropped), or
    replaced outright by ``header=...``."""
    save_octree(octree, path)
    with np.load(path) as data:
        stored = {name: data[name] for name in data.files}
    header = json.loads(bytes(stored["header"]).decode())
    header = changes.pop("header", header)
    if isinstance(header, dict):
        header = {k: v for k, v in {**header, **changes}.items() if v is not None}
    stored["header"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    with open(path, "wb") as f:
        np.savez(f, **stored)
    return path


def test_an_octree_file_with_two_roots_is_refused(tmp_path):
    """Level offsets [0, 2, 4]: a red voxel under root 0, a green one under root 1. Each
    level held as many nodes as the level above declared children, so it loaded, and
    ``voxfield info`` counted 2 voxels that no render ever showed the green one of."""
    two_roots = Octree(
        depth=1, name="tworoot",
        descriptors=np.array([(2 << FIRST_CHILD_SHIFT) | 0x01, (3 << FIRST_CHILD_SHIFT) | 0x80],
                             np.int64),
        level_offsets=np.array([0, 2, 4], np.int64),
        attributes={"color": np.array([[200, 0, 0], [0, 200, 0]] * 2, np.uint8)},
        voxel_box=np.array([[0, 0, 0], [2, 2, 2]], np.int64))
    path = save_octree(two_roots, tmp_path / "tworoot.npz")
    with pytest.raises(OctreeFormatError, match=r"tworoot.npz: level 0 holds 2 nodes; an octree "
                                                r"has one root"):
        load_octree(path)
    one_root = Octree(
        depth=1, name="oneroot", descriptors=np.array([(1 << FIRST_CHILD_SHIFT) | 0x01], np.int64),
        level_offsets=np.array([0, 1, 2], np.int64),
        attributes={"color": np.array([[200, 0, 0]] * 2, np.uint8)},
        voxel_box=np.array([[0, 0, 0], [1, 1, 1]], np.int64))
    assert load_octree(save_octree(one_root, tmp_path / "oneroot.npz")).voxel_count == 1


def test_octree_files_with_float_colours_out_of_range_are_refused(tmp_path):
    """A scene's albedo outside [0, 1] is refused; an octree file's -5 rendered black and
    1e30 white, exit 0. Light (lit channels, emission) may exceed 1, never go below 0."""
    octree = build_octree(random_scene(5), colour_storage="float32")
    n = octree.node_count
    lit = octree.recoloured(attributes={**octree.attributes,
                                        "noon": np.full((n, 3), 3.5, np.float32)})
    refused = {
        "albedo -5": ("color", -5.0, r"'color' holds -5\.\.\S+; the albedo is linear in \[0, 1\]"),
        "albedo 1e30": ("color", 1e30, r"'color' holds \S+\.\.1e\+30; the albedo"),
        "albedo NaN": ("color", np.nan, "'color' holds NaN or infinity"),
        "lit infinity": ("noon", np.inf, "'noon' holds NaN or infinity"),
        "lit -1": ("noon", -1.0, "'noon' holds -1; light and emission are never negative"),
    }
    for what, (name, value, message) in refused.items():
        values = np.array(lit.attributes[name])
        values[len(values) // 2] = value
        path = _saved_with(lit, tmp_path / "colours.npz", **{f"attr_{name}": values})
        with pytest.raises(OctreeFormatError, match="colours.npz: attribute " + message):
            load_octree(path)
            pytest.fail(what)
    # Rounding past the ends is no damage; light past 1 is legitimate.
    rounded = np.array(lit.attributes["color"])
    rounded[0], rounded[1] = np.nextafter(np.float32(1), np.float32(2)), -1e-7
    path = _saved_with(lit, tmp_path / "rounded.npz", attr_color=rounded)
    loaded = load_octree(path)
    assert loaded.attributes["noon"].max() == 3.5


def test_octree_file_headers_of_the_wrong_kind_are_named_not_crashed_on(tmp_path):
    """A list header failed with "'list' object has no attribute 'get'", a string of
    attributes with "attr_c is not a file in the archive", and a depth of 6.7 was taken as
    6 without a word."""
    octree = build_octree(random_scene(5))
    bad = {
        "the header is a list, not an object": {"header": [1, 2]},
        "the header is a string, not an object": {"header": "voxfield-octree"},
        "the header's attributes must be a list of names, got \"color\"":
            {"attributes": "color"},
        "the header's attributes must be a list of names, got \\[1\\]": {"attributes": [1]},
        "the header's attributes must be a list of names, got null": {"attributes": None},
        "the header's depth must be a whole number, got 6.7": {"depth": 6.7},
        "the header's depth must be a whole number, got \"abc\"": {"depth": "abc"},
        "the header's depth must be a whole number, got true": {"depth": True},
        "the header's depth must be a whole number, got null": {"depth": None},
        "the file has no 'attr_noon' array": {"attributes": ["color", "noon"]},
    }
    for message, change in bad.items():
        path = _with_header(octree, tmp_path / "header.npz", **change)
        with pytest.raises(OctreeFormatError, match=f"^{re.escape(str(path))}: {message}$"):
            load_octree(path)
    # A depth written as a float of a whole number is still that depth.
    whole = _with_header(octree, tmp_path / "whole.npz", depth=float(octree.depth))
    assert load_octree(whole).depth == octree.depth

def test_an_octree_cannot_be_changed_in_place_or_assembled_from_arrays_that_disagree():
    """The kernels index one array by another's values: an octree changed in place, or made
    with a short colour array or the wrong depth, crashed the interpreter or read garbage
    (a render of one built with ``depth=2`` drew 8 hits of 500)."""
    octree = build_octree(random_scene(5))
    for array in (octree.descriptors, octree.level_offsets, octree.voxel_box,
                  octree.scene_origin, octree.attributes["color"]):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = array[-1]
    bad = {"a short colour array": {"attributes": {"color": octree.attributes["color"][:10]}},
           "another depth": {"depth": 2},
           "descriptors of another type": {"descriptors": octree.descriptors.astype(np.int32)},
           "a box past the root cube": {"voxel_box": np.array([[0, 0, 0],
                                                               [octree.size + 1] * 3])}}
    for what, change in bad.items():
        with pytest.raises(VoxfieldError, match="octree 'random5'"):
            replace(octree, **change)
            pytest.fail(what)
    # Nor can a channel be added or dropped in place; a copy with other channels is checked.
    with pytest.raises(TypeError, match="channels are read-only"):
        octree.attributes["half"] = octree.attributes["color"][:10]
    with pytest.raises(TypeError, match="channels are read-only"):
        del octree.attributes["color"]
    with pytest.raises(VoxfieldError, match="attribute 'half' has shape"):
        octree.recoloured(attributes={**octree.attributes,
                                      "half": octree.attributes["color"][:10]})
    assert pickle.loads(pickle.dumps(octree)).attributes.keys() == {"color"}


def test_octree_files_whose_solid_flags_or_voxel_box_lie_are_refused(tmp_path):
    """Traversal trusts both: a cleared solid bit costs speed, a set one on a node with a hole
    paints the hole, a box cut short clips the render; none may load as a good file."""
    octree = build_octree(random_scene(8, n=900, size=8))
    solid_bits = (octree.descriptors & SOLID_BIT) != 0
    assert solid_bits.any() and not solid_bits.all()
    lies = {
        "every solid bit cleared": replace(octree, descriptors=octree.descriptors & ~SOLID_BIT),
        "a node with a hole said solid": replace(
            octree, descriptors=octree.descriptors | SOLID_BIT * ~solid_bits),
    }
    for axis in range(3):
        for side in (0, 1):
            box = octree.voxel_box.copy()
            box[side, axis] += 1 - 2 * side  # one voxel layer of the box cut off
            lies[f"box cut on axis {axis}, side {side}"] = replace(octree, voxel_box=box)
    for what, lie in lies.items():
        path = save_octree(lie, tmp_path / "lie.npz")
        with pytest.raises(OctreeFormatError, match="solid flags|leaves out voxels"):
            load_octree(path)
            pytest.fail(what)
    # A box larger than the voxels is harmless (rays merely start earlier) and loads.
    roomy = replace(octree, voxel_box=np.array([[0, 0, 0], [octree.size] * 3]))
    assert np.array_equal(load_octree(save_octree(roomy, tmp_path / "roomy.npz")).voxel_box,
                          roomy.voxel_box)


def _under_a_new_root(octree, octant: int):
    """The octree as child ``octant`` of a root one level up: its voxels move away from the
    origin (a built octree's start at 0), so each face's descent meets both halves."""
    shifted = octree.descriptors + (1 << FIRST_CHILD_SHIFT)  # every node one index later
    root = np.array([(1 << FIRST_CHILD_SHIFT) | (1 << octant)], np.int64)
    corner = np.array([(octant >> axis) & 1 for axis in range(3)]) << octree.depth
    return replace(
        octree, depth=octree.depth + 1, descriptors=np.concatenate((root, shifted)),
        level_offsets=np.concatenate(([0], octree.level_offsets + 1)),
        attributes={k: np.concatenate((v[:1], v)) for k, v in octree.attributes.items()},
        voxel_box=octree.voxel_box + corner,
        facing=None if octree.facing is None else np.concatenate((octree.facing[:1],
                                                                  octree.facing)))


@pytest.mark.parametrize("seed", range(4))
def test_occupied_box_is_the_voxels_bounding_box(seed):
    octree = build_octree(random_scene(seed, n=40 + 60 * seed, size=16 << seed % 2))
    for tree in (octree, _under_a_new_root(octree, 7), _under_a_new_root(octree, 2 + seed)):
        validate_octree(tree)
        leaves = tree.node_coords(tree.depth)
        expected = np.array([leaves.min(axis=0), leaves.max(axis=0) + 1])
        assert np.array_equal(tree.occupied_box(), expected)
        assert np.array_equal(tree.voxel_box, expected)  # the builder's box is the tight one


def test_surface_lod_colour_ignores_buried_voxels():
    # A solid 4³ block, bright outside and black inside: the mean darkens the root, the
    # surface rule gives the colour of the voxels a ray can see.
    coords = np.argwhere(np.ones((4, 4, 4), bool))
    inside = np.all((coords > 0) & (coords < 3), axis=1)
    color = np.where(inside[:, None], 0.0, 0.8) * np.ones(3)
    scene = VoxelScene(coords, color)
    mean = build_octree(scene, colour_storage="float32")
    surface = build_octree(scene, lod_colour="surface", colour_storage="float32")
    assert mean.color[0] == pytest.approx(0.8 * 56 / 64)
    assert np.allclose(surface.color[0], 0.8)
    # Leaves and structure are untouched; a node with no buried voxel keeps its plain mean.
    assert np.array_equal(surface.child_mask, mean.child_mask)
    leaves = mean.level_slice(mean.depth)
    assert np.array_equal(surface.color[leaves], mean.color[leaves])
    with pytest.raises(VoxfieldError):
        build_octree(scene, lod_colour="median")


def test_version_1_files_still_load(tmp_path):
    """Files of the first format stored masks, first children and positions per node."""
    import json

    octree = build_octree(random_scene(6))
    header = {"format": "voxfield-octree", "version": 1, "depth": octree.depth, "name": "v1",
              "build_seconds": 0.0, "attributes": ["color"]}
    path = tmp_path / "v1.npz"
    np.savez(path, header=np.frombuffer(json.dumps(header).encode(), np.uint8),
             child_mask=octree.child_mask, first_child=octree.first_child.astype(np.uint32),
             node_coord=octree.all_node_coords().astype(np.int32),
             level_offsets=octree.level_offsets, scene_origin=octree.scene_origin,
             attr_color=octree.color)
    loaded = load_octree(path)
    assert np.array_equal(loaded.descriptors, octree.descriptors)
    assert np.array_equal(loaded.voxel_box, octree.voxel_box)
    assert np.array_equal(loaded.color, octree.color)


def test_solid_flags_match_a_brute_force_fill_check():
    scene = random_scene(8, n=900, size=8)  # dense enough for full 2³ and 4³ blocks
    octree = build_octree(scene)
    occupied = {tuple(c) for c in octree.node_coords(octree.depth)}
    solid = octree.solid_nodes()
    for level in range(octree.depth + 1):
        size = 1 << (octree.depth - level)
        block = np.argwhere(np.ones((size,) * 3, bool))
        for node, corner in zip(range(*octree.level_slice(level).indices(octree.node_count)),
                                octree.node_coords(level) * size, strict=True):
            full = all(tuple(corner + b) in occupied for b in block)
            assert solid[node] == full, (level, corner)
    assert solid[octree.level_slice(octree.depth - 1)].any()  # the check is not vacuous
    assert np.array_equal(octree.derived_solid_flags(), solid[: octree.inner_count])


def test_srgb8_albedo_keeps_8_bit_inputs_exactly_and_rounds_the_rest_to_a_code():
    from voxfield.kernels.colour import SRGB8_TO_LINEAR, srgb_encode

    rng = np.random.default_rng(12)
    coords = np.unique(rng.integers(0, 16, size=(400, 3)), axis=0)
    codes = rng.integers(0, 256, size=(len(coords), 3))
    eight_bit = VoxelScene(coords, SRGB8_TO_LINEAR[codes])
    stored = build_octree(eight_bit)
    exact = build_octree(eight_bit, colour_storage="float32")
    assert stored.attributes["color"].dtype == np.uint8
    leaves = stored.level_slice(stored.depth)
    assert np.array_equal(stored.color[leaves], exact.color[leaves])
    # Inner nodes (means) land on the nearest code: within half a code step in sRGB.
    error = np.abs(srgb_encode(stored.color) - srgb_encode(exact.color)) * 255
    assert error.max() <= 0.5 + 1e-3
    assert stored.nbytes < exact.nbytes
    with pytest.raises(VoxfieldError, match="colour storage"):
        build_octree(eight_bit, colour_storage="float16")


def test_open_octree_takes_a_path_as_well_as_a_string(tmp_path):
    from pathlib import Path

    from voxfield.svo.open import open_octree

    octree = build_octree(random_scene(4, 100))
    path = save_octree(octree, tmp_path / "saved.npz")
    assert isinstance(path, Path)
    for spec in (path, str(path)):
        assert open_octree(spec).fingerprint() == octree.fingerprint()
    with pytest.raises(VoxfieldError, match="a path or a name"):
        open_octree(42)


def test_the_builders_refuse_what_is_not_a_scene_or_an_octree(tmp_path):
    """An array, None or a name passed for the scene or octree raised AttributeError or
    TypeError from inside."""
    for scene in (np.zeros((3, 3), int), None):
        with pytest.raises(VoxfieldError, match="needs a VoxelScene"):
            build_octree(scene)
    with pytest.raises(VoxfieldError, match="needs a voxfield Octree"):
        save_octree("builtin:sphere", tmp_path / "x.npz")
    with pytest.raises(VoxfieldError, match="channels must map names"):
        VoxelScene(np.zeros((1, 3), int), np.ones((1, 3)), channels=[1, 2])
    from voxfield.render.ray_query import occluded, trace

    for query in (trace, occluded):
        with pytest.raises(VoxfieldError, match="needs a voxfield Octree"):
            query(None, [[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]])


def test_the_renderers_refuse_what_is_not_an_octree_or_a_camera():
    """render_reference(None, camera) raised "'NoneType' object has no attribute 'depth'",
    and a camera of None "... no attribute 'width'", from inside."""
    from voxfield.render import (
        render_adaptive,
        render_error_aware,
        render_lod,
        render_reference,
        top_down_camera,
    )
    from voxfield.svo.open import open_octree

    octree = open_octree("builtin:sphere")
    camera = top_down_camera(*octree.voxel_bounds, size=8)
    for render in (render_reference, render_lod, render_error_aware, render_adaptive):
        for scene in (None, "builtin:sphere"):
            with pytest.raises(VoxfieldError, match=f"{render.__name__} needs a voxfield "
                                                    "Octree"):
                render(scene, camera)
        with pytest.raises(VoxfieldError, match=f"{render.__name__} needs a voxfield Camera "
                                                r"\(voxfield.render.Camera and its presets\), "
                                                "got NoneType"):
            render(octree, None)
