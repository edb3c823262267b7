"""Renderers against independent facts: analytic images, LOD-grid equivalence, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.errors import VoxfieldError
from voxfield.render import Camera, orbit_camera, ray_query, render, render_lod, render_reference
from voxfield.render.adaptive import render_adaptive
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import TILE, tile_order
from voxfield.scene.builtin import pillars
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def pillar_octree():
    return build_octree(pillars(32))


def test_orthographic_view_of_a_flat_slab_is_its_colour_and_distance():
    xz = np.stack(np.meshgrid(np.arange(16), np.arange(16), indexing="ij"), -1).reshape(-1, 2)
    coords = np.c_[xz[:, 0], np.full(len(xz), 3), xz[:, 1]]
    octree = build_octree(VoxelScene(coords, np.tile([0.2, 0.4, 0.6], (len(xz), 1))),
                          colour_storage="float32")
    cam = Camera.orthographic((8, 10, 8), (0, -1, 0), (0, 0, -1), view_height=16, width=16)
    result = render_reference(octree, cam, side=4)
    assert np.allclose(result.image, [0.2, 0.4, 0.6])
    # The slab is at y = 0 after the build moves it to the origin: its top face is at y = 1.
    assert np.allclose(result.depth, 9.0)
    assert np.allclose(result.normal, [0, 1, 0])
    assert np.all(result.ray_count == 16) and np.all(result.hit_count == 16)
    assert np.all(result.finest_lod == 0)


def test_one_and_two_threads_give_identical_output(pillar_octree, small_jobs_in_parallel):
    lo, hi = pillar_octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=64)
    a = render_reference(pillar_octree, cam, side=4, seed=5, threads=1)
    b = render_reference(pillar_octree, cam, side=4, seed=5, threads=2)
    for name in ("image", "depth", "normal", "ray_count", "hit_count", "steps", "finest_lod"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_seed_changes_samples_but_not_counts_of_rays(pillar_octree):
    lo, hi = pillar_octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=48)
    a = render_reference(pillar_octree, cam, seed=1)
    b = render_reference(pillar_octree, cam, seed=2)
    assert a.total_rays == b.total_rays == 48 * 48 * 16
    assert not np.array_equal(a.image, b.image)


def test_lod_zero_with_one_sample_equals_reference_with_one_sample(pillar_octree):
    lo, hi = pillar_octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=64)
    ref = render_reference(pillar_octree, cam, side=1)
    lod = render_lod(pillar_octree, cam, lod=0)
    assert np.array_equal(ref.image, lod.image) and np.array_equal(ref.steps, lod.steps)


@pytest.mark.parametrize("lod", [1, 2])
def test_lod_image_equals_the_finest_render_of_the_lod_grid(lod):
    """Rendering LOD k must equal rendering, at LOD 0, a scene made of the LOD-k blocks."""
    scene = random_scene(7, n=400, size=16)
    octree = build_octree(scene, lod_colour="mean")  # a block shows its children's mean
    sl = octree.level_slice(octree.depth - lod)
    corners = octree.lod_voxels(lod)
    block = np.stack(np.meshgrid(*[np.arange(2**lod)] * 3, indexing="ij"), -1).reshape(-1, 3)
    coords = (corners[:, None, :] + block[None]).reshape(-1, 3)
    colors = np.repeat(octree.color[sl], len(block), axis=0)
    expanded = build_octree(VoxelScene(coords, colors))
    cam = Camera.look_at((-9.3, 21.7, 30.1), (8, 8, 8), fov_deg=50, width=48)
    a = render_lod(octree, cam, lod=lod)
    b = render_lod(expanded, cam, lod=0)
    assert np.array_equal(a.hit_count, b.hit_count)
    assert np.array_equal(a.depth, b.depth)
    np.testing.assert_allclose(a.image, b.image, atol=1e-6)
    assert np.all(a.finest_lod[a.hit_count > 0] == lod)


def test_cone_lod_coarsens_with_distance(pillar_octree):
    lo, hi = pillar_octree.voxel_bounds
    near = Camera.look_at((16, 20, 40), (16, 0, 16), fov_deg=60, width=64)
    far = Camera.look_at((16, 200, 400), (16, 0, 16), fov_deg=60, width=64)
    lod_near = render_lod(pillar_octree, near, lod=None).finest_lod
    lod_far = render_lod(pillar_octree, far, lod=None).finest_lod
    assert lod_far[lod_far >= 0].mean() > lod_near[lod_near >= 0].mean()
    # Fewer traversal steps when the cone stops early.
    full = render_lod(pillar_octree, far, lod=0)
    assert render_lod(pillar_octree, far, lod=None).total_steps < full.total_steps


def test_bad_renderer_options_raise(pillar_octree):
    cam = Camera.look_at((0, 0, 0), (1, 1, 1), width=8)
    with pytest.raises(VoxfieldError, match="unknown renderer"):
        render(pillar_octree, cam, renderer="magic")
    with pytest.raises(VoxfieldError, match="LOD must be"):
        render_lod(pillar_octree, cam, lod=99)
    with pytest.raises(VoxfieldError, match="no channel"):
        render_reference(pillar_octree, cam, channel="sunset")


@pytest.mark.parametrize(("call", "message"), [
    (lambda o, c: render_lod(o, c, lod=1.5), "LOD must be an integer"),
    (lambda o, c: render_lod(o, c, lod=True), "LOD must be an integer"),
    (lambda o, c: render_lod(o, c, lod=None, cone_scale=math.inf), "cone scale must be a finite"),
    (lambda o, c: render_lod(o, c, lod=None, cone_scale=math.nan), "cone scale must be a finite"),
    (lambda o, c: render_lod(o, c, lod=None, cone_scale=-1.0), "positive cone scale"),
    (lambda o, c: render_reference(o, c, side=2.5), "samples per pixel side must be an integer"),
    (lambda o, c: render_reference(o, c, side=True), "samples per pixel side must be an integer"),
    (lambda o, c: render_reference(o, c, side=2, seed=1.5), "seed must be an integer"),
    (lambda o, c: render_reference(o, c, side=2, seed=-1), "seed must be an integer"),
    (lambda o, c: render_reference(o, c, side=2, seed=2**32), "seed must be an integer"),
    (lambda o, c: render_error_aware(o, c, seed=0.5), "seed must be an integer"),
    (lambda o, c: render_error_aware(o, c, max_refinements=1.5), "refinements must be"),
    (lambda o, c: render_error_aware(o, c, base_lod=1.0), "base LOD must be an integer"),
    (lambda o, c: render_adaptive(o, c, base_lod=99), "base LOD must be an integer in 0.."),
    (lambda o, c: ray_query.trace(o, [[1, 40, 1]], [[0, -1, 0]], lod=0.5), "LOD must be"),
    (lambda o, c: ray_query.trace(o, [[1, 40, 1]], [[0, -1, 0]], tmin=math.nan), "tmin must"),
    (lambda o, c: ray_query.occluded(o, [[1, 40, 1]], [[0, -1, 0]], tmax=math.nan), "tmax"),
    (lambda o, c: ray_query.occluded(o, [[1, 40, 1]], [[0, -1, 0]], tmin="0"), "tmin must"),
])
def test_entry_points_refuse_numbers_a_kernel_cannot_take(pillar_octree, call, message):
    # Before, a float LOD, side or seed failed in Numba's type inference with pages of
    # text, and a NaN bound made every ray a miss without a word.
    cam = orbit_camera(*pillar_octree.voxel_bounds, size=8)
    with pytest.raises(VoxfieldError, match=message):
        call(pillar_octree, cam)


def test_numpy_integers_and_floats_render_as_python_ones(pillar_octree):
    cam = orbit_camera(*pillar_octree.voxel_bounds, size=16)
    a = render_reference(pillar_octree, cam, side=np.int64(2), seed=np.uint32(3))
    b = render_reference(pillar_octree, cam, side=2, seed=3)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.steps, b.steps)
    rays = ([[1.5, 40.0, 1.5]], [[0.1, -1.0, 0.2]])
    hit = ray_query.trace(pillar_octree, *rays, lod=np.int8(1), tmin=np.float32(0.5))
    same = ray_query.trace(pillar_octree, *rays, lod=1, tmin=0.5)
    assert hit.node[0] == same.node[0] and hit.t[0] == same.t[0]


def test_an_empty_segment_misses(pillar_octree):
    rays = ([[1.5, 40.0, 1.5]], [[0.0, -1.0, 0.0]])
    assert ray_query.trace(pillar_octree, *rays).hit[0]
    assert not ray_query.trace(pillar_octree, *rays, tmin=5.0, tmax=1.0).hit[0]
    assert not ray_query.occluded(pillar_octree, *rays, tmin=5.0, tmax=5.0).blocked[0]


@pytest.mark.parametrize(("height", "width"), [(16, 24), (13, 10)])
def test_tile_order_visits_each_pixel_once_tile_by_tile_in_quads(height, width):
    """Every pixel once; whole rows of 8×8 tiles are contiguous runs (the bands a render
    hands out); inside a full tile every four consecutive pixels form a 2×2 quad."""
    order = tile_order(height, width)
    assert np.array_equal(np.sort(order), np.arange(height * width))
    rows, cols = np.divmod(order, width)
    tile_rows = rows // TILE
    assert np.all(np.diff(tile_rows) >= 0)
    first = order[: TILE * TILE]  # the first tile, always full here (both sides >= 8)
    r, c = np.divmod(first, width)
    assert r.max() < TILE and c.max() < TILE
    for quad in range(0, TILE * TILE, 4):
        qr, qc = r[quad:quad + 4], c[quad:quad + 4]
        assert qr.max() - qr.min() == 1 and qc.max() - qc.min() == 1


@pytest.mark.parametrize("lod, side, columns, runs", [
    (0, 1, True, "render_pixels_over_columns"),  # a fixed level with the pyramid
    (0, 4, False, "render_pixels_in_packets"),  # supersampled, a fixed level, no pyramid
    (0, 1, False, "render_pixels_per_ray"),
    (None, 1, True, "render_pixels_cone_over_columns"),  # cone LOD with the pyramid
    (None, 1, False, "render_pixels_per_ray"),
])
def test_a_render_runs_only_the_kernel_of_its_traversal(pillar_octree, monkeypatch, lod, side,
                                                        columns, runs):
    """Each traversal has a kernel of its own so that a render compiles only what it runs:
    the others are never called, and the image is the one the chosen kernel draws."""
    from voxfield.kernels import primary

    kernels = ("render_pixels_over_columns", "render_pixels_in_packets",
               "render_pixels_per_ray", "render_pixels_cone_over_columns")
    calls = []

    def spy(name, real):
        def counted(*args):
            calls.append(name)
            return real(*args)
        return counted

    for name in kernels:
        monkeypatch.setattr(primary, name, spy(name, getattr(primary, name)))
    lo, hi = pillar_octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=24)
    result = render_lod(pillar_octree, cam, lod=lod, side=side, columns=columns)
    assert set(calls) == {runs}
    assert result.hit_count.sum() > 0


@pytest.mark.parametrize("arguments, keywords, words", [
    ((None, "camera"), {}, "Octree"),
    (("octree", None), {}, "Camera"),
    (("octree", "camera", "lod"), {"bogus": 1}, "takes no bogus"),
    (("octree", "camera", "error-aware"), {"decay": "x"}, "decay must be a number"),
    (("octree", "camera", "error-aware"), {"colour_term": None}, "colour term"),
    (("octree", "camera", "error-aware"), {"threshold": math.nan}, "threshold"),
    (("octree", "camera", "error-aware"), {"bright_ratio": "x", "lighting_aware": True},
     "bright ratio"),
])
def test_render_refuses_what_it_cannot_use_in_one_clear_error(pillar_octree, arguments,
                                                              keywords, words):
    """Each was an AttributeError or TypeError from deep inside the renderer."""
    camera = orbit_camera(*pillar_octree.voxel_bounds, size=8)
    given = {"octree": pillar_octree, "camera": camera}
    with pytest.raises(VoxfieldError, match=words):
        render(*(given.get(a, a) for a in arguments), **keywords)


@pytest.mark.parametrize("name", ["beam", "columns", "progress"])
@pytest.mark.parametrize("renderer", ["render_lod", "render_reference", "render_adaptive",
                                      "render_error_aware"])
def test_a_switch_of_every_renderer_takes_a_bool_not_any_truthy_object(renderer, name):
    """``beam="no"`` rendered with the beam on (a non-empty string is true), and an array
    for ``columns`` failed with NumPy's "truth value … is ambiguous"."""
    import voxfield.render as renderers

    octree = build_octree(pillars())
    camera = Camera.look_at((40.0, 40.0, 40.0), (16.0, 16.0, 16.0), width=4)
    draw = getattr(renderers, renderer)
    if name == "beam" and renderer in ("render_adaptive", "render_error_aware"):
        pytest.skip(f"{renderer} has no beam switch")
    for value in ("no", np.array([1, 2]), None):
        with pytest.raises(VoxfieldError, match=f"{name} must be True or False"):
            draw(octree, camera, **{name: value})
