"""Rendering from probes: the two analytic baselines (probe thesis §5.1), the light-field
render, compositing by depth (§8.1.2) and ``voxfield probe-render`` end to end."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from voxfield import cli
from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import texel_directions
from voxfield.lightfield import LightFieldOptions
from voxfield.lightfield.baselines import (
    box_proxy_lookup,
    environment_lookup,
    lookup_maps,
    nearest_probe,
)
from voxfield.lightfield.probe_render import (
    LOST_NOTE_SHARE,
    composite_by_depth,
    lost_rays_note,
    lost_share,
    probe_set_bounds,
    probes_seeing,
    render_from_probes,
    result_kinds,
)
from voxfield.metrics import psnr
from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions
from voxfield.render.camera import Camera
from voxfield.render.primary import render_lod
from voxfield.render.result import RenderResult
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo.build import build_octree

ROOM = 16  # outer size of the closed test room; its inside is [1, ROOM - 1]³


def random_probes(resolution: int = 8, count: int = 2, seed: int = 0) -> SimpleNamespace:
    """Probe-set-shaped arrays with random radiance: enough for the lookups."""
    rng = np.random.default_rng(seed)
    return SimpleNamespace(
        positions=rng.uniform(2.0, 10.0, (count, 3)), enabled=np.ones(count, bool),
        radiance=rng.random((count, resolution, resolution, 3)).astype(np.float16))


def room_scene() -> VoxelScene:
    """A closed room with one-voxel walls, each wall a checker of its own two colours, so any
    parallax error shows as misplaced squares."""
    n = ROOM
    idx = np.arange(n)
    x, y, z = np.meshgrid(idx, idx, idx, indexing="ij")
    wall = (x == 0) | (x == n - 1) | (y == 0) | (y == n - 1) | (z == 0) | (z == n - 1)
    coords = np.argwhere(wall)
    base = np.array([[0.8, 0.2, 0.2], [0.2, 0.8, 0.2], [0.2, 0.2, 0.8],
                     [0.8, 0.8, 0.2], [0.2, 0.8, 0.8], [0.8, 0.2, 0.8]], np.float32)
    face = np.select([coords[:, 0] == 0, coords[:, 0] == n - 1, coords[:, 1] == 0,
                      coords[:, 1] == n - 1, coords[:, 2] == 0], [0, 1, 2, 3, 4], 5)
    checker = ((coords // 4).sum(axis=1) % 2).astype(np.float32)
    color = base[face] * (0.4 + 0.6 * checker)[:, None]
    return VoxelScene(coords, color, name="room")


@pytest.fixture(scope="module")
def room():
    """The room's octree and one probe baked at its centre (exact LOD-0 radiance)."""
    octree = build_octree(room_scene())
    grid = ProbeGrid((ROOM / 2,) * 3, (1.0, 1.0, 1.0), (1, 1, 1))
    probes = bake_probes(octree, grid, BakeOptions(resolution=64, renderer="lod", lod=0))
    return octree, probes


# --------------------------------------------------------------------------- baselines


@pytest.mark.parametrize("resolution", [4, 8, 16])
def test_environment_lookup_returns_texels_at_texel_centres(resolution):
    probes = random_probes(resolution)
    dirs = texel_directions(resolution)
    expected = probes.radiance[1].reshape(-1, 3).astype(np.float32)
    for filter in ("bilinear", "nearest"):
        radiance, distance = environment_lookup(probes, 1, dirs, filter=filter)
        np.testing.assert_allclose(radiance, expected, atol=1e-6)
        assert np.isinf(distance).all()


def test_environment_lookup_ignores_where_the_ray_starts():
    probes = random_probes()
    dirs = np.random.default_rng(1).normal(size=(50, 3))
    a, _ = environment_lookup(probes, 0, dirs)
    b, _ = environment_lookup(probes, np.zeros(50, np.int64), dirs * 3.0)  # any length
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("box", [((0, 0, 0), (12, 12, 12)), ((-3, 1, 2), (20, 9, 40)),
                                 ((30, 30, 30), (31, 32, 33))])  # the last misses the probe
def test_box_proxy_is_the_environment_lookup_from_the_probe_centre(box):
    probes = random_probes(16)
    dirs = np.random.default_rng(2).normal(size=(400, 3))
    origins = np.tile(probes.positions[0], (len(dirs), 1))
    env, _ = environment_lookup(probes, 0, dirs)
    proxy, distance = box_proxy_lookup(probes, 0, origins, dirs, *box)
    np.testing.assert_allclose(proxy, env, atol=1e-5)
    assert (distance > 0).all()


def test_box_proxy_corrects_parallax_off_centre():
    probes = random_probes(16)
    probes.positions[0] = (5.0, 5.0, 5.0)
    dirs = np.random.default_rng(3).normal(size=(400, 3))
    origins = np.tile((8.0, 6.0, 3.0), (len(dirs), 1))
    env, _ = environment_lookup(probes, 0, dirs)
    proxy, distance, normal = box_proxy_lookup(probes, 0, origins, dirs, (0, 0, 0), (10, 10, 10),
                                               return_normal=True)
    assert (np.abs(proxy - env).max(axis=1) > 1e-3).mean() > 0.5
    # Every ray from inside leaves the box: finite distance to a wall that faces the ray.
    unit = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    hit = origins + distance[:, None] * unit
    on_wall = np.isclose(hit, 0.0, atol=1e-4) | np.isclose(hit, 10.0, atol=1e-4)
    assert np.isfinite(distance).all() and on_wall.any(axis=1).all()
    assert ((normal * unit).sum(axis=1) < 0).all()


