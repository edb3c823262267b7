"""Variance-adaptive baseline: the thesis's cut-offs, background exclusion and ray counting."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from random_scenes import hollow_shell_terrain, overhanging_terrain
from voxfield.errors import VoxfieldError
from voxfield.render import Camera, adaptive, orbit_camera, render_lod, render_reference
from voxfield.render.adaptive import (
    CLASS_SIDE,
    PixelRefinement,
    refinement_classes,
    render_adaptive,
    window_variance,
)
from voxfield.render.beam import raster_beam, raster_cells, raster_level
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.column_tops import octree_column_tops


def test_classes_follow_the_cut_offs_on_a_synthetic_variance_image():
    variance = np.array([[0.0, 0.249, 0.25, 0.5], [0.749, 0.75, 1.0, 7.0]])
    valid = np.ones_like(variance, bool)
    valid[0, 0] = False
    assert refinement_classes(variance, valid).tolist() == [[-1, 0, 1, 1], [1, 2, 2, 2]]


def test_window_variance_matches_a_direct_computation_and_skips_background():
    rng = np.random.default_rng(0)
    lum = rng.random((7, 9))
    valid = rng.random((7, 9)) > 0.3
    got = window_variance(lum, valid)
    for y in range(7):
        for x in range(9):
            if not valid[y, x]:
                assert got[y, x] == 0
                continue
            win = lum[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2]
            ok = valid[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2]
            vals = win[ok]
            assert np.isclose(got[y, x], np.sum((vals - vals.mean()) ** 2))


def test_refined_pixels_add_rays_by_class():
    # Black and white stripes: every window straddling an edge has high variance.
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], 1)
    color = np.repeat(((x.ravel() // 4) % 2)[:, None], 3, axis=1).astype(float)
    octree = build_octree(VoxelScene(coords, color))
    cam = Camera.orthographic((16, 5, 16), (0, -1, 0), (0, 0, -1), view_height=32, width=32)
    result = render_adaptive(octree, cam, base_lod=0)
    classes = result.maps["refinement_class"]
    expected = np.choose(classes.clip(0), [1 + s * s if s > 1 else 1 for s in CLASS_SIDE])
    assert np.array_equal(result.ray_count, expected)
    assert (classes == 2).any() and (classes == 0).any()
    # Flat regions away from edges keep their single ray.
    assert result.ray_count[16, 2] == 1


def _stripes():
    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], 1)
    color = np.repeat(((x.ravel() // 4) % 2)[:, None], 3, axis=1).astype(float)
    cam = Camera.orthographic((16, 5, 16), (0, -1, 0), (0, 0, -1), view_height=32, width=32)
    return build_octree(VoxelScene(coords, color)), cam


def test_iterations_past_the_last_change_change_nothing():
    # A pixel's class only rises and tops out at 2, so the refinement settles; the loop stops
    # there, and a large count returns what a few do.
    octree, cam = _stripes()
    few = render_adaptive(octree, cam, base_lod=0, iterations=3)
    many = render_adaptive(octree, cam, base_lod=0, iterations=1000)
    for name in ("image", "ray_count", "steps"):
        assert np.array_equal(getattr(few, name), getattr(many, name)), name
    for name in ("variance", "refinement_class"):
        assert np.array_equal(few.maps[name], many.maps[name]), name


def test_a_subnormal_normalisation_refines_every_varied_pixel_without_a_warning():
    """Dividing by 1e-320 overflows to infinity, which is over every cut-off: the render is
    the one a merely tiny normalisation gives, and NumPy's overflow warning (shown on the
    command line as a note) is not raised."""
    octree, cam = _stripes()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        subnormal = render_adaptive(octree, cam, base_lod=0, variance_normalisation=1e-320)
    tiny = render_adaptive(octree, cam, base_lod=0, variance_normalisation=1e-30)
    assert np.array_equal(subnormal.maps["refinement_class"], tiny.maps["refinement_class"])
    assert np.array_equal(subnormal.image, tiny.image)
    assert (tiny.maps["refinement_class"] == 2).any() and (tiny.maps["refinement_class"] == 0).any()


@pytest.mark.parametrize(("options", "message"), [
    ({"iterations": 1.5}, "iterations must be an integer"),
    ({"iterations": True}, "iterations must be an integer"),
    ({"iterations": -1}, "iterations must be an integer ≥ 0"),
    ({"variance_normalisation": "1"}, "variance normalisation must be a number"),
    ({"variance_normalisation": 0.0}, "must be positive"),
])
def test_bad_options_are_refused(options, message):
    octree, cam = _stripes()
    with pytest.raises(VoxfieldError, match=message):
        render_adaptive(octree, cam, base_lod=0, **options)


def _refinement_scene(scene):
    octree = build_octree(scene)
    lo, hi = octree.voxel_bounds
    return octree, orbit_camera(lo, hi, size=40)


@pytest.mark.parametrize("scene", [overhanging_terrain(1), hollow_shell_terrain(2)],
                         ids=["overhangs", "hollow"])
def test_refinements_from_the_drawn_bound_change_no_pixel(scene, monkeypatch):
    """Refinement rays started at their pixel's drawn bound (every pass drawing) or at the
    block beam (none drawing) give the same pixels and rays; the drawing's cells are shared
    out over the whole image, the block beam's steps over the refined pixels alone."""
    octree, cam = _refinement_scene(scene)
    renders = {}
    for name, saving in (("drawn", 10**9), ("beam", 0)):
        monkeypatch.setattr(adaptive, "DRAWN_BOUND_SAVING", saving)
        renders[name] = render_adaptive(octree, cam, base_lod=1)
    drawn, beam = renders["drawn"], renders["beam"]
    for name in ("image", "depth", "normal", "ray_count", "hit_count", "finest_lod"):
        assert np.array_equal(getattr(drawn, name), getattr(beam, name)), name
    kept = drawn.maps["refinement_class"] == 0
    assert kept.any() and (drawn.maps["refinement_class"] > 0).any()
    first = render_lod(octree, cam, lod=1)
    assert np.array_equal(beam.steps[kept], first.steps[kept])
    share = raster_beam(cam, octree_column_tops(octree), stop_level=octree.depth,
                        depth=octree.depth, whole_pixel=True).image_steps(cam.height,
                                                                         cam.width)
    assert np.array_equal(drawn.steps[kept], first.steps[kept] + share[kept])


