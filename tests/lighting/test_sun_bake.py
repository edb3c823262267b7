"""The sun bake against analytic cases, a brute-force shadow oracle and its own invariants."""

from __future__ import annotations

import argparse
import json
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from numba import njit
from PIL import Image

from random_scenes import overhanging_terrain, pillar_field, random_scene
from ray_oracle import first_hits
from voxfield.cli.cmd_light import preview_sheet
from voxfield.cli.cmd_light import register as add_light_parser
from voxfield.errors import VoxfieldError
from voxfield.kernels.sampling import cmj_sample
from voxfield.kernels.sun_bake import cos_sin_turns, cosine_direction
from voxfield.lighting import (
    TIMES_OF_DAY,
    SunLight,
    bake_sun_lighting,
    parse_suns,
    sun_at,
    sun_visibility,
)
from voxfield.lighting import sun_bake as bake_module
from voxfield.metrics import psnr
from voxfield.render import Camera, render_reference
from voxfield.scene.builtin import builtin_scene
from voxfield.scene.npz_io import save_scene
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.horizons import no_horizon_slopes
from voxfield.svo.io import load_octree

ALBEDO = np.array([0.5, 0.4, 0.3])
#: Face normals in the kernel's face order: −x, +x, −y, +y, −z, +z.
NORMALS = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]])


def slab(x: range, y: int, z: range) -> np.ndarray:
    xs, zs = np.meshgrid(np.asarray(x), np.asarray(z), indexing="ij")
    return np.stack([xs.ravel(), np.full(xs.size, y), zs.ravel()], axis=1)


def octree_of(*parts: np.ndarray, name: str = "test"):
    coords = np.unique(np.concatenate(parts), axis=0)
    assert coords.min() == 0  # the build moves the scene to the origin; keep coordinates
    return build_octree(VoxelScene(coords, np.tile(ALBEDO, (len(coords), 1)), name=name),
                        colour_storage="float32")


def leaf_index(octree, xyz) -> int:
    leaves = octree.node_coords(octree.depth)
    (index,) = np.flatnonzero((leaves == np.asarray(xyz)).all(axis=1))
    return int(index)


def leaf_channel(octree, name: str) -> np.ndarray:
    return octree.channel(name)[octree.level_slice(octree.depth)]


def test_a_floor_voxel_open_to_the_sky_is_lit_by_sun_and_sky():
    floor = octree_of(slab(range(9), 0, range(9)))
    sun = SunLight("test", azimuth_deg=30.0, elevation_deg=60.0,
                   irradiance=(0.9, 0.8, 0.7), sky=(0.1, 0.2, 0.3))
    lit, report = bake_sun_lighting(floor, [sun], sky_rays=16, shadow_rays=4)
    centre = leaf_index(floor, (4, 0, 4))
    expected = ALBEDO * (np.array(sun.irradiance) * math.sin(math.radians(60.0)) + sun.sky)
    assert np.allclose(leaf_channel(lit, "test")[centre], expected, rtol=1e-6)
    assert report.surface_voxels == 81 and report.sunlit_fraction["test"] == 1.0
    assert report.shadow_rays > 0 and report.sky_rays > 0 and report.traversal_steps > 0
    assert report.summary().startswith("sun bake: 1 sun over 81 surface voxels")  # not "1 suns"


def test_a_floor_voxel_under_a_roof_gets_no_sun_and_little_sky():
    floor = slab(range(2, 11), 0, range(2, 11))
    roof = slab(range(13), 3, range(13))  # larger than the floor, two voxels of air between
    octree = octree_of(floor, roof)
    suns = [SunLight("overhead", 0.0, 90.0, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)),
            SunLight("high", 200.0, 60.0, (1.0, 1.0, 1.0), (0.2, 0.2, 0.2))]
    vis, _ = sun_visibility(octree, np.array([s.direction() for s in suns]), sky_rays=64)
    centre = leaf_index(octree, (6, 0, 6))
    assert vis.direct[0, centre] == 0.0 and vis.direct[1, centre] == 0.0
    # Only rays flatter than atan(2/6) ≈ 18° pass under the roof's edge: sin²(18.4°) ≈ 0.1.
    assert 0.0 < vis.sky[centre] < 0.2
    lit, _ = bake_sun_lighting(octree, suns, sky_rays=64)
    assert np.all(leaf_channel(lit, "overhead")[centre] == 0.0)
    # The roof's top is lit by both suns.
    top = leaf_index(octree, (6, 3, 6))
    assert vis.direct[0, top] == 1.0 and vis.sky[top] == 1.0


def test_a_voxel_inside_a_closed_box_is_black():
    cube = np.stack(np.meshgrid(*[np.arange(7)] * 3, indexing="ij"), -1).reshape(-1, 3)
    shell = cube[(cube == 0).any(axis=1) | (cube == 6).any(axis=1)]
    octree = octree_of(shell)
    lit, _ = bake_sun_lighting(octree, list(TIMES_OF_DAY.values()), sky_rays=32)
    inner_floor = leaf_index(octree, (3, 0, 3))
    for name in TIMES_OF_DAY:
        assert np.all(leaf_channel(lit, name)[inner_floor] == 0.0)


