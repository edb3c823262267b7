"""LOD colours a ray can see: the hull test, two-sided walls, and the directional colours and
exposed faces against dense brute-force oracles."""

from __future__ import annotations

import numpy as np
import pytest
from tests.random_scenes import random_scene

from voxfield.kernels.colour import from_srgb8
from voxfield.render.camera import Camera, preset_camera
from voxfield.render.primary import render_lod
from voxfield.scene.loaders import SceneOptions, load_scene
from voxfield.scene.surface import face_mask
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.io import load_octree, save_octree
from voxfield.svo.lod_colours import (
    DEFAULT_LOD_COLOUR,
    apply_lod_colour,
    exposed_face_weights,
    exposed_faces,
    facing_colours,
)
from voxfield.svo.open import open_octree


def hull_scene(n: int = 24, offset: int = 0) -> VoxelScene:
    """A grey hull one voxel thick around a bright red interior."""
    g = np.argwhere(np.ones((n, n, n), bool))
    shell = (g == 0).any(axis=1) | (g == n - 1).any(axis=1)
    colour = np.where(shell[:, None], [0.5, 0.5, 0.5], [1.0, 0.1, 0.0]).astype(np.float32)
    return VoxelScene(g + offset, colour, name="hull")


def colour_shift(octree, camera, lod: int) -> float:
    """Largest per-channel change of the mean colour over pixels hit at LOD 0 and ``lod``."""
    reference = render_lod(octree, camera, lod=0)
    coarse = render_lod(octree, camera, lod=lod)
    hit = (reference.hit_count > 0) & (coarse.hit_count > 0)
    return float(np.abs(coarse.image[hit].mean(axis=0) - reference.image[hit].mean(axis=0)).max())


def hull_cameras(lo, hi):
    """Preset views and three from outside the sides and from below."""
    centre = (lo + hi) / 2.0
    span = float((hi - lo).max())
    cameras = [preset_camera(view, lo, hi, size=48) for view in ("oblique", "orbit", "top")]
    for offset in ((2.0, 0.3, 0.4), (-0.5, 0.2, -2.0), (0.3, -2.0, 0.5)):
        eye = centre + span * np.array(offset)
        cameras.append(Camera.look_at(eye, centre, fov_deg=40, width=48))
    return cameras


@pytest.mark.parametrize("offset", [0, 1])
@pytest.mark.parametrize("rule", ["facing", "surface"])
def test_a_grey_hull_renders_grey_at_every_lod(rule, offset):
    octree = build_octree(hull_scene(offset=offset), lod_colour=rule)
    cameras = hull_cameras(*octree.voxel_bounds)
    if rule == "surface":
        cameras = cameras[:-1]  # it leaves out the floor's faces: the hull's bottom is unseen
    for k, camera in enumerate(cameras):
        assert colour_shift(octree, camera, 1) <= 0.015, k
        assert colour_shift(octree, camera, 2) <= 0.03, k


def test_the_thesis_mean_shows_the_hull_interior():
    """The failure the other rules fix: children's means bleed the interior through."""
    octree = build_octree(hull_scene(), lod_colour="mean")
    lo, hi = octree.voxel_bounds
    camera = preset_camera("oblique", lo, hi, size=48)
    assert colour_shift(octree, camera, 1) > 0.1


def two_sided_walls() -> VoxelScene:
    """Walls two voxels thick, white on their low-z face and red on their high-z face."""
    slab = np.argwhere(np.ones((32, 16, 2), bool))
    coords, colours = [], []
    for z0 in (5, 21):
        c = slab + [0, 0, z0]
        coords.append(c)
        colours.append(np.where((c[:, 2] == z0)[:, None], [0.9, 0.9, 0.9], [0.8, 0.1, 0.1]))
    return VoxelScene(np.concatenate(coords), np.concatenate(colours).astype(np.float32))


def test_facing_colours_show_each_side_of_a_wall():
    """Between the walls, looking at the high-z face of one and the low-z face of the other."""
    facing = build_octree(two_sided_walls(), lod_colour="facing")
    surface = build_octree(two_sided_walls(), lod_colour="surface")
    for target in ((16, 8, 0), (16, 8, 30)):
        camera = Camera.look_at((16, 8, 14), target, fov_deg=70, width=48)
        for lod in (1, 2):
            assert colour_shift(facing, camera, lod) <= 0.015
        # One colour per node cannot be both sides at once.
        assert colour_shift(surface, camera, 1) > 0.2


def dense_grid(octree):
    """Occupancy and linear colours of the voxels on the full ``2**depth`` grid."""
    size = octree.size
    occupied = np.zeros((size,) * 3, bool)
    colour = np.zeros((size,) * 3 + (3,))
    coords = octree.node_coords(octree.depth)
    occupied[tuple(coords.T)] = True
    colour[tuple(coords.T)] = octree.color[octree.level_slice(octree.depth)]
    return occupied, colour