def test_a_pass_draws_once_it_has_rays_enough_and_later_passes_reuse_it(monkeypatch):
    """``DRAWN_BOUND_SAVING`` steps a ray against the drawing's cells: one refined pixel
    starts at the block beam (no other pixel's steps change), a pass refining most of the
    image draws (every other pixel takes its share of the cells once), and a later small
    pass starts at that drawing (no more shares). The refined pixels are the reference
    render's, whichever start they had."""
    octree, cam = _refinement_scene(overhanging_terrain(1))
    cells = raster_cells(octree_column_tops(octree), raster_level(
        cam, octree_column_tops(octree), stop_level=octree.depth, depth=octree.depth,
        whole_pixel=True))
    side = 2
    assert side * side * adaptive.DRAWN_BOUND_SAVING < cells  # one pixel: no drawing
    result = render_lod(octree, cam, lod=1)
    truth = render_reference(octree, cam, side=side)
    refinement = PixelRefinement(octree, cam, result, 0, octree.kernel_colours("albedo"))
    pixels = np.flatnonzero(result.hit_count.ravel() > 0)
    lone, many, last = pixels[:1], pixels[1:-1], pixels[-1:]
    before = result.steps.copy().ravel()
    refinement.refine(lone, side)
    others = np.setdiff1d(np.arange(before.size), lone)
    assert np.array_equal(result.steps.ravel()[others], before[others])
    assert len(many) * side * side * adaptive.DRAWN_BOUND_SAVING >= cells
    before = result.steps.copy().ravel()
    refinement.refine(many, side)
    assert refinement.drawn is not None
    share = refinement.drawn.image_steps(cam.height, cam.width).ravel()
    assert share.sum() == cells
    others = np.setdiff1d(np.arange(before.size), many)
    assert np.array_equal(result.steps.ravel()[others], before[others] + share[others])
    before = result.steps.copy().ravel()

    def no_block_beam(*args, **kwargs):
        raise AssertionError("a pass after the drawing started at the block beam")

    monkeypatch.setattr(adaptive, "primary_beam", no_block_beam)
    refinement.refine(last, side)
    others = np.setdiff1d(np.arange(before.size), last)
    assert np.array_equal(result.steps.ravel()[others], before[others])
    for name in ("image", "depth", "normal", "hit_count"):
        got = getattr(result, name).reshape(-1, *getattr(result, name).shape[2:])
        want = getattr(truth, name).reshape(-1, *getattr(truth, name).shape[2:])
        assert np.array_equal(got[pixels], want[pixels]), name