def test_box_proxy_from_outside_reads_the_far_wall_and_misses_fall_back():
    probes = random_probes(8)
    probes.positions[0] = (5.0, 5.0, 5.0)
    origins = np.array([[5.0, 5.0, 20.0], [5.0, 5.0, 20.0], [5.0, 5.0, 20.0]])
    dirs = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    radiance, distance = box_proxy_lookup(probes, 0, origins, dirs, (0, 0, 0), (10, 10, 10))
    assert distance[0] == pytest.approx(20.0)  # through the near face to the back wall
    assert np.isinf(distance[1:]).all()  # box behind the ray; box beside it
    env, _ = environment_lookup(probes, 0, dirs[1:])
    np.testing.assert_array_equal(radiance[1:], env)


def test_nearest_probe_skips_disabled_probes():
    probes = random_probes(count=3)
    probes.positions[:] = [(0, 0, 0), (10, 0, 0), (20, 0, 0)]
    assert nearest_probe(probes, [(1, 0, 0), (9, 0, 0), (19, 0, 0)]).tolist() == [0, 1, 2]
    probes.enabled[1] = False
    assert nearest_probe(probes, [(9, 0, 0), (11, 0, 0)]).tolist() == [0, 2]
    with pytest.raises(VoxfieldError, match="disabled"):
        environment_lookup(probes, 1, [(1.0, 0.0, 0.0)])


def test_baselines_refuse_bad_input():
    probes = random_probes()
    with pytest.raises(VoxfieldError, match="M×3"):
        environment_lookup(probes, 0, np.ones((4, 2)))
    with pytest.raises(VoxfieldError, match="zero vector"):
        environment_lookup(probes, 0, np.zeros((1, 3)))
    with pytest.raises(VoxfieldError, match="outside"):
        environment_lookup(probes, 5, np.ones((1, 3)))
    with pytest.raises(VoxfieldError, match="empty"):
        box_proxy_lookup(probes, 0, np.ones((1, 3)), np.ones((1, 3)), (0, 0, 0), (1, -1, 1))
    with pytest.raises(VoxfieldError, match="filter"):
        environment_lookup(probes, 0, np.ones((1, 3)), filter="cubic")


@pytest.mark.parametrize("filter", ["bilinear", "nearest"])
def test_lookups_read_the_same_from_maps_made_once(filter):
    """A render converts its probes' maps once and reads them band after band: the answers
    must be those of converting them at every call."""
    probes = random_probes(16, count=5)
    rng = np.random.default_rng(4)
    which = rng.choice([1, 3, 4], 300)  # not 0 and 2: a map's place is not its index
    dirs = rng.normal(size=(300, 3))
    origins = rng.uniform(0.0, 12.0, (300, 3))
    maps = lookup_maps(probes, [4, 1, 3, 3], filter)  # any order, repeats
    assert maps.probes.tolist() == [1, 3, 4]
    np.testing.assert_array_equal(
        environment_lookup(probes, which, dirs, filter=filter, maps=maps)[0],
        environment_lookup(probes, which, dirs, filter=filter)[0])
    for a, b in zip(box_proxy_lookup(probes, which, origins, dirs, (0, 0, 0), (12, 12, 12),
                                     filter=filter, return_normal=True, maps=maps),
                    box_proxy_lookup(probes, which, origins, dirs, (0, 0, 0), (12, 12, 12),
                                     filter=filter, return_normal=True), strict=True):
        np.testing.assert_array_equal(a, b)


def test_lookup_maps_refuse_a_probe_they_lack_or_another_filter():
    probes = random_probes(8, count=4)
    maps = lookup_maps(probes, [1, 3])
    with pytest.raises(VoxfieldError, match="probe 2 is not among"):
        environment_lookup(probes, [1, 2, 3], np.ones((3, 3)), maps=maps)
    with pytest.raises(VoxfieldError, match="probe 0 is not among"):
        environment_lookup(probes, 0, np.ones((1, 3)), maps=maps)
    with pytest.raises(VoxfieldError, match="nearest filter"):
        environment_lookup(probes, 1, np.ones((1, 3)), filter="nearest", maps=maps)
    with pytest.raises(VoxfieldError, match="filter"):
        lookup_maps(probes, [1], "cubic")


# --------------------------------------------------------------------------- renders