def dense_exposure(occupied: np.ndarray) -> np.ndarray:
    """(size, size, size, 6) bool: a voxel's face k (-x, +x, -y, +y, -z, +z) has no neighbour."""
    padded = np.pad(occupied, 1)
    inner = (slice(1, -1),) * 3
    out = []
    for axis in range(3):
        for step in (-1, 1):
            out.append(~np.roll(padded, -step, axis=axis)[inner])
    return np.stack(out, axis=-1) & occupied[..., None]


def dense_facing(occupied, colour, levels: int):
    """Per level above the voxels, per travel direction: coverage and colour, by compositing
    front over back along the axis and averaging the four columns (float, no quantisation)."""
    exposed = dense_exposure(occupied)
    cover = [exposed[..., [d ^ 1 for d in range(6)]].astype(float)]  # entered face per direction
    premult = [cover[0][..., None] * colour[..., None, :]]
    out = []
    for _ in range(levels):
        a, p = cover[-1], premult[-1]
        s = a.shape[0] // 2
        a8 = a.reshape(s, 2, s, 2, s, 2, 6)
        p8 = p.reshape(s, 2, s, 2, s, 2, 6, 3)
        new_a = np.empty((s, s, s, 6))
        new_p = np.empty((s, s, s, 6, 3))
        for direction in range(6):
            axis, up = divmod(direction, 2)
            front, back = (0, 1) if up else (1, 0)
            ax = 1 + 2 * axis
            af = np.take(a8[..., direction], front, axis=ax)
            ab = np.take(a8[..., direction], back, axis=ax)
            pf = np.take(p8[..., direction, :], front, axis=ax)
            pb = np.take(p8[..., direction, :], back, axis=ax)
            column_a = af + (1 - af) * ab
            column_p = pf + ((1 - af) / 1.0)[..., None] * pb
            others = tuple(1 + 2 * k for k in range(3) if k != axis)
            others = tuple(o - (1 if o > ax else 0) for o in others)
            new_a[..., direction] = column_a.mean(axis=others)
            new_p[..., direction, :] = column_p.mean(axis=others)
        cover.append(new_a)
        premult.append(new_p)
        out.append((new_a, new_p))
    return out


@pytest.mark.parametrize(("seed", "n", "size"), [(0, 700, 16), (1, 700, 16), (2, 700, 16),
                                                  (8, 120_000, 64)])
def test_exposed_faces_match_the_dense_grid(seed, n, size):
    """Sparse small scenes, and a dense 64³ one deep enough that most neighbours are found
    from a common ancestor the walk holds rather than from the root."""
    octree = build_octree(random_scene(seed, n=n, size=size))
    occupied, _ = dense_grid(octree)
    coords = octree.node_coords(octree.depth)
    expected = dense_exposure(occupied)[tuple(coords.T)]
    bits = exposed_faces(octree)
    got = (bits[:, None] >> np.arange(6)) & 1
    assert np.array_equal(got.astype(bool), expected)
    assert np.array_equal(expected, face_mask(coords))  # and the mesher's own rule


@pytest.mark.parametrize("seed", [3, 4])
def test_facing_colours_match_dense_compositing(seed):
    octree = build_octree(random_scene(seed, n=900, size=16), colour_storage="float32",
                          lod_colour="mean")
    occupied, colour = dense_grid(octree)
    facing = facing_colours(octree)
    levels = dense_facing(occupied, colour, octree.depth)
    for lod, (cover, premult) in enumerate(levels, start=1):
        level = octree.depth - lod
        coords = octree.node_coords(level)
        sl = octree.level_slice(level)
        want_cover = cover[tuple(coords.T)]
        got_cover = facing[sl, :, 3] / 255.0
        np.testing.assert_allclose(got_cover, want_cover, atol=2.5 / 255 * lod)
        visible = want_cover > 0.05
        want_rgb = premult[tuple(coords.T)][visible] / want_cover[visible][:, None]
        got_rgb = from_srgb8(facing[sl, :, :3])[visible]
        np.testing.assert_allclose(got_rgb, want_rgb, atol=0.02 * lod)


def test_exposed_face_weights_skip_the_floor():
    """Two stacked voxels on the floor: the lower has 4 side faces (its bottom is on the
    floor), the upper 4 sides and its top."""
    scene = VoxelScene(np.array([[0, 0, 0], [0, 1, 0]]), np.full((2, 3), 0.5, np.float32))
    octree = build_octree(scene, lod_colour="surface")
    coords = octree.node_coords(octree.depth)
    weights = dict(zip(map(tuple, coords.tolist()), exposed_face_weights(octree),
                       strict=True))
    assert weights == {(0, 0, 0): 4.0, (0, 1, 0): 5.0}