def test_a_sun_below_the_horizon_leaves_only_sky_light():
    floor = octree_of(slab(range(9), 0, range(9)))
    night = SunLight("night", 0.0, -10.0, (1.0, 1.0, 1.0), (0.2, 0.2, 0.2))
    horizon = SunLight("horizon", 90.0, 0.0, (1.0, 1.0, 1.0), (0.2, 0.2, 0.2))
    lit, report = bake_sun_lighting(floor, [night, horizon], sky_rays=16)
    centre = leaf_index(floor, (4, 0, 4))
    for name in ("night", "horizon"):
        assert np.allclose(leaf_channel(lit, name)[centre], ALBEDO * 0.2, rtol=1e-6)
        assert report.sunlit_fraction[name] == 0.0
    assert report.shadow_rays == 0


def test_a_voxel_lit_past_1_is_kept_at_1_with_a_note():
    """A sun high over bright albedo lit open ground past 1 (0.85 + 0.25 over white), and
    every measuring command then failed after its renders: the metrics take [0, 1]."""
    floor = slab(range(9), 0, range(9))
    coords = np.unique(np.concatenate([floor, slab(range(4, 5), 1, range(4, 5))]), axis=0)
    albedo = np.array([1.0, 0.5, 0.25])
    octree = build_octree(VoxelScene(coords, np.tile(albedo, (len(coords), 1)), name="white"),
                          colour_storage="float32")
    sun = SunLight("zen", 0.0, 90.0, (0.85, 0.85, 0.85), (0.25, 0.25, 0.25))
    vis, _ = sun_visibility(octree, np.array([sun.direction()]), sky_rays=16)
    light = vis.direct[0] * 0.85 + vis.sky * 0.25
    unclamped = albedo * light[:, None]
    over = int(np.count_nonzero(unclamped[:, 0] > 1.0))
    assert 0 < over < len(coords)  # some voxels, under less sky, stay under 1
    with pytest.warns(UserWarning, match=rf"sun 'zen' lit {over} of 82 voxels brighter than 1 "
                                         rf"\(up to {unclamped.max():.3g}\); they are kept at 1"):
        lit, _ = bake_sun_lighting(octree, [sun], sky_rays=16)
    # Only what passed 1 changed: red, here; green and blue keep their light.
    np.testing.assert_allclose(leaf_channel(lit, "zen"), np.minimum(unclamped, 1.0), rtol=1e-6)
    # Under 1 nothing changes and nothing is said.
    dim = SunLight("dim", 0.0, 90.0, (0.5, 0.5, 0.5), (0.1, 0.1, 0.1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lit, _ = bake_sun_lighting(octree, [dim], sky_rays=16)
    np.testing.assert_allclose(leaf_channel(lit, "dim"),
                               albedo * (vis.direct[0] * 0.5 + vis.sky * 0.1)[:, None],
                               rtol=1e-6)


def test_a_sun_that_gives_no_light_is_noted():
    floor = octree_of(slab(range(5), 0, range(5)))
    with pytest.warns(UserWarning, match=r"sun 'deep' gives no light \(elevation -30°, below "
                                         r"the horizon\): its channel is black"):
        lit, _ = bake_sun_lighting(floor, parse_suns("deep=0,-30"), sky_rays=4)
    assert not leaf_channel(lit, "deep").any()


def test_a_zenith_sun_lights_no_wall_whatever_its_azimuth():
    """A sun straight overhead is square to every top face and grazes every wall; its
    direction's horizontal parts are rounding (~1e-16, by azimuth), which lit one side of a
    pillar by a hair and made the "in sun" share depend on the azimuth."""
    octree = octree_of(slab(range(9), 0, range(9)), np.array([(4, y, 4) for y in range(1, 5)]))
    suns = [SunLight(f"z{azimuth}", azimuth, 90.0, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
            for azimuth in (0, 45, 90, 180, 270)]
    lit, report = bake_sun_lighting(octree, suns, sky_rays=0, shadow_rays=2)
    # By hand: faces weigh (1 + n_y) / 2 without sky rays; only top faces see the sun, and
    # nothing stands above any of them.
    exposed = exposed_faces_by_hand(octree.node_coords(octree.depth))
    weight = np.where(exposed, (1.0 + NORMALS[:, 1]) / 2.0, 0.0)
    total = weight.sum(axis=1)  # 0 under the pillar: only its bottom face is open
    expected = np.divide(weight[:, 3], total, out=np.zeros_like(total), where=total > 0)
    assert 0.0 < (expected > 0).mean() < 1.0  # the pillar's lower voxels show only walls
    for sun in suns:
        assert np.allclose(leaf_channel(lit, sun.name), ALBEDO * expected[:, None],
                           rtol=1e-6, atol=0.0)
        assert report.sunlit_fraction[sun.name] == pytest.approx(
            (expected > 0).sum() / (total > 0).sum())
    assert report.shadow_rays == 2 * len(suns) * int(exposed[:, 3].sum())


def exposed_faces_by_hand(coords: np.ndarray) -> np.ndarray:
    occupied = {tuple(c) for c in coords}
    return np.array([[tuple(c + n) not in occupied for n in NORMALS] for c in coords])


def test_shadow_rays_agree_with_a_brute_force_oracle():
    """One ray from each face centre, faces weighted as if unoccluded ((1 + n_y) / 2)."""
    octree = build_octree(random_scene(seed=11, n=350, size=10))
    leaves = octree.node_coords(octree.depth)
    suns = np.array([sun_at("a", 130.0, 35.0).direction(), sun_at("b", 300.0, 70.0).direction()])
    vis, _ = sun_visibility(octree, suns, sky_rays=0, shadow_rays=1)
    exposed = exposed_faces_by_hand(leaves)
    weight = np.where(exposed, (1.0 + NORMALS[:, 1]) / 2.0, 0.0)
    assert np.allclose(vis.weight, weight.sum(axis=1))
    for k, sun in enumerate(suns):
        expected = np.zeros(len(leaves))
        for f, normal in enumerate(NORMALS):
            cos = float(normal @ sun)
            rows = np.flatnonzero(exposed[:, f] & (weight[:, f] > 0))
            if cos <= 0.0 or len(rows) == 0:
                continue
            centres = leaves[rows] + 0.5 + 0.5 * normal  # on the face plane
            hit, _ = first_hits(centres, np.tile(sun, (len(rows), 1)), leaves, 1.0)
            expected[rows] += weight[rows, f] * cos * (hit < 0)
        total = weight.sum(axis=1)
        seen = total > 0
        expected[seen] /= total[seen]
        assert np.allclose(vis.direct[k], expected, rtol=1e-6, atol=1e-7)
        assert 0.0 < (expected > 0).mean() < 1.0  # some faces lit, some in shadow


def _suns_each_quarter_and_on_a_grid_plane() -> np.ndarray:
    """Five sun directions: one from each quarter of the sky, one with ``x`` exactly 0."""
    suns = np.array([sun_at(f"s{k}", azimuth, elevation).direction()
                     for k, (azimuth, elevation) in enumerate(
                         [(40.0, 30.0), (130.0, 55.0), (220.0, 12.0), (310.0, 70.0),
                          (90.0, 25.0)])])
    suns[4] = [0.0, suns[4][1], math.hypot(suns[4][0], suns[4][2])]
    return suns


def _same_visibility_in_fewer_steps(fast, fast_cost, slow, slow_cost) -> None:
    """Two bakes of the same voxels and rays: identical terms and ray counts, the first in
    fewer traversal steps."""
    for name in ("direct", "sky", "weight", "surface"):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
    assert fast_cost["sky_rays"] == slow_cost["sky_rays"]
    assert fast_cost["shadow_rays"] == slow_cost["shadow_rays"]
    assert fast_cost["traversal_steps"] < slow_cost["traversal_steps"]


def test_rays_settled_over_column_tops_give_the_octree_bake():
    """Terrain with caves, ledges and hollows: walking the column tops first changes the
    cost, never a voxel's sky or sun visibility."""
    octree = build_octree(overhanging_terrain(seed=3, size=40))
    suns = np.array([sun_at("a", 130.0, 35.0).direction(), sun_at("b", 300.0, 10.0).direction()])
    walked, walked_cost = sun_visibility(octree, suns, sky_rays=12, shadow_rays=3, seed=1)
    plain, plain_cost = sun_visibility(octree, suns, sky_rays=12, shadow_rays=3, seed=1,
                                       columns=False)
    _same_visibility_in_fewer_steps(walked, walked_cost, plain, plain_cost)
    assert 0.0 < walked.sky[walked.surface].mean() < 1.0


def test_a_faces_shadow_rays_settled_together_change_the_cost_not_the_visibility(
        monkeypatch):
    """Shadow rays settled from their face's rear corner (``parallel_rays_clear``) get the
    visibility the same rays walked one by one get, in fewer steps; suns from each quarter
    and one along a grid plane."""
    octree = build_octree(overhanging_terrain(seed=6, size=40))
    suns = _suns_each_quarter_and_on_a_grid_plane()
    # Without horizon slopes, which would settle many of the same faces first.
    monkeypatch.setattr(bake_module, "_horizon_slopes", lambda columns: no_horizon_slopes())
    together, together_cost = sun_visibility(octree, suns, sky_rays=2, shadow_rays=5, seed=3)
    monkeypatch.setattr(bake_module, "_tops_ahead_per_sun",
                        lambda columns, dirs: np.zeros((len(dirs), 0), np.int32))
    alone, alone_cost = sun_visibility(octree, suns, sky_rays=2, shadow_rays=5, seed=3)
    _same_visibility_in_fewer_steps(together, together_cost, alone, alone_cost)
    assert together_cost["traversal_steps"] < 0.9 * alone_cost["traversal_steps"]
    lit = together.direct[:, together.surface]
    assert np.all((lit > 0).mean(axis=1) > 0.2) and np.all((lit == 0).mean(axis=1) > 0.01)


def test_rays_settled_by_the_horizon_change_the_cost_not_the_visibility(monkeypatch):
    """Sky rays steeper than their column's horizon (``svo.horizons``), and a face's shadow
    rays whose rear corner is, are clear without a walk: the visibility is that of every ray
    walked, in fewer steps, on ledges and caves and on a pillar field whose far pillars
    block flat rays; suns from each quarter and one along a grid plane."""
    suns = _suns_each_quarter_and_on_a_grid_plane()
    for scene in (overhanging_terrain(seed=6, size=40), pillar_field(seed=3, size=48)):
        octree = build_octree(scene)
        monkeypatch.undo()
        settled, settled_cost = sun_visibility(octree, suns, sky_rays=24, shadow_rays=5,
                                               seed=5)
        monkeypatch.setattr(bake_module, "_horizon_slopes", lambda columns: no_horizon_slopes())
        walked, walked_cost = sun_visibility(octree, suns, sky_rays=24, shadow_rays=5, seed=5)
        _same_visibility_in_fewer_steps(settled, settled_cost, walked, walked_cost)
        assert 0.0 < settled.sky[settled.surface].mean() < 1.0


@pytest.mark.parametrize("coords", [
    [(0, 0, 0)],  # one voxel: a 1×1 footprint
    [(0, y, 0) for y in (0, 1, 3, 4, 7)],  # one column with gaps
    [(x, 0, 0) for x in range(9)] + [(4, 3, 0)],  # a row one voxel deep, a ledge above
    [(x, y, z) for x in range(5) for z in range(5) for y in (0, 4)],  # a roof over a floor
])
def test_the_column_walk_agrees_with_the_octree_on_degenerate_footprints(coords):
    octree = octree_of(np.array(coords))
    suns = np.array([sun_at("a", 130.0, 35.0).direction(), sun_at("b", 0.0, 89.0).direction()])
    walked, _ = sun_visibility(octree, suns, sky_rays=32, shadow_rays=4, seed=2)
    plain, _ = sun_visibility(octree, suns, sky_rays=32, shadow_rays=4, seed=2, columns=False)
    for name in ("direct", "sky", "weight"):
        assert np.array_equal(getattr(walked, name), getattr(plain, name)), name


def test_an_isolated_voxel_sees_all_the_sky_above_and_half_from_its_sides():
    octree = octree_of(np.zeros((1, 3), int))
    vis, _ = sun_visibility(octree, np.array([[0.0, 1.0, 0.0]]), sky_rays=1000)
    # Weights are the faces' sky visibility: top 1, four sides 1/2 each.
    assert vis.weight[0] == pytest.approx(3.0, abs=0.06)
    assert vis.sky[0] == pytest.approx((1.0 + 4 * 0.25) / 3.0, abs=0.02)


def test_sky_directions_are_cosine_weighted_about_the_face_normal():
    samples = np.array([cmj_sample(s, 32, 32, 12345) for s in range(1024)])
    for face, normal in enumerate(NORMALS):
        dirs = np.array([cosine_direction(face, u1, u2) for u1, u2 in samples])
        assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0)
        cos = dirs @ normal
        assert np.all(cos >= 0.0)
        assert cos.mean() == pytest.approx(2.0 / 3.0, abs=0.01)  # E[cos θ] under cos weighting


@njit
def _cos_sin_turns(u, out):
    for i in range(u.shape[0]):
        out[i, 0], out[i, 1] = cos_sin_turns(u[i])


def test_turns_give_the_librarys_cosine_and_sine():
    """Within 1e-15 of NumPy's over random turns and every octant's edges (where the
    quarter turn split off changes), compiled and in plain Python alike."""
    edges = np.array([0.0, 1.0, 2.0 ** -60, 1.0 - 2.0 ** -53])
    octants = np.arange(9) / 8.0
    u = np.concatenate([np.random.default_rng(5).random(200_000), edges, octants,
                        np.nextafter(octants, 0.0), np.nextafter(octants, 1.0)])
    u = u[(u >= 0.0) & (u <= 1.0)]
    got = np.empty((len(u), 2))
    _cos_sin_turns(u, got)
    expected = np.stack([np.cos(2.0 * np.pi * u), np.sin(2.0 * np.pi * u)], axis=1)
    assert np.abs(got - expected).max() <= 1e-15
    assert np.allclose(cos_sin_turns.py_func(0.3), (math.cos(0.6 * math.pi),
                                                    math.sin(0.6 * math.pi)), rtol=0, atol=1e-15)


def test_buried_voxels_do_not_darken_coarse_levels():
    # A two-voxel-thick floor: the lower layer sees no sky and stays black, but the
    # 2×2×2 nodes above show the lit top layer's colour.
    octree = octree_of(slab(range(8), 0, range(8)), slab(range(8), 1, range(8)))
    lit, _ = bake_sun_lighting(octree, [TIMES_OF_DAY["noon"]], sky_rays=16)
    top = leaf_channel(lit, "noon")[leaf_index(octree, (2, 1, 2))]
    assert np.all(leaf_channel(lit, "noon")[leaf_index(octree, (2, 0, 2))] == 0.0)
    parents = octree.level_slice(octree.depth - 1)
    inner = (octree.node_coords(octree.depth - 1) == (1, 0, 1)).all(axis=1)
    assert np.allclose(lit.channel("noon")[parents][inner], top, rtol=1e-6)


def test_results_do_not_depend_on_threads_or_chunking(monkeypatch):
    octree = build_octree(random_scene(seed=5, n=700, size=14))
    suns = list(TIMES_OF_DAY.values())
    one, report_one = bake_sun_lighting(octree, suns, sky_rays=8, seed=3, threads=1)
    two, report_two = bake_sun_lighting(octree, suns, sky_rays=8, seed=3, threads=2)
    monkeypatch.setattr(bake_module, "CHUNK_VOXELS", 7)
    chunked, report_chunked = bake_sun_lighting(octree, suns, sky_rays=8, seed=3)
    for name in TIMES_OF_DAY:
        assert np.array_equal(one.channel(name), two.channel(name))
        assert np.array_equal(one.channel(name), chunked.channel(name))
    for key in ("sky_rays", "shadow_rays", "traversal_steps"):
        assert getattr(report_one, key) == getattr(report_two, key)
        assert getattr(report_one, key) == getattr(report_chunked, key)
    other_seed, _ = bake_sun_lighting(octree, suns, sky_rays=8, seed=4)
    assert not np.array_equal(one.channel("noon"), other_seed.channel("noon"))


def test_lit_channels_are_as_compact_as_the_albedo_and_render_the_same():
    """Beside 8-bit albedo the lit channels are RGB9E5, 4 bytes a node instead of 12: every
    node within a 511th of its largest float32 channel (or half the finest step, 2^-24),
    and renders of them above 60 dB against the float32 bake's. A float32 albedo keeps
    float32 lit channels."""
    octree = build_octree(random_scene(seed=8, n=1500, size=20))
    suns = [TIMES_OF_DAY["noon"], TIMES_OF_DAY["evening"]]
    packed, _ = bake_sun_lighting(octree, suns, sky_rays=8)
    full, _ = bake_sun_lighting(octree, suns, sky_rays=8, storage="float32")
    camera = Camera.look_at((34.0, 30.0, 40.0), (10.0, 6.0, 10.0), width=64)
    for sun in suns:
        codes, exact = packed.channel(sun.name), full.channel(sun.name)
        assert codes.dtype == np.uint32 and codes.nbytes * 3 == exact.nbytes
        decoded = packed.channel_linear(sun.name)
        bound = np.maximum(exact.max(axis=1) / 511, 2.0 ** -25)  # the format's finest step
        assert np.all(np.abs(decoded - exact).max(axis=1) <= bound)
        images = [render_reference(lit, camera, side=2, channel=sun.name).image
                  for lit in (full, packed)]
        assert images[0].max() > 0.05  # the camera sees lit voxels
        assert psnr(*images) >= 60.0  # quieter than 8-bit quantization (58.9 dB)
    float_albedo = build_octree(random_scene(seed=8, n=1500, size=20), colour_storage="float32")
    assert bake_sun_lighting(float_albedo, suns[:1], sky_rays=2)[0].channel("noon").dtype == (
        np.float32)
    with pytest.raises(VoxfieldError, match="channel storage"):
        bake_sun_lighting(octree, suns, storage="half")


def test_sun_directions_follow_the_compass():
    assert np.allclose(sun_at("e", 90.0, 0.0).direction(), [1.0, 0.0, 0.0], atol=1e-12)
    assert np.allclose(sun_at("s", 180.0, 0.0).direction(), [0.0, 0.0, 1.0], atol=1e-12)
    assert np.allclose(sun_at("n", 0.0, 45.0).direction(), [0.0, 0.5**0.5, -(0.5**0.5)])
    assert np.allclose(sun_at("z", 123.0, 90.0).direction(), [0.0, 1.0, 0.0], atol=1e-12)
    # Low suns are dimmer and redder than high ones; the sky fades after sunset.
    noon, evening = TIMES_OF_DAY["noon"], TIMES_OF_DAY["evening"]
    assert all(e < n for e, n in zip(evening.irradiance, noon.irradiance, strict=True))
    assert evening.irradiance[0] > evening.irradiance[2]
    assert sun_at("night", 0.0, -10.0).sky == (0.0, 0.0, 0.0)


def test_sun_lists_parse_names_thesis_times_and_angles():
    suns = parse_suns("morning,noon;dawn=90,5;135,-2.5")
    assert [s.name for s in suns] == ["morning", "noon", "dawn", "sun_135_m2p5"]
    assert (suns[2].azimuth_deg, suns[2].elevation_deg) == (90.0, 5.0)
    assert [s.name for s in parse_suns("time0,time1,time2,time3")] == [
        "morning", "evening", "noon", "afternoon"]
    assert [s.name for s in parse_suns("all")] == list(TIMES_OF_DAY)
    assert parse_suns("400,10")[0].azimuth_deg == 40.0


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("midnight", "unknown time of day"),
        ("10,95", "elevation"),
        ("nan,30", "finite"),
        ("noon,45", "mixes"),
        ("10,20,30", "AZIMUTH,ELEVATION"),
        ("", "no sun"),
        ("noon;;evening", "empty"),
        ("noon,time2", "more than once"),
        ("bad name=10,20", "channel name"),
        ("color=10,20", "albedo"),
    ],
)
def test_bad_sun_lists_are_refused(spec, message):
    with pytest.raises(VoxfieldError, match=message):
        parse_suns(spec)