def test_box_proxy_beats_the_environment_map_in_a_box_room(room):
    octree, probes = room
    camera = Camera.look_at((4.5, 6.0, 11.0), (12.0, 9.0, 2.0), fov_deg=70.0, width=48)
    direct = render_lod(octree, camera, lod=0).image
    inside = (np.ones(3), np.full(3, ROOM - 1.0))  # the walls' inner faces ARE the proxy
    proxy = render_from_probes(probes, camera, method="box-proxy", box=inside)
    env = render_from_probes(probes, camera, method="environment")
    proxy_psnr, env_psnr = psnr(direct, proxy.image), psnr(direct, env.image)
    assert proxy_psnr > env_psnr + 6.0, (proxy_psnr, env_psnr)
    assert proxy_psnr > 20.0, (proxy_psnr, env_psnr)
    # Depth: the proxy gives the distance to the walls, the environment map none.
    reference_depth = render_lod(octree, camera, lod=0).depth
    assert np.isinf(env.depth).all()
    np.testing.assert_allclose(proxy.depth, reference_depth, rtol=1e-4, atol=1e-3)
    assert (proxy.maps["probes_tried"] == 1).all()
    assert (proxy.maps["texel_fetches"] == 4).all()
    assert (proxy.maps["result_kind"] == result_kinds()["hit"]).all()
    assert (env.maps["result_kind"] == result_kinds()["environment"]).all()


def test_render_is_deterministic_and_thread_independent(room, small_jobs_in_parallel):
    _, probes = room
    camera = Camera.look_at((5.0, 7.0, 9.0), (9.0, 7.0, 2.0), width=24)
    a = render_from_probes(probes, camera, method="box-proxy", threads=1)
    b = render_from_probes(probes, camera, method="box-proxy")
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.depth, b.depth)


def test_a_render_reads_each_pixel_from_its_nearest_probe(room):
    """An orthographic view's rays start apart, so its pixels read several probes (their
    maps converted once for the whole render): each pixel is the lookup of its own."""
    _, probes = room
    grid = ProbeGrid((ROOM / 2,) * 3, (6.0, 6.0, 6.0), (2, 2, 2))
    several = bake_probes(build_octree(room_scene()), grid,
                          BakeOptions(resolution=16, renderer="lod", lod=0))
    camera = Camera.orthographic((8.0, 8.0, 8.0), (0.3, -0.2, -1.0), view_height=12.0, width=20)
    origins, dirs = camera.rays(side=1, seed=0)
    nearest = nearest_probe(several, origins)
    assert len(np.unique(nearest)) >= 4
    for method in ("environment", "box-proxy"):
        image = render_from_probes(several, camera, method=method).image.reshape(-1, 3)
        if method == "environment":
            expected, _ = environment_lookup(several, nearest, dirs)
        else:
            lo, hi = probe_set_bounds(several)
            expected, _ = box_proxy_lookup(several, nearest, origins, dirs, lo, hi)
        np.testing.assert_array_equal(image, expected)


def test_render_refuses_bad_input(room):
    _, probes = room
    camera = Camera.look_at((5.0, 7.0, 9.0), (9.0, 7.0, 2.0), width=8)
    with pytest.raises(VoxfieldError, match="method"):
        render_from_probes(probes, camera, method="raster")
    with pytest.raises(VoxfieldError, match="Camera"):
        render_from_probes(probes, "top", method="environment")
    with pytest.raises(VoxfieldError, match="proxy box"):
        render_from_probes(probes, camera, method="box-proxy", box=((0, 0, 0), (0, 0, 0)))
    with pytest.raises(VoxfieldError, match="pair of corners"):
        render_from_probes(probes, camera, method="box-proxy", box=(1, 2, 3))


def test_probe_set_bounds_is_the_fitted_box(room):
    octree, _ = room
    lo, hi = octree.voxel_bounds
    grid = ProbeGrid.fit(lo, hi, (3, 1, 2))
    fake = SimpleNamespace(grid=grid, positions=grid.positions)
    got_lo, got_hi = probe_set_bounds(fake)
    np.testing.assert_allclose(got_lo, lo, atol=1e-9)
    np.testing.assert_allclose(got_hi, hi, atol=1e-9)


def test_light_field_from_a_probe_at_the_camera_matches_the_direct_render(room):
    try:
        from voxfield.lightfield.trace import trace_light_field  # noqa: F401
    except ImportError as exc:
        pytest.skip(f"voxfield.lightfield.trace is not importable yet ({exc})")
    octree, _ = room
    eye = (6.0, 7.0, 10.0)
    grid = ProbeGrid(eye, (1.0, 1.0, 1.0), (1, 1, 1))
    probes = bake_probes(octree, grid, BakeOptions(resolution=128, renderer="lod", lod=0))
    camera = Camera.look_at(eye, (10.0, 8.0, 2.0), fov_deg=60.0, width=32)
    direct = render_lod(octree, camera, lod=0)
    light_field = render_from_probes(probes, camera, method="light-field",
                                     options=LightFieldOptions(colour_filter="nearest"))
    # From the probe centre the march ends in the texel of ω itself: only texel-sized
    # sampling differences at colour edges remain (the 32-pixel view at 60° has pixels about
    # the size of the 128² map's texels).
    assert psnr(direct.image, light_field.image) > 20.0
    close = np.abs(light_field.image - direct.image).max(axis=2) < 0.05
    assert close.mean() > 0.9
    found = np.isfinite(light_field.depth)
    assert found.mean() > 0.95
    np.testing.assert_allclose(light_field.depth[found], direct.depth[found], rtol=0.05, atol=0.3)
    assert (light_field.maps["probes_tried"][found] >= 1).all()
    assert (light_field.maps["texel_fetches"][found] >= 1).all()
    # A PackedProbes renders the same, by every method.
    from voxfield.lightfield.packed import PackedProbes

    packed = PackedProbes.from_probe_set(probes)
    for method in ("light-field", "box-proxy"):
        np.testing.assert_array_equal(render_from_probes(packed, camera, method=method).image,
                                      render_from_probes(probes, camera, method=method).image)


