"""Probe baking: maps checked against the octree's own ray cast, mip and cube-face properties,
renderer choice, real scenes, determinism and bad input."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import oct_encode, texel_directions
from voxfield.kernels.primary import normal_from_code
from voxfield.metrics import compare_images
from voxfield.probes.bake import bake_cube_faces, bake_probe, bake_probes, export_cube_faces
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import (
    NO_NORMAL,
    BakeOptions,
    ProbeMaps,
    ProbeSet,
    decode_normals,
    encode_normals,
    min_distance_mips,
)
from voxfield.render.ray_query import trace
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

BOX = 16


class PointGrid:
    """Probes at arbitrary points: the duck-typed slice of ProbeGrid the baker reads
    (``positions``, ``enabled``), for tests that need exact positions off a lattice."""

    def __init__(self, positions, enabled=None):
        self.positions = np.asarray(positions, np.float64).reshape(-1, 3)
        self.enabled = (np.ones(len(self.positions), bool) if enabled is None
                        else np.asarray(enabled, bool))

    @property
    def count(self) -> int:
        return len(self.positions)


@pytest.fixture(scope="module")
def box_octree():
    """A closed hollow box (16³ shell, colours varying per wall voxel) with a few pillars."""
    grid = np.indices((BOX, BOX, BOX)).reshape(3, -1).T
    shell = grid[(grid.min(axis=1) == 0) | (grid.max(axis=1) == BOX - 1)]
    pillars = np.array([(x, y, z) for x, z in ((4, 4), (11, 5), (6, 11)) for y in range(1, 9)])
    coords = np.concatenate([shell, pillars])
    rng = np.random.default_rng(3)
    return build_octree(VoxelScene(coords, rng.random((len(coords), 3)) * 0.8 + 0.1))


@pytest.fixture(scope="module")
def plain_box():
    grid = np.indices((BOX, BOX, BOX)).reshape(3, -1).T
    shell = grid[(grid.min(axis=1) == 0) | (grid.max(axis=1) == BOX - 1)]
    return build_octree(VoxelScene(shell, np.full((len(shell), 3), 0.5)))


PROBE = (7.3, 9.6, 8.2)


def test_distance_is_the_octree_ray_cast_distance_for_every_texel(box_octree):
    r = 32
    maps = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="error-aware"))
    dirs = texel_directions(r)
    hits = trace(box_octree, np.tile(PROBE, (len(dirs), 1)), dirs)
    # Bit-for-bit: the baked distance is float32 of the independent LOD-0 ray cast.
    assert maps.distance.dtype == np.float32
    assert np.array_equal(maps.distance.ravel(), hits.t.astype(np.float32))


def test_normals_decode_to_the_face_normal_of_the_hit(box_octree):
    r = 24
    maps = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="lod"))
    dirs = texel_directions(r)
    hits = trace(box_octree, np.tile(PROBE, (len(dirs), 1)), dirs)
    expected = np.array([normal_from_code(c) for c in hits.normal_code])
    assert maps.normal.dtype == np.int16 and maps.normal.shape == (r, r, 2)
    assert np.allclose(maps.normal_vectors().reshape(-1, 3), expected, atol=1e-4)
    # Every normal faces back towards the probe.
    assert np.all((expected * dirs).sum(axis=1) < 0)


def test_probe_inside_a_closed_box_sees_a_surface_everywhere(box_octree):
    maps = bake_probe(box_octree, PROBE, BakeOptions(resolution=16, renderer="lod"))
    assert np.isfinite(maps.distance).all()
    assert (maps.distance > 0).all() and (maps.distance < BOX * np.sqrt(3)).all()
    assert not (maps.normal == NO_NORMAL).any()


def test_probe_in_open_space_has_inf_distance_and_no_normal_where_rays_escape(box_octree):
    maps = bake_probe(box_octree, (8.0, BOX + 5.0, 8.0), BakeOptions(resolution=16))
    dirs = texel_directions(16).reshape(16, 16, 3)
    up = dirs[..., 1] > 0
    assert np.isinf(maps.distance[up]).all()
    assert np.isfinite(maps.distance[dirs[..., 1] < -0.9]).all()
    assert (maps.normal[np.isinf(maps.distance)] == NO_NORMAL).all()
    assert (maps.radiance[np.isinf(maps.distance)] == 0).all()


def _brute_min(d, level, i, j):
    s = 1 << level
    return d[..., i * s:(i + 1) * s, j * s:(j + 1) * s].min(axis=(-2, -1))


@pytest.mark.parametrize("size", [16, 12, 5, 1])
def test_min_mips_are_the_true_block_minimum_and_conservative(size):
    rng = np.random.default_rng(size)
    d = rng.random((2, size, size)).astype(np.float32) * 50
    d[rng.random(d.shape) < 0.2] = np.inf
    chain = min_distance_mips(d)
    assert chain[0].shape == d.shape and chain[-1].shape == (2, 1, 1)
    for level, mip in enumerate(chain):
        assert mip.dtype == np.float32
        n = mip.shape[-1]
        assert n == -(-size // (1 << level))  # ceil halvings
        for i in range(n):
            for j in range(n):
                assert np.array_equal(mip[:, i, j], _brute_min(d, level, i, j))
        # Conservative: each mip texel is <= every level-0 texel it covers.
        rows = np.arange(size) >> level
        covering = mip[:, rows[:, None], rows[None, :]]
        assert (covering <= d).all()
    assert np.array_equal(chain[-1][:, 0, 0], d.min(axis=(-2, -1)))


def test_probe_set_mips_follow_its_distance(box_octree):
    grid = PointGrid([PROBE, (3.5, 3.5, 3.5)])
    probes = bake_probes(box_octree, grid, BakeOptions(resolution=16, renderer="lod"))
    chain = probes.distance_mips()
    assert [m.shape for m in chain] == [(2, 16, 16), (2, 8, 8), (2, 4, 4), (2, 2, 2), (2, 1, 1)]
    assert np.array_equal(chain[2][:, 1, 3], probes.distance[:, 4:8, 12:16].min(axis=(1, 2)))


def test_cube_face_centres_see_the_axis_distance_of_the_octahedral_map(plain_box):
    position = (6.3, 9.4, 7.7)
    r, s = 32, 9  # odd face size: the centre pixel's ray is the face axis itself
    maps = bake_probe(plain_box, position, BakeOptions(resolution=r, renderer="lod"))
    radiance, distance = bake_cube_faces(plain_box, position, s, BakeOptions(renderer="lod"))
    assert radiance.shape == (6, s, s, 3) and radiance.dtype == np.float16
    assert distance.shape == (6, s, s) and distance.dtype == np.float32
    axes = np.array([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)], float)
    exact = trace(plain_box, np.tile(position, (6, 1)), axes).t
    assert np.allclose(distance[:, s // 2, s // 2], exact, rtol=1e-6)
    for axis, centre in zip(axes, distance[:, s // 2, s // 2], strict=True):
        u, v = oct_encode(*axis)
        col = min(int(u * r), r - 1)
        row = min(int(v * r), r - 1)
        # The axis falls on a texel corner (even R): its texels lie within a texel's angle.
        assert abs(maps.distance[row, col] - centre) <= 0.02 * centre + 0.05


def test_probe_set_cube_faces_need_the_baked_octree(box_octree, plain_box):
    probes = bake_probes(box_octree, PointGrid([PROBE]), BakeOptions(resolution=8,
                                                                        renderer="lod"))
    radiance, distance = export_cube_faces(probes, box_octree, 0)
    assert radiance.shape == (6, 4, 4, 3) and np.isfinite(distance).all()
    with pytest.raises(VoxfieldError, match="not the one"):
        export_cube_faces(probes, plain_box, 0)


def test_renderer_choice_changes_radiance_not_geometry(box_octree):
    r = 16
    ref = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="reference"))
    lod = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="lod", lod=1))
    assert np.array_equal(ref.distance, lod.distance)
    assert np.array_equal(ref.normal, lod.normal)
    assert not np.array_equal(ref.radiance, lod.radiance)
    # Costs: 4×4 reference rays vs one LOD ray per texel, plus the exact pass for both.
    assert ref.cost.radiance_rays == 16 * r * r and lod.cost.radiance_rays == r * r
    assert ref.cost.geometry_rays == lod.cost.geometry_rays == r * r
    assert ref.cost_summary()["rays_per_texel"] == 17.0
    assert ref.cost.radiance_steps > lod.cost.radiance_steps > 0


def test_single_sample_lod0_bake_reuses_its_pass_for_geometry(box_octree):
    one = bake_probe(box_octree, PROBE, BakeOptions(resolution=16, renderer="reference",
                                                    samples=1))
    lod0 = bake_probe(box_octree, PROBE, BakeOptions(resolution=16, renderer="lod", lod=0))
    assert np.array_equal(one.radiance, lod0.radiance)
    assert one.cost.geometry_rays == 0 and one.cost.radiance_rays == 256
    assert one.cost.steps == lod0.cost.steps


def test_error_aware_refining_everywhere_matches_the_reference(box_octree):
    r = 32
    ref = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="reference"))
    ea = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="error-aware",
                                                   lod=2, threshold=-1.0))
    cheap = bake_probe(box_octree, PROBE, BakeOptions(resolution=r, renderer="lod", lod=2))
    as_rgb = [np.clip(m.radiance.astype(np.float32), 0, 1) for m in (ref, ea, cheap)]
    close = compare_images(as_rgb[0], as_rgb[1])
    far = compare_images(as_rgb[0], as_rgb[2])
    # Two refinements from LOD 2 end at LOD 0 with 4×4 rays: close to the reference (the
    # renderer's own property), and far closer than the unrefined LOD-2 bake.
    assert close["rmse"] < 1e-3 and far["rmse"] > 0.05
    assert ea.cost.radiance_rays == 21 * r * r - np.isinf(ea.distance).sum() * 20


def test_disabled_probes_are_empty_and_flagged(box_octree):
    grid = ProbeGrid.fit((1, 1, 1), (BOX - 1, BOX - 1, BOX - 1), (3, 1, 1))
    grid = grid.with_enabled(np.array([True, False, True]))
    probes = bake_probes(box_octree, grid, BakeOptions(resolution=8, renderer="lod"))
    assert probes.enabled.tolist() == [True, False, True] and probes.grid is grid
    assert np.isinf(probes.distance[1]).all() and not probes.radiance[1].any()
    assert (probes.normal[1] == NO_NORMAL).all()
    assert probes.cost["radiance_rays"][1] == 0 and probes.cost["geometry_rays"][1] == 0
    summary = probes.cost_summary()
    assert summary["baked"] == 2 and summary["rays"] == 2 * 2 * 64
    assert summary["rays_per_texel"] == 2.0
    single = bake_probe(box_octree, grid.positions[2], probes.options)
    assert np.array_equal(probes.probe(2).distance, single.distance)
    assert np.array_equal(probes.probe(2).radiance, single.radiance)


def test_bake_is_deterministic_for_any_thread_count(box_octree, small_jobs_in_parallel):
    grid = ProbeGrid.fit((1, 1, 1), (BOX - 1, BOX - 1, BOX - 1), (2, 1, 2))
    for renderer in ("reference", "error-aware"):
        options = BakeOptions(resolution=16, renderer=renderer, seed=5)
        a = bake_probes(box_octree, grid, options, threads=1)
        b = bake_probes(box_octree, grid, options, threads=2)
        for name in ("radiance", "distance", "normal"):
            assert np.array_equal(getattr(a, name), getattr(b, name))
        for name in ("radiance_rays", "radiance_steps", "geometry_rays", "geometry_steps"):
            assert np.array_equal(a.cost[name], b.cost[name])


def test_probe_maps_and_options_pickle(box_octree):
    options = BakeOptions(resolution=8, renderer="lod", threshold=float("inf"))
    maps = bake_probe(box_octree, PROBE, options)
    again = pickle.loads(pickle.dumps((options, maps)))
    assert again[0] == options
    assert np.array_equal(again[1].distance, maps.distance) and again[1].cost == maps.cost


def test_options_round_trip_through_dict():
    options = BakeOptions(resolution=128, renderer="reference", samples=2, lod=3,
                          cone_scale=0.5, threshold=float("inf"), decay=0.1, seed=7)
    data = options.to_dict()
    assert data["threshold"] == "inf"
    import json

    assert BakeOptions.from_dict(json.loads(json.dumps(data))) == options
    assert BakeOptions.from_dict({}) == BakeOptions()


def test_snorm16_normals_round_trip():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(2000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    back = decode_normals(encode_normals(v))
    assert np.abs(back - v).max() < 2e-4
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    assert np.array_equal(decode_normals(encode_normals(axes)), axes.astype(np.float32))
    assert (encode_normals(np.zeros((2, 3))) == NO_NORMAL).all()
    assert not decode_normals(encode_normals(np.zeros((1, 3)))).any()


@pytest.mark.parametrize("bad", [
    {"resolution": 3}, {"resolution": 2}, {"resolution": 7}, {"resolution": 4096},
    {"resolution": 64.0}, {"resolution": True}, {"renderer": "cubemap"}, {"samples": 0},
    {"samples": 17}, {"lod": -1}, {"lod": 1.5}, {"cone_scale": 0.0},
    {"cone_scale": float("nan")}, {"threshold": float("nan")}, {"threshold": "high"},
    {"decay": -0.1}, {"seed": -1}, {"seed": 2**32}, {"seed": True}, {"channel": ""},
])
def test_bad_options_raise(bad):
    with pytest.raises(VoxfieldError):
        BakeOptions(**bad)


def test_bad_bake_input_raises(box_octree):
    with pytest.raises(VoxfieldError, match="deeper"):
        bake_probe(box_octree, PROBE, BakeOptions(resolution=8, lod=box_octree.depth + 1))
    with pytest.raises(VoxfieldError, match="channel"):
        bake_probe(box_octree, PROBE, BakeOptions(resolution=8, channel="noon"))
    with pytest.raises(VoxfieldError):
        bake_probe(box_octree, (np.nan, 1.0, 1.0), BakeOptions(resolution=8))
    with pytest.raises(VoxfieldError, match="unknown bake option"):
        BakeOptions.from_dict({"resolution": 8, "faces": 6})
    with pytest.raises(VoxfieldError):
        bake_probes(box_octree, PointGrid([PROBE], enabled=[True, False]),
                    BakeOptions(resolution=8))
    with pytest.raises(VoxfieldError):
        ProbeMaps(np.zeros((4, 4, 3), np.float32), np.zeros((4, 4), np.float32),
                  np.zeros((4, 4, 2), np.int16), None)
    with pytest.raises(VoxfieldError):
        bake_cube_faces(box_octree, PROBE, 0, BakeOptions(resolution=8))
    with pytest.raises(VoxfieldError, match="cube face size must be an integer"):
        bake_cube_faces(box_octree, PROBE, 2.5, BakeOptions(resolution=8))


def _check_real_bake(octree, probes: ProbeSet, r: int, min_covered: float):
    assert probes.radiance.shape == (probes.count, r, r, 3)
    assert np.isfinite(probes.radiance.astype(np.float32)).all()
    assert not np.isnan(probes.distance).any()
    covered = np.isfinite(probes.distance)
    assert (covered.mean(axis=(1, 2)) > min_covered).all()  # every probe sees the scene
    assert (probes.radiance[covered].astype(np.float32).max(axis=-1) > 0).mean() > 0.9
    assert (probes.cost["geometry_rays"] == r * r).all()
    # The independent check on one probe of the grid.
    dirs = texel_directions(r)
    hits = trace(octree, np.tile(probes.positions[-1], (len(dirs), 1)), dirs)
    assert np.array_equal(probes.distance[-1].ravel(), hits.t.astype(np.float32))
    assert len(probes.distance_mips()) == int(np.log2(r)) + 1


def test_cornell_box_room_bakes_on_a_small_grid(shared_data):
    from voxfield.scene.loaders import SceneOptions
    from voxfield.svo.open import open_octree

    obj = shared_data / "mesh" / "cornell" / "CornellBox-Original.obj"
    octree = open_octree(str(obj), SceneOptions(mesh_resolution=32))
    lo, hi = octree.voxel_bounds
    grid = ProbeGrid.fit(lo + 2, hi - 2, (2, 1, 2))
    probes = bake_probes(octree, grid, BakeOptions(resolution=16))
    _check_real_bake(octree, probes, 16, 0.5)
    # The room is open only at the front (+z): probes see walls in every other direction.
    dirs = texel_directions(16).reshape(16, 16, 3)
    assert np.isfinite(probes.distance[:, dirs[..., 2] < -0.3]).all()


def test_vox_scene_bakes_on_a_small_grid(shared_data):
    from voxfield.svo.open import open_octree

    octree = open_octree(str(shared_data / "vox" / "chr_knight.vox"))
    lo, hi = octree.voxel_bounds
    grid = ProbeGrid.fit(lo - 4, hi + 4, (2, 1, 2))
    probes = bake_probes(octree, grid, BakeOptions(resolution=16, renderer="reference",
                                                   samples=2))
    _check_real_bake(octree, probes, 16, 0.05)
    assert probes.fingerprint and probes.options.renderer == "reference"


def test_probes_baked_side_by_side_wait_for_one_untimed_warm_up(box_octree, monkeypatch):
    """Kernels compile in one warm-up per configuration, on a 2×2 map, before any probe's
    timed passes start: threads that would otherwise compile beside a timed pass wait."""
    from concurrent.futures import ThreadPoolExecutor

    from voxfield.probes import bake as bake_module

    monkeypatch.setattr(bake_module, "_WARMED", set())
    calls = []
    real_passes = bake_module._passes

    def recording_passes(octree, camera, options, threads):
        calls.append(camera.width)
        return real_passes(octree, camera, options, threads)

    monkeypatch.setattr(bake_module, "_passes", recording_passes)
    options = BakeOptions(resolution=8, renderer="reference", samples=2)
    with ThreadPoolExecutor(3) as pool:
        maps = list(pool.map(lambda p: bake_probe(box_octree, p, options, threads=1),
                             [(4.5, 4.5, 4.5), (3.5, 4.5, 5.5), (5.5, 3.5, 4.5)]))
    assert calls[0] == 2 and calls.count(2) == 1 and calls[1:] == [8, 8, 8]
    bake_probe(box_octree, (4.5, 4.5, 4.5), BakeOptions(resolution=8, renderer="lod", lod=1))
    assert calls[4:] == [2, 8]  # a new configuration warms up once more
    assert all(m.cost.radiance_rays == 8 * 8 * 4 for m in maps)