def test_bad_bake_input_is_refused():
    floor = octree_of(slab(range(2), 0, range(2)))
    noon = TIMES_OF_DAY["noon"]
    with pytest.raises(VoxfieldError, match="elevation"):
        SunLight("x", 0.0, float("nan"), (1, 1, 1), (0, 0, 0))
    with pytest.raises(VoxfieldError, match="colour"):
        SunLight("x", 0.0, 10.0, (1, -1, 1), (0, 0, 0))
    with pytest.raises(VoxfieldError, match="no sun"):
        bake_sun_lighting(floor, [])
    with pytest.raises(VoxfieldError, match="share"):
        bake_sun_lighting(floor, [noon, noon])
    with pytest.raises(VoxfieldError, match="sky rays"):
        bake_sun_lighting(floor, [noon], sky_rays=-1)
    with pytest.raises(VoxfieldError, match="shadow rays"):
        bake_sun_lighting(floor, [noon], shadow_rays=0)
    with pytest.raises(VoxfieldError, match="sky rays"):
        bake_sun_lighting(floor, [noon], sky_rays=2.5)
    with pytest.raises(VoxfieldError, match="seed"):
        bake_sun_lighting(floor, [noon], seed=2**32)
    with pytest.raises(VoxfieldError, match="thread count"):
        bake_sun_lighting(floor, [noon], threads=0)