def test_passes_of_a_round_too_small_alone_draw_together(monkeypatch):
    """``refine_round`` decides on its passes' rays together: a 2×2 and a 4×4 pass that would
    each start at the block beam alone pay for the drawing together, so the first draws
    (every pixel takes its share once) and the second starts there; the refined pixels are
    the reference renders'."""
    octree, cam = _refinement_scene(overhanging_terrain(1))
    pyramid = octree_column_tops(octree)
    cells = raster_cells(pyramid, raster_level(cam, pyramid, stop_level=octree.depth,
                                               depth=octree.depth, whole_pixel=True))
    result = render_lod(octree, cam, lod=1)
    pixels = np.flatnonzero(result.hit_count.ravel() > 0)
    saving = adaptive.DRAWN_BOUND_SAVING
    fours = pixels[: cells // (4 * saving)]  # each pass just short of paying alone
    sixteens = pixels[len(fours):][: cells // (16 * saving)]
    assert len(fours) * 4 * saving < cells and len(sixteens) * 16 * saving < cells
    assert (len(fours) * 4 + len(sixteens) * 16) * saving >= cells
    alone = PixelRefinement(octree, cam, render_lod(octree, cam, lod=1), 0,
                            octree.kernel_colours("albedo"))
    alone.refine(fours, 2)
    alone.refine(sixteens, 4)
    assert alone.drawn is None
    before = result.steps.copy().ravel()
    together = PixelRefinement(octree, cam, result, 0, octree.kernel_colours("albedo"))
    searches = []
    monkeypatch.setattr(adaptive, "primary_beam",
                        lambda *args, **kwargs: searches.append(1))  # never called
    together.refine_round([(fours, 2), (sixteens, 4), (pixels[:0], 4)])
    assert together.drawn is not None and not searches and together.round_rays == 0
    share = together.drawn.image_steps(cam.height, cam.width).ravel()
    others = np.setdiff1d(np.arange(before.size), np.concatenate([fours, sixteens]))
    assert np.array_equal(result.steps.ravel()[others], before[others] + share[others])
    for side, chosen in ((2, fours), (4, sixteens)):
        truth = render_reference(octree, cam, side=side)
        for name in ("image", "depth", "normal", "hit_count"):
            got = getattr(result, name).reshape(-1, *getattr(result, name).shape[2:])
            want = getattr(truth, name).reshape(-1, *getattr(truth, name).shape[2:])
            assert np.array_equal(got[chosen], want[chosen]), name


@pytest.mark.parametrize("scene", [overhanging_terrain(1), hollow_shell_terrain(2)],
                         ids=["overhangs", "hollow"])
@pytest.mark.parametrize("kind", ["pinhole", "orthographic"])
def test_refining_every_pixel_costs_what_a_reference_render_does(scene, kind):
    """Every renderer counts alike: 4×4 refinements of every pixel of a LOD-1 render add
    exactly a 4×4 reference render's steps to each pixel, the share of its start bounds'
    search included (the drawing's under a pinhole camera, the block beam's under an
    orthographic one, where nothing is drawn), and leave the reference's pixels."""
    octree, cam = _refinement_scene(scene)
    if kind == "orthographic":
        lo, hi = (np.asarray(b, float) for b in octree.voxel_bounds)
        centre = (lo + hi) / 2.0
        cam = Camera.orthographic((centre[0], hi[1] + 20.0, centre[2]), (0.3, -1.0, 0.2),
                                  (0.0, 0.0, -1.0), view_height=float(hi[0] - lo[0]), width=32)
    result = render_lod(octree, cam, lod=1)
    first_steps = result.steps.copy()
    refinement = PixelRefinement(octree, cam, result, 0, octree.kernel_colours("albedo"))
    refinement.refine(np.arange(cam.width * cam.height), 4)
    assert (refinement.drawn is None) == (kind == "orthographic")
    truth = render_reference(octree, cam, side=4)
    assert np.array_equal(result.steps - first_steps, truth.steps)
    for name in ("image", "depth", "normal", "hit_count"):
        assert np.array_equal(getattr(result, name), getattr(truth, name)), name


def test_a_camera_the_bound_cannot_be_drawn_for_refines_from_the_block_beam():
    """A camera among the columns (a box across its eye plane): the drawing is tried once,
    given up, and every pass starts at the block beam, with the reference's pixels."""
    octree = build_octree(overhanging_terrain(1))
    lo, hi = octree.voxel_bounds
    inside = Camera.look_at((lo[0] + 3.5, lo[1] + 1.5, lo[2] + 3.5),
                            (hi[0], lo[1] + 1.5, hi[2]), fov_deg=70, width=24, height=24)
    result = render_lod(octree, inside, lod=1)
    refinement = PixelRefinement(octree, inside, result, 0, octree.kernel_colours("albedo"))
    # Drawable as far as the pyramid and the camera's kind go.
    assert refinement.drawing_cells is not None
    for pixels in (np.arange(0, 576, 2), np.arange(1, 576, 2)):
        refinement.refine(pixels, 4)
        assert refinement.drawn is None and refinement.drawing_cells is None
    truth = render_reference(octree, inside, side=4)
    for name in ("image", "depth", "normal", "hit_count"):
        assert np.array_equal(getattr(result, name), getattr(truth, name)), name