# --------------------------------------------------------------------------- compositing


def _flat(depth, value: float, renderer: str) -> RenderResult:
    h, w = np.shape(depth)
    return RenderResult(
        image=np.full((h, w, 3), value, np.float32), depth=np.asarray(depth, np.float32),
        normal=np.zeros((h, w, 3), np.float32), ray_count=np.ones((h, w), np.int32),
        hit_count=np.isfinite(depth).astype(np.int32), steps=np.full((h, w), 3, np.int64),
        finest_lod=np.zeros((h, w), np.int8), renderer=renderer,
        maps={"probe": np.full((h, w), 7 if value > 0.5 else 2)})


def test_composite_by_depth_keeps_the_nearer_surface():
    inf = np.inf
    a = _flat([[1.0, 5.0], [inf, 2.0]], 0.25, "a")
    b = _flat([[2.0, 4.0], [3.0, 2.0]], 0.75, "b")
    c = composite_by_depth(a, b)
    assert c.depth.tolist() == [[1.0, 4.0], [3.0, 2.0]]
    assert c.image[..., 0].tolist() == [[0.25, 0.75], [0.75, 0.25]]  # a tie keeps a
    assert c.maps["source"].tolist() == [[0, 1], [1, 0]]
    assert c.maps["probe"].tolist() == [[2, 7], [7, 2]]
    assert (c.ray_count == 2).all() and (c.steps == 6).all()
    with pytest.raises(VoxfieldError, match="different sizes"):
        composite_by_depth(a, _flat([[1.0]], 0.0, "tiny"))


def test_composite_puts_an_octree_object_into_a_probe_render(room):
    """§8.1.2: the probe render supplies the static room, the octree renderer one object."""
    octree, probes = room
    camera = Camera.look_at((4.5, 6.0, 11.0), (12.0, 9.0, 2.0), fov_deg=70.0, width=32)
    inside = (np.ones(3), np.full(3, ROOM - 1.0))
    probe_view = render_from_probes(probes, camera, method="box-proxy", box=inside)
    cube = VoxelScene(np.argwhere(np.ones((2, 2, 2), bool)) + (8, 7, 5),
                      np.full((8, 3), 1.0, np.float32), name="cube")
    dynamic = render_lod(build_octree_at(cube), camera, lod=0)
    mixed = composite_by_depth(probe_view, dynamic)
    object_pixels = np.isfinite(dynamic.depth)
    assert object_pixels.any()
    np.testing.assert_array_equal(mixed.image[object_pixels], dynamic.image[object_pixels])
    np.testing.assert_array_equal(mixed.image[~object_pixels], probe_view.image[~object_pixels])


def build_octree_at(scene: VoxelScene):
    """An octree whose coordinates are the scene's own (``build_octree`` moves the minimum
    corner to the origin, so a voxel at the origin anchors it)."""
    anchored = VoxelScene(np.vstack([scene.coords, [[0, 0, 0]]]),
                          np.vstack([scene.color, [[0.0, 0.0, 0.0]]]), name=scene.name)
    return build_octree(anchored)


# --------------------------------------------------------------------------- command line


@pytest.fixture
def run():
    """``voxfield.cli.main``."""
    return cli.main


@pytest.fixture(scope="module")
def cornell_folder(tmp_path_factory):
    """A tiny probe-set folder of builtin:cornell, as ``voxfield bake`` writes it."""
    from voxfield.probes.folder_bake import bake_to_folder
    from voxfield.svo.open import open_octree

    octree = open_octree("builtin:cornell")
    grid = ProbeGrid.fit(*octree.voxel_bounds, (2, 1, 1))
    out = tmp_path_factory.mktemp("probes") / "cornell"
    bake_to_folder(octree, grid, BakeOptions(resolution=16, renderer="lod", lod=0), out,
                   scheduler="serial")
    return out