def run_light_command(argv):
    parser = argparse.ArgumentParser()
    add_light_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["light", *argv])
    return args.func(args)


def test_the_light_command_writes_the_octree_report_and_previews(tmp_path, capsys):
    out = tmp_path / "lit.npz"
    argv = ["builtin:sphere", "--times", "noon;dawn=90,5", "--sky-rays", "4",
            "--preview-size", "24", "--out", str(out)]
    assert run_light_command(argv) == 0
    lit = load_octree(out)
    assert {"noon", "dawn"} <= set(lit.attributes)
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["cost"]["rays"] > 0 and [s["name"] for s in report["suns"]] == ["noon", "dawn"]
    assert (tmp_path / "lit_noon.png").is_file() and (tmp_path / "lit_dawn.png").is_file()
    assert (tmp_path / "lit.png").is_file()
    assert "sun bake" in capsys.readouterr().out
    # the sheet names each preview's sun and where it stands; the files name only the channel
    suns = parse_suns("noon;dawn=90,5")
    previews = [(sun.name, np.zeros((4, 4, 3), np.float32)) for sun in suns]
    titles = [ax.get_title() for ax in preview_sheet(previews, suns, "builtin:sphere").axes]
    assert titles[:2] == [f"noon: azimuth {suns[0].azimuth_deg:g}°, elevation "
                          f"{suns[0].elevation_deg:g}°", "dawn: azimuth 90°, elevation 5°"]
    with pytest.raises(VoxfieldError, match="unknown time of day"):
        run_light_command(["builtin:sphere", "--times", "dusk", "--out", str(out)])