def test_facing_colours_survive_a_file_and_change_the_fingerprint(tmp_path):
    scene = hull_scene(8)
    facing = build_octree(scene, lod_colour="facing")
    mean = build_octree(scene, lod_colour="mean")
    back = load_octree(save_octree(facing, tmp_path / "hull.npz"))
    assert np.array_equal(back.facing, facing.facing)
    assert back.fingerprint() == facing.fingerprint() != mean.fingerprint()
    assert mean.facing is None and facing.nbytes == mean.nbytes + facing.facing.nbytes


def test_a_streamed_terrain_gets_the_same_facing_colours_as_a_monolithic_build(tmp_path):
    x, z = np.meshgrid(np.arange(40.0), np.arange(36.0))
    np.savez(tmp_path / "dem.npz", elevation=90.0 * np.sin(x / 7.0) * np.cos(z / 5.0) + 120.0,
             spacing=30.0)
    spec = str(tmp_path / "dem.npz")
    options = SceneOptions(terrain_footprint=32, dem_fit="stretch")
    streamed = open_octree(spec, options)
    whole = build_octree(load_scene(spec, options))
    assert DEFAULT_LOD_COLOUR == "facing"
    assert np.array_equal(streamed.facing, whole.facing)


def test_directional_colours_in_bands_equal_one_call(monkeypatch):
    """``facing_colours`` calls its kernel on bands of nodes (so Ctrl-C is heard); the
    colours are those of one call per level."""
    from voxfield.svo import lod_colours

    octree = build_octree(random_scene(11, n=700, size=20))
    whole = lod_colours.facing_colours(octree)
    monkeypatch.setattr(lod_colours, "KERNEL_BAND_NODES", 3)
    np.testing.assert_array_equal(lod_colours.facing_colours(octree), whole)
    assert whole.any()


def test_exposed_faces_are_found_once_per_structure_and_kept_read_only():
    """A command builds (facing colours read the exposure) and then bakes (which reads it
    again): the recoloured octrees between them share one table, which nobody can alter."""
    octree = build_octree(random_scene(5, n=400, size=16), lod_colour="mean")
    bits = exposed_faces(octree)
    assert not bits.flags.writeable
    with_facing = apply_lod_colour(octree, "facing")
    with_surface = apply_lod_colour(with_facing, "surface")
    assert exposed_faces(with_facing) is bits and exposed_faces(with_surface) is bits
    # A different structure gets its own table.
    other = build_octree(random_scene(6, n=400, size=16), lod_colour="mean")
    assert exposed_faces(other) is not bits
    # Weights are derived from a copy: the shared table stays as it was.
    before = bits.copy()
    exposed_face_weights(with_surface)
    assert np.array_equal(exposed_faces(with_surface), before)


def test_recoloured_copies_change_colours_only():
    octree = build_octree(random_scene(7, n=300, size=16), lod_colour="mean")
    with pytest.raises(ValueError, match="colours only"):
        octree.recoloured(descriptors=octree.descriptors.copy())
    octree.derived(("colour_error", "color", 0.5), lambda: "per colour")
    copy = octree.recoloured(name="renamed")
    assert copy.name == "renamed" and copy.descriptors is octree.descriptors
    # Tables of the colours are not carried: the copy works its own out.
    assert copy.derived(("colour_error", "color", 0.5), lambda: "again") == "again"


def test_bucketed_srgb_encoding_is_the_midpoint_search():
    """The bucketed encoder gives ``np.searchsorted``'s code for every value: random ones,
    each midpoint itself and its float neighbours, the ends and beyond them."""
    from numba import njit

    from voxfield.kernels.facing_colour import _ENCODE_EDGES, encode_srgb8

    @njit
    def encode_all(values, out):
        for k in range(values.shape[0]):
            out[k] = encode_srgb8(values[k])

    rng = np.random.default_rng(4)
    values = np.concatenate([
        rng.random(200_000), rng.random(20_000) * 1e-3, _ENCODE_EDGES,
        np.nextafter(_ENCODE_EDGES, 0.0), np.nextafter(_ENCODE_EDGES, 1.0),
        np.arange(4097) / 4096.0, [0.0, 1.0, -0.5, 1.5, 1e-300],
    ])
    out = np.empty(len(values), np.int64)
    encode_all(values, out)
    assert np.array_equal(out, np.searchsorted(_ENCODE_EDGES, values))
    encode_all(np.array([np.nan]), out[:1])
    assert out[0] == 255