def test_command_writes_image_and_maps(run, cornell_folder, tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "env.png"
    code = run(["probe-render", str(cornell_folder), "--method", "environment", "--size", "24",
                "--camera", "oblique", "--counters", "--out", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "texel fetches per pixel" in printed and "wrote" in printed
    assert Image.open(out).size == (24, 24)
    for suffix in ("_probes_tried.png", "_texel_fetches.png", "_kind.png", "_summary.json"):
        assert (tmp_path / f"env{suffix}").is_file()


def test_command_light_field_options(run, cornell_folder, tmp_path, capsys):
    out = tmp_path / "lf.png"
    code = run(["probe-render", str(cornell_folder), "--marcher", "dda", "--ordering",
                "nearest", "--epsilon", "adaptive", "--epsilon-k", "2", "--backface",
                "--size", "16", "--camera", "oblique", "--counters", "--out", str(out)])
    assert code == 0
    assert "probes:light-field" in capsys.readouterr().out
    summary = json.loads((tmp_path / "lf_summary.json").read_text())
    assert summary["probes_tried_per_pixel"] >= 1.0 and sum(summary["pixels_by_kind"].values())
    with pytest.raises(SystemExit) as refused:  # by the parser, in the option's name
        run(["probe-render", str(cornell_folder), "--epsilon-value", "-1", "--quiet",
             "--out", str(out)])
    assert refused.value.code == 2
    assert "argument --epsilon-value: " in capsys.readouterr().err


def test_command_compares_with_the_octree_and_writes_depth(run, cornell_folder, tmp_path,
                                                          capsys):
    from voxfield.render.image_io import load_exr

    out = tmp_path / "box.exr"
    code = run(["probe-render", str(cornell_folder), "--method", "box-proxy", "--scene",
                "builtin:cornell", "--compare", "--size", "16", "--eye", "16,16,45",
                "--target", "16,14,0", "--out", str(out), "--quiet"])
    assert code == 0
    channels = load_exr(out)
    assert channels["RGB"].shape == (16, 16, 3) and channels["Z"].shape == (16, 16)
    assert np.isfinite(channels["Z"]).any()
    assert (tmp_path / "box_compare.png").is_file()


def test_command_lights_its_pngs_for_display_not_its_figures(run, cornell_folder, tmp_path,
                                                            capsys):
    """An albedo probe render's PNG is lit by the display key light as render's is (the
    Cornell box's white walls read as one flat grey otherwise); --albedo keeps it flat, and
    the measured figures do not change."""
    from PIL import Image

    view = ["--scene", "builtin:cornell", "--camera", "room", "--size", "16", "--compare"]
    printed = {}
    for name, extra in (("lit", []), ("flat", ["--albedo"])):
        assert run(["probe-render", str(cornell_folder), *view, *extra, "--out",
                    str(tmp_path / f"{name}.png")]) == 0
        printed[name] = [line for line in capsys.readouterr().out.splitlines()
                         if "PSNR" in line or "bound" in line]
    assert printed["lit"] == printed["flat"] and printed["lit"]
    lit, flat = (np.asarray(Image.open(tmp_path / f"{n}.png"), np.int64)
                 for n in ("lit", "flat"))
    assert np.all(lit <= flat + 1)  # the key light scales a colour by at most 1
    assert np.mean(lit.sum(-1) < flat.sum(-1) - 6) > 0.5


def test_command_notes_a_compared_view_of_one_colour(run, cornell_folder, tmp_path, capsys):
    """A room of one colour: the light field's false hits show that colour too, so its
    PSNR against the octree measures outlines alone (a sponge of one colour measured 33 dB
    and SSIM 0.98 over a trace that hit the wrong surface at 98 % of its pixels, without a
    word). --compare says so; over the Cornell box's colours it does not."""
    from voxfield.probes.folder_bake import bake_to_folder
    from voxfield.svo.io import save_octree

    room = room_scene()
    grey = np.full_like(room.color, 0.5)
    octree = build_octree(VoxelScene(room.coords, grey, name="grey"))
    scene = save_octree(octree, tmp_path / "grey.npz")
    folder = tmp_path / "grey_probes"
    bake_to_folder(octree, ProbeGrid.fit(*octree.voxel_bounds, (2, 1, 1)),
                   BakeOptions(resolution=8, renderer="lod", lod=0), folder, scheduler="serial")
    view = ["--camera", "room", "--size", "16", "--compare", "--quiet"]
    assert run(["probe-render", str(folder), "--scene", str(scene), *view, "--out",
                str(tmp_path / "grey.png")]) == 0
    err = capsys.readouterr().err
    assert "every voxel the view sees has one colour in 'albedo'" in err
    assert len(err.splitlines()) == 1
    assert run(["probe-render", str(cornell_folder), "--scene", "builtin:cornell", *view,
                "--out", str(tmp_path / "cornell.png")]) == 0
    assert "one colour" not in capsys.readouterr().err
    # Without --compare nothing is measured, and nothing is said.
    assert run(["probe-render", str(folder), "--scene", str(scene), "--camera", "room",
                "--size", "16", "--quiet", "--out", str(tmp_path / "plain.png")]) == 0
    assert "one colour" not in capsys.readouterr().err


def test_command_says_when_no_probe_answers_most_pixels(run, cornell_folder, tmp_path,
                                                       capsys):
    """From above the box its probes, inside it, see none of the roof the camera sees: the
    light field falls back almost everywhere, and the command says so; from inside, not."""
    for camera, lost in (("top", True), ("room", False)):
        out = tmp_path / f"{camera}.png"
        assert run(["probe-render", str(cornell_folder), "--camera", camera, "--size", "16",
                    "--counters", "--out", str(out)]) == 0
        err = capsys.readouterr().err
        kinds = json.loads((tmp_path / f"{camera}_summary.json").read_text())["pixels_by_kind"]
        seen = 256 - kinds.get("miss", 0)
        share = (kinds.get("fallback", 0) + kinds.get("unknown", 0)) / max(seen, 1)
        assert (share > LOST_NOTE_SHARE) == lost
        assert ("were answered by no probe of this probe set" in err) == lost
        assert "voxfield: error" not in err
    # --quiet silences bars and summaries, not word that the picture is the fallback.
    assert run(["probe-render", str(cornell_folder), "--camera", "top", "--size", "16",
                "--quiet", "--out", str(tmp_path / "quiet.png")]) == 0
    quiet = capsys.readouterr()
    assert quiet.out == "" and "were answered by no probe" in quiet.err
    # Not for a baseline, which answers every ray from the nearest probe.
    assert run(["probe-render", str(cornell_folder), "--camera", "top", "--method",
                "environment", "--size", "16", "--out", str(tmp_path / "env.png")]) == 0
    assert "answered by no probe" not in capsys.readouterr().err


def _kinds_result(counts: dict[str, int], method: str = "light-field") -> RenderResult:
    """A one-row render whose ``result_kind`` map holds ``counts`` pixels of each kind."""
    codes = result_kinds()
    kind = np.concatenate([np.full(n, codes[name], np.int8) for name, n in counts.items()])
    result = _flat(np.ones((1, kind.size)), 0.5, method)
    result.maps["result_kind"] = kind.reshape(1, -1)
    result.params["method"] = method
    return result


def test_the_lost_share_leaves_proven_empty_sky_out():
    """An object seen against a wide sky: 10 of its 30 pixels fell back. Counted against
    all 100 pixels that is 10 % and would pass unnoticed; among the 30 the probes did not
    prove empty it is a third of the picture of the object, and the note speaks."""
    sky_wide = _kinds_result({"miss": 70, "hit": 20, "fallback": 6, "unknown": 4})
    assert lost_share(sky_wide) == pytest.approx(10 / 30)
    note = lost_rays_note(lost_share(sky_wide), "this probe set")
    assert note is not None and note.startswith("33% of the light field's pixels that no "
                                                "probe proved empty")
    assert note.endswith("they show the fallback, not the trace")
    # With the fallback off those pixels are black, as the note then says.
    assert lost_rays_note(lost_share(sky_wide), "this probe set", fallback=False).endswith(
        "they are left unknown (black; --no-fallback), not the trace")
    # The same object filling the view: 10 of 100 lost, under the note's share.
    close_up = _kinds_result({"hit": 90, "fallback": 10})
    assert lost_share(close_up) == pytest.approx(0.1)
    assert lost_share(close_up) < LOST_NOTE_SHARE
    assert lost_rays_note(lost_share(close_up), "this probe set") is None
    # All sky: nothing to judge. A baseline answers every ray.
    assert lost_share(_kinds_result({"miss": 50})) == 0.0
    assert lost_share(_kinds_result({"fallback": 50}, method="environment")) == 0.0


def test_the_default_view_stands_among_the_probes(run, cornell_folder, tmp_path, capsys):
    """A probe set of a room is looked through from inside its grid by default (the old
    default, top, stood above the Cornell box's roof, where no probe answers a ray); a
    grid in one corner of the scene is looked through from inside that corner."""
    import argparse

    from voxfield.cli.cmd_probe_render import probe_view
    from voxfield.probes.folder_bake import bake_to_folder
    from voxfield.probes.probe_folder import open_probe_set
    from voxfield.svo.open import open_octree

    assert run(["probe-render", str(cornell_folder), "--size", "16", "--counters", "--out",
                str(tmp_path / "default.png")]) == 0
    assert run(["probe-render", str(cornell_folder), "--camera", "room", "--size", "16",
                "--out", str(tmp_path / "room.png")]) == 0
    assert (tmp_path / "default.png").read_bytes() == (tmp_path / "room.png").read_bytes()
    kinds = json.loads((tmp_path / "default_summary.json").read_text())["pixels_by_kind"]
    assert kinds.get("fallback", 0) + kinds.get("unknown", 0) < 0.2 * 256

    octree = open_octree("builtin:cornell")
    lo, hi = octree.voxel_bounds
    corner = ProbeGrid.fit(lo, lo + 0.4 * (hi - lo), (2, 2, 2))
    folder = tmp_path / "corner"
    bake_to_folder(octree, corner, BakeOptions(resolution=8, renderer="lod", lod=0), folder,
                   scheduler="serial")
    probes = open_probe_set(folder)
    args = argparse.Namespace(camera="auto", eye=None, target=None, fov=None, size=8,
                              scene=None)
    view = probe_view(args, folder, probes, None, (lo, hi))
    box_lo, box_hi = probe_set_bounds(probes)
    assert np.all(view.position > box_lo) and np.all(view.position < box_hi)


def test_the_default_view_of_an_object_s_probes_is_from_around_it(tmp_path):
    """A solid ball where the room view's eye stands, in a 2x2x2 grid whose probes all lie
    outside it: no probe sees into the ball, and the default looks from around the grid's
    box instead (as from inside T-Rex.vox's grid, whose room eye lies in the model). A
    room's probes keep the room view (the test above)."""
    import argparse

    from voxfield.cli.cmd_probe_render import probe_view
    from voxfield.cli.options import camera
    from voxfield.probes.folder_bake import bake_to_folder
    from voxfield.probes.probe_folder import open_probe_set

    side = 64
    eye = np.array([0.57, 0.72, 0.74]) * side  # room_camera's eye in a box of this side
    grid = np.indices((side,) * 3).reshape(3, -1).T
    ball = grid[np.linalg.norm(grid + 0.5 - eye, axis=1) < 7.0]
    corners = np.array([[0, 0, 0], [side - 1] * 3])  # the octree's box is the grid's
    coords = np.concatenate([ball, corners])
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    folder = tmp_path / "ball"
    bake_to_folder(octree, ProbeGrid.fit(lo, hi, (2, 2, 2)),
                   BakeOptions(resolution=16, renderer="lod", lod=0), folder, scheduler="serial")
    probes = open_probe_set(folder)
    assert np.all(np.linalg.norm(probes.positions - eye, axis=1) > 10.0)  # none in the ball
    args = argparse.Namespace(camera="auto", eye=None, target=None, fov=None, size=24,
                              scene=None)
    view = probe_view(args, folder, probes, None, (lo, hi))
    room, orbit = (camera(argparse.Namespace(**{**vars(args), "camera": name}),
                          probe_set_bounds(probes)) for name in ("room", "orbit"))
    assert np.linalg.norm(room.position - eye) < 3.0  # the room view stands in the ball
    assert probes_seeing(probes, room.position) == 0
    assert np.array_equal(view.position, orbit.position)
    assert np.array_equal(view.forward, orbit.forward)
    assert lost_share(render_from_probes(probes, view)) < LOST_NOTE_SHARE


def test_a_point_is_seen_by_the_probes_whose_distance_maps_reach_it():
    """Two probes either side of a solid wall: each sees points on its own side, up to the
    wall, and none behind it or inside it; a disabled probe sees nothing."""
    n = 24
    coords = np.argwhere(np.ones((n, n, 4), bool)) + (0, 0, 10)  # a wall, z in [10, 14)
    box = np.array([[0, 0, 0], [n - 1, n - 1, n - 1]])  # the octree's box: 24 voxels a side
    coords = np.concatenate([coords, box])
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))
    grid = SimpleNamespace(positions=np.array([[12.0, 12.0, 4.0], [12.0, 12.0, 20.0]]),
                           enabled=np.array([True, True]))
    probes = bake_probes(octree, grid, BakeOptions(resolution=32, renderer="lod", lod=0))
    assert probes_seeing(probes, (12.0, 12.0, 8.0)) == 1  # in front of the wall, one side
    assert probes_seeing(probes, (8.0, 15.0, 18.0)) == 1  # the other side
    assert probes_seeing(probes, (12.0, 12.0, 12.0)) == 0  # in the wall
    assert probes_seeing(probes, (12.5, 12.5, 9.0)) == 1  # a voxel short of it
    probes.enabled[0] = False
    assert probes_seeing(probes, (12.0, 12.0, 8.0)) == 0


def test_the_default_view_of_a_terrain_s_probes_is_from_above(run, tmp_path, capsys):
    """Probes laid over a terrain are looked down on, as ``render`` looks at a terrain."""
    folder = tmp_path / "desert"
    assert run(["bake", "terrain:desert", "--footprint", "32", "--grid", "surface:2x2@4",
                "--resolution", "8", "--quiet", "--out", str(folder)]) == 0
    for camera in ("auto", "top"):
        assert run(["probe-render", str(folder), "--camera", camera, "--size", "8", "--quiet",
                    "--out", str(tmp_path / f"{camera}.png")]) == 0
    assert (tmp_path / "auto.png").read_bytes() == (tmp_path / "top.png").read_bytes()


def test_command_bad_input_exits_2(run, cornell_folder, tmp_path, capsys):
    def error(argv) -> str:
        assert run(argv) == 2
        return capsys.readouterr().err

    assert "no such probe-set folder" in error(
        ["probe-render", str(tmp_path / "missing"), "--method", "environment", "--quiet"])
    assert "--scene" in error(["probe-render", str(cornell_folder), "--method", "environment",
                               "--compare", "--quiet"])
    assert ".png or .exr" in error(["probe-render", str(cornell_folder), "--method",
                                    "environment", "--out", str(tmp_path / "x.txt"), "--quiet"])
    assert "together" in error(["probe-render", str(cornell_folder), "--method", "box-proxy",
                                "--box-min", "0,0,0", "--quiet"])
    empty = tmp_path / "not_probes"
    empty.mkdir()
    assert "probes.json" in error(["probe-render", str(empty), "--method", "environment",
                                   "--quiet"])
    with pytest.raises(SystemExit) as exc:
        run(["probe-render", str(cornell_folder), "--method", "raster"])
    assert exc.value.code == 2


def _strict_json(text: str):
    def refuse(constant):
        raise AssertionError(f"{constant} is not JSON")
    return json.loads(text, parse_constant=refuse)


def test_command_writes_strict_json_and_words_a_depth_never_found(run, cornell_folder,
                                                                  tmp_path, capsys):
    """From above the box most pixels fall back: the depth percentiles are infinite, which
    the summary wrote as `Infinity` (not JSON) and the console as "inf voxels"."""
    out = tmp_path / "top.png"
    assert run(["probe-render", str(cornell_folder), "--scene", "builtin:cornell", "--camera",
                "top", "--size", "16", "--compare", "--counters", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    summary = _strict_json((tmp_path / "top_summary.json").read_text())
    assert summary["compare"]["depth"]["p99"] is None
    assert "99th percentile no depth (missed or fell back)" in printed and "inf" not in printed
    # The environment baseline has no depth to classify its pixels by: no bare "pixels:".
    assert run(["probe-render", str(cornell_folder), "--scene", "builtin:cornell", "--method",
                "environment", "--camera", "room", "--size", "16", "--compare", "--out",
                str(tmp_path / "env.png")]) == 0
    assert "pixels: \n" not in capsys.readouterr().out + "\n"


@pytest.mark.parametrize("extra, note", [
    (["--marcher", "dda", "--step", "0.1"],
     "the light-field render with the dda marcher takes no --step (for the march3d marcher)"),
    (["--method", "environment", "--marcher", "dda", "--epsilon", "constant"],
     "the environment render takes no --marcher (for light-field), --epsilon (for "
     "light-field)"),
    (["--filter", "nearest"], "the light-field render takes no --filter (for "
     "environment/box-proxy)"),
    (["--method", "environment", "--box-min", "0,0,0", "--box-max", "1,1,1"],
     "the environment render takes no --box-min/--box-max (for box-proxy)"),
    (["--spp-side", "4"], "the light-field render takes no --spp-side (for --compare)"),
    (["--method", "environment", "--no-fallback"],
     "the environment render takes no --no-fallback (for light-field)"),
    (["--method", "box-proxy", "--step", "0.5"],
     "the box-proxy render takes no --step (for light-field)"),
    (["--footprint", "64", "--seed", "5"],
     "the light-field render takes no --footprint (for --scene), --seed (for --scene)"),
    (["--epsilon-k", "4"],
     "the footprint epsilon takes no --epsilon-k (for adaptive/adaptive-text/angular)"),
    (["--epsilon", "angular", "--epsilon-value", "2", "--epsilon-front", "1"],
     "the angular epsilon takes no --epsilon-value (for constant/slope/footprint), "
     "--epsilon-front (for footprint)"),
])
def test_command_notes_options_its_render_does_not_read(run, cornell_folder, tmp_path, capsys,
                                                       extra, note):
    """Each of these rendered the same image as without them, and said nothing."""
    assert run(["probe-render", str(cornell_folder), "--camera", "room", "--size", "8",
                "--quiet", *extra, "--out", str(tmp_path / "x.png")]) == 0
    assert capsys.readouterr().err.strip() == f"voxfield: note: {note}; ignored"


def test_command_notes_nothing_for_options_its_render_reads(run, cornell_folder, tmp_path,
                                                           capsys):
    for extra in (["--marcher", "march3d", "--step", "0.25"], ["--method", "environment",
                  "--filter", "nearest"], ["--method", "box-proxy", "--box-min", "0,0,0",
                  "--box-max", "32,32,32"], [],
                  ["--epsilon-value", "2", "--epsilon-front", "1"],
                  ["--epsilon", "adaptive", "--epsilon-k", "4"],
                  ["--epsilon", "slope", "--epsilon-value", "2"]):
        assert run(["probe-render", str(cornell_folder), "--camera", "room", "--size", "8",
                    "--quiet", *extra, "--out", str(tmp_path / "x.png")]) == 0
        assert capsys.readouterr().err == "", extra


def test_command_notes_an_eye_no_probe_sees(run, tmp_path, capsys):
    """The light field answers rays from an eye inside a solid block as if it stood in the
    open (a picture of surfaces it cannot see, or every ray lost with no word of why):
    probe-render without --scene says that no probe sees the eye, in one note; an eye in
    the open beside the block, or outside the grid's box where its rays enter the box, gets
    no such note."""
    from voxfield.probes.folder_bake import bake_to_folder

    axis = np.arange(8, 24)
    block = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    corners = np.array([[0, 0, 0], [31, 31, 31], [0, 31, 0], [31, 0, 31]])
    coords = np.concatenate([block, corners])
    colours = np.random.default_rng(3).random((len(coords), 3)).astype(np.float32)
    octree = build_octree(VoxelScene(coords, colours, name="block"))
    folder = tmp_path / "block_probes"
    bake_to_folder(octree, ProbeGrid.fit(*octree.voxel_bounds, (2, 2, 2)),
                   BakeOptions(resolution=16, renderer="lod", lod=0), folder, scheduler="serial")
    notes = {}
    for name, eye in (("inside", "13,13,14"), ("open", "3,28,4"), ("outside", "-20,40,-20")):
        assert run(["probe-render", str(folder), "--eye", eye, "--target", "16,16,16",
                    "--size", "8", "--quiet", "--out", str(tmp_path / f"{name}.png")]) == 0
        notes[name] = capsys.readouterr().err
    assert notes["inside"].startswith("voxfield: note: no probe of this set sees the camera's "
                                      "eye at (13, 13, 14)")
    assert len(notes["inside"].splitlines()) == 1  # not the lost-pixels note as well
    assert "camera's eye" not in notes["open"] + notes["outside"]
    assert run(["probe-render", str(folder), "--eye", "13,13,14", "--target", "16,16,16",
                "--method", "environment", "--size", "8", "--quiet", "--out",
                str(tmp_path / "environment.png")]) == 0
    assert "camera's eye" not in capsys.readouterr().err  # a baseline reads no depth