def test_lighting_a_lit_octree_again_keeps_the_record_of_its_kept_channels(tmp_path):
    """The record beside a re-lit octree listed only the new suns, and a channel of the same
    name was replaced without a word: the suns behind the kept channels were lost."""
    out = tmp_path / "lit.npz"
    quick = ["--sky-rays", "0", "--no-preview", "--quiet", "--out", str(out)]
    assert run_light_command(["builtin:sphere", "--times", "noon;east=90,45", *quick]) == 0
    first = json.loads(out.with_suffix(".json").read_text())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert run_light_command([str(out), "--times", "east=90,20", *quick]) == 0
    assert [str(w.message) for w in caught] == [
        f"{out} already has channel east; this bake replaces it"]
    second = json.loads(out.with_suffix(".json").read_text())
    assert [s["name"] for s in second["suns"]] == ["east"]
    assert second["suns"][0]["elevation_deg"] == 20.0 and second["replaced"] == ["east"]
    noon = [s for s in first["suns"] if s["name"] == "noon"]
    assert second["earlier_bakes"] == [{**first, "suns": noon}]
    assert set(load_octree(out).attributes) == {"color", "noon", "east"}
    # Newest first: each channel's sun from the bake that made it.
    assert run_light_command([str(out), "--times", "west=270,30", *quick]) == 0
    third = json.loads(out.with_suffix(".json").read_text())
    assert [[s["name"] for s in bake["suns"]] for bake in third["earlier_bakes"]] == [
        ["east"], ["noon"]]
    assert third["earlier_bakes"][0]["suns"] == second["suns"]
    assert "replaced" not in third
    # Without the record: said, and listed as such.
    out.with_suffix(".json").unlink()
    with pytest.warns(UserWarning, match="no record of the suns behind channels east, noon, "
                      "west of"):
        assert run_light_command([str(out), "--times", "dusk=280,5", *quick]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["unrecorded_channels"] == [
        "east", "noon", "west"]


def test_a_voxel_scene_s_own_channels_are_kept_as_its_own_not_as_unrecorded_suns(tmp_path):
    """A saved voxel scene with a channel of its own was taken for a lit octree: the bake
    noted "no record of the suns behind" a channel no sun made."""
    sphere = builtin_scene("sphere")
    mask = np.linspace(0.0, 1.0, len(sphere.coords), dtype=np.float32)[:, None].repeat(3, 1)
    scene = save_scene(replace(sphere, channels={"mask": mask}), tmp_path / "masked.npz")
    out = tmp_path / "lit.npz"
    notes = _notes_of([str(scene), "--times", "noon", "--sky-rays", "0", "--no-preview",
                       "--quiet", "--out", str(out)])
    assert notes == []
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["scene_channels"] == ["mask"]
    assert "unrecorded_channels" not in record and "earlier_bakes" not in record
    assert set(load_octree(out).attributes) == {"color", "mask", "noon"}


def _notes_of(argv) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert run_light_command(argv) == 0
    return [str(w.message) for w in caught]


def test_previews_a_bake_leaves_behind_are_named_not_removed(tmp_path):
    """``--no-preview`` over an earlier bake's outputs left its previews beside the new
    octree without a word, though they showed channels it no longer has (or has anew)."""
    out = tmp_path / "o.npz"
    quick = ["--sky-rays", "0", "--quiet", "--out", str(out)]
    small = ["--preview-size", "8"]
    assert _notes_of(["builtin:sphere", "--times", "noon;dawn=90,5", *small, *quick]) == []
    assert json.loads(out.with_suffix(".json").read_text())["previews"] == {
        "o_noon.png": ["noon"], "o_dawn.png": ["dawn"], "o.png": ["noon", "dawn"]}
    (tmp_path / "o_notes.png").write_bytes(b"the user's own")  # named by no record
    before = {p.name: p.read_bytes() for p in tmp_path.glob("o*.png")}
    # A new octree without dawn, no previews: every earlier one is stale.
    assert _notes_of(["builtin:sphere", "--times", "noon", "--no-preview", *quick]) == [
        f"o.png, o_dawn.png, o_noon.png beside {out} are previews of an earlier bake that "
        "no longer match it; left as they are"]
    assert {p.name: p.read_bytes() for p in tmp_path.glob("o*.png")} == before
    # Written again, they are fresh; lit again in place, the kept channels' previews stay
    # true, and only the re-baked channel's preview and the sheet that shows it go stale.
    assert _notes_of(["builtin:sphere", "--times", "noon;dawn=90,5", *small, *quick]) == []
    relit = [str(out), "--no-preview", *quick]
    assert _notes_of([*relit, "--times", "east=90,45"]) == []
    assert _notes_of([*relit, "--times", "dawn=90,8"]) == [
        f"{out} already has channel dawn; this bake replaces it",
        f"o.png, o_dawn.png beside {out} are previews of an earlier bake that no longer "
        "match it; left as they are"]
    # Still stale on the next bake, until written again or removed.
    assert _notes_of([*relit, "--times", "west=270,20"]) == [
        f"o.png, o_dawn.png beside {out} are previews of an earlier bake that no longer "
        "match it; left as they are"]
    (tmp_path / "o.png").unlink()
    assert _notes_of([*relit, "--times", "west=270,20"]) == [
        f"{out} already has channel west; this bake replaces it",
        f"o_dawn.png beside {out} is a preview of an earlier bake that no longer matches "
        "it; left as it is"]
    # Another octree lit from this one: this one's previews are not its to judge, on its
    # first bake or any later one (they were carried over and named stale).
    other = tmp_path / "p.npz"
    again = ["--sky-rays", "0", "--quiet", "--out", str(other)]
    assert _notes_of([str(out), "--times", "evening=270,20", *small, *again]) == []
    assert _notes_of([str(other), "--times", "noon", "--no-preview", *again]) == [
        f"{other} already has channel noon; this bake replaces it"]  # p's still show evening


def test_scheduled_bake_is_bit_identical_to_the_local_loop(monkeypatch, dask_client):
    """Voxel chunks as Dask tasks (threads, a LocalCluster) merge into exactly the arrays
    and counters of the plain loop, whatever order the chunks finish in."""
    monkeypatch.setattr(bake_module, "CHUNK_VOXELS", 37)  # many uneven chunks
    octree = build_octree(random_scene(5, n=900, size=14))
    suns = [SunLight("a", 30.0, 50.0, (1.0, 0.9, 0.8), (0.2, 0.3, 0.4)),
            SunLight("b", 200.0, 20.0, (1.0, 1.0, 1.0), (0.1, 0.1, 0.1))]
    dirs = np.array([s.direction() for s in suns])
    runs = {}
    for scheduler in (None, "threads", dask_client):
        vis, cost = bake_module.sun_visibility(octree, dirs, sky_rays=6, shadow_rays=2,
                                               seed=4, scheduler=scheduler)
        runs[str(type(scheduler).__name__ if scheduler is not None else None)] = (vis, cost)
    (base, base_cost), *others = runs.values()
    assert base.surface.sum() > 5 * 37
    for vis, cost in others:
        for name in ("direct", "sky", "weight", "surface"):
            np.testing.assert_array_equal(getattr(vis, name), getattr(base, name), err_msg=name)
        for key in ("sky_rays", "shadow_rays", "traversal_steps"):
            assert cost[key] == base_cost[key]


def test_chunks_shrink_with_the_rays_a_voxel_casts():
    # Ctrl-C is heard between kernel calls: 1024 sky and 1024 shadow rays a voxel made a
    # call of CHUNK_VOXELS last seconds
    assert bake_module.chunk_voxels(16, 4, 4) == bake_module.CHUNK_VOXELS  # the default
    sizes = [bake_module.chunk_voxels(sky, 4, 4) for sky in (16, 64, 256, 1024)]
    assert sizes == sorted(sizes, reverse=True) and sizes[1] < sizes[0]
    heavy = bake_module.chunk_voxels(1024, 1024, 4)
    assert heavy == bake_module.MIN_CHUNK_VOXELS
    assert heavy * (1024 + 1024 * 4) <= 8 * bake_module.CHUNK_VOXELS * 32  # bounded work


def test_a_preview_size_with_no_previews_is_noted_and_the_default_is_not(tmp_path):
    """``--no-preview --preview-size 8`` ran without a word about the size it dropped, where
    every other command notes an option its work does not read."""
    out = tmp_path / "lit.npz"
    quick = ["builtin:sphere", "--times", "noon", "--sky-rays", "0", "--shadow-rays", "1",
             "--quiet", "--out", str(out)]
    assert _notes_of([*quick, "--no-preview", "--preview-size", "8"]) == [
        "a bake with --no-preview takes no --preview-size (for the previews); ignored"]
    assert not (tmp_path / "lit_noon.png").exists()
    assert _notes_of([*quick, "--no-preview"]) == []
    assert _notes_of([*quick, "--preview-size", "8"]) == []
    with Image.open(tmp_path / "lit_noon.png") as preview:
        assert preview.size == (8, 8)
    assert _notes_of(quick) == []  # the default size, unsaid
    with Image.open(tmp_path / "lit_noon.png") as preview:
        assert preview.size == (256, 256)


@pytest.mark.parametrize("blocked", ["lit.json", "lit_noon.png", "lit.png"])
def test_every_output_of_light_is_checked_before_the_scene_opens(blocked, tmp_path, capsys,
                                                                 monkeypatch):
    """Only the octree's path was: a folder where the record or a preview goes failed after
    the bake (20 s and 1.7 GiB on a 2048² terrain)."""
    from voxfield.cli import cmd_light, main

    def no_scene(*args, **kwargs):
        raise AssertionError("the scene was opened")

    monkeypatch.setattr(cmd_light, "open_octree", no_scene)
    (tmp_path / blocked).mkdir()
    assert main(["light", "builtin:sphere", "--times", "noon",
                 "--out", str(tmp_path / "lit.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"voxfield: error: cannot use {tmp_path / blocked}: it is a folder, not a "
                   "file"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [blocked]
