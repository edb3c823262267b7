"""Per-pixel start bounds from the column-top pyramid drawn into the image: never past a
pixel's hit, inf only where its ray misses, and renders that change by nothing."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import hollow_shell_terrain, overhanging_terrain, random_scene
from voxfield.render import Camera, orbit_camera, render_lod, render_reference
from voxfield.render.beam import coarsest_cone_level, raster_beam
from voxfield.render.ray_query import trace
from voxfield.svo import build_octree
from voxfield.svo.column_tops import octree_column_tops

SAME = ("image", "depth", "normal", "ray_count", "hit_count", "finest_lod")
SCENES = [random_scene(3, n=500, size=20), overhanging_terrain(1), hollow_shell_terrain(2)]


def assert_same(a, b):
    for name in SAME:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def pinhole_cameras(octree):
    lo, hi = octree.voxel_bounds
    centre = (np.asarray(lo) + np.asarray(hi)) / 2.0
    yield orbit_camera(lo, hi, size=41)
    yield Camera.look_at((centre[0], hi[1] + 30, centre[2]), tuple(centre),
                         (0.0, 0.0, -1.0), fov_deg=80, width=37, height=29)
    yield Camera.look_at((lo[0] - 9.5, hi[1] + 4.25, lo[2] - 7.0), tuple(centre),
                         fov_deg=60, width=33, height=33)


@pytest.mark.parametrize("scene", SCENES, ids=["random", "overhangs", "hollow"])
@pytest.mark.parametrize("side", [1, 3])
def test_bound_never_passes_a_hit(scene, side):
    """Brute force: every ray of a pixel (its centre's, or each of its ``side``×``side``
    sub-samples') traced from the eye hits no earlier than the pixel's bound; a pixel
    without a bound (inf) has no ray that hits."""
    octree = build_octree(scene)
    columns = octree_column_tops(octree)
    for cam in pinhole_cameras(octree):
        for lod in (0, 1):
            stop = octree.depth - lod
            beam = raster_beam(cam, columns, stop_level=stop, depth=octree.depth,
                               whole_pixel=side > 1)
            assert beam is not None and beam.block == 1
            origins, directions = cam.rays(side=side, seed=7)
            hits = trace(octree, origins, directions, lod=lod)
            bound = np.repeat(beam.bound.ravel(), side * side)  # the rays are pixel-major
            assert np.all(bound[hits.hit] <= hits.t[hits.hit])
            assert not np.any(np.isinf(bound) & hits.hit)
            assert np.any(np.isfinite(bound))
            assert beam.total_steps > 0


def test_supersampled_bound_covers_the_whole_pixel():
    """The centre ray's bound may pass an off-centre ray's hit (which is why supersampled
    pixels get a bound of their own): over a terrain of steps, some pixel's centre bound lies
    beyond the hit of one of its corner-near rays, and the whole-pixel bound never does."""
    octree = build_octree(overhanging_terrain(1))
    columns = octree_column_tops(octree)
    passed = 0
    for cam in pinhole_cameras(octree):
        centre = raster_beam(cam, columns, stop_level=octree.depth, depth=octree.depth)
        whole = raster_beam(cam, columns, stop_level=octree.depth, depth=octree.depth,
                            whole_pixel=True)
        origins, directions = cam.rays(side=4, seed=3)
        hits = trace(octree, origins, directions)
        t = np.where(hits.hit, hits.t, np.inf).reshape(-1, 16)
        passed += int(np.sum(centre.bound.ravel() > t.min(axis=1)))
        assert np.all(whole.bound.ravel() <= t.min(axis=1))
    assert passed > 0


@pytest.mark.parametrize("scene", SCENES[1:], ids=["overhangs", "hollow"])
def test_render_is_unchanged(scene):
    """A render started from the drawn bounds equals one from the camera, pixel for pixel,
    with one ray a pixel or several."""
    octree = build_octree(scene)
    for cam in pinhole_cameras(octree):
        for lod in (0, 1):
            assert_same(render_lod(octree, cam, lod=lod, beam=True),
                        render_lod(octree, cam, lod=lod, beam=False))
        assert_same(render_reference(octree, cam, side=3, beam=True),
                    render_reference(octree, cam, side=3, beam=False))


@pytest.mark.parametrize("scene", SCENES, ids=["random", "overhangs", "hollow"])
def test_cone_lod_renders_from_the_bound_drawn_for_their_coarsest_nodes(scene):
    """Cone-LOD rays start at the bound drawn with the boxes rounded out to the largest node
    their cone accepts anywhere (``coarsest_cone_level``): every pixel as from the eye, the
    nodes hit never larger than that level, and cones wide enough that coarse nodes reaching
    above the column tops and past the voxels' box are hit. Drawn for voxels instead, the
    bound would start rays past such hits."""
    octree = build_octree(scene)
    lo, hi = octree.voxel_bounds
    centre = (np.asarray(lo) + np.asarray(hi)) / 2.0
    far = Camera.look_at((hi[0] + 70.0, hi[1] + 45.0, lo[2] - 60.0), tuple(centre),
                         fov_deg=30, width=40, height=32)
    coarse_hits = 0
    for cam in [*pinhole_cameras(octree), far]:
        for cone_scale, side in ((1.0, 1), (6.0, 1), (6.0, 2)):
            coarsest = coarsest_cone_level(octree, cam, cone_scale, side)
            drawn = render_lod(octree, cam, lod=None, cone_scale=cone_scale, side=side,
                               beam=True)
            assert_same(drawn, render_lod(octree, cam, lod=None, cone_scale=cone_scale,
                                          side=side, beam=False))
            assert drawn.finest_lod.max() <= coarsest
            coarse_hits += int(np.count_nonzero(drawn.finest_lod >= 2))
    assert coarse_hits > 0


def test_camera_among_the_columns_falls_back():
    """A box across the eye plane has no bounded picture: no raster bound."""
    octree = build_octree(overhanging_terrain(1))
    lo, hi = octree.voxel_bounds
    inside = Camera.look_at((lo[0] + 3.5, lo[1] + 1.5, lo[2] + 3.5), (hi[0], lo[1] + 1.5, hi[2]),
                            fov_deg=70, width=16, height=16)
    assert raster_beam(inside, octree_column_tops(octree), stop_level=octree.depth,
                       depth=octree.depth) is None
    ortho = Camera.orthographic((10, 60, 10), (0.3, -1, 0.2), (0, 0, -1), view_height=30,
                                width=16)
    assert raster_beam(ortho, octree_column_tops(octree), stop_level=octree.depth,
                       depth=octree.depth) is None


@pytest.mark.parametrize("reach", [0.0, 0.5])
def test_direction_limits_hold_every_ray_of_the_pixel(reach):
    """Brute force: no ray through a point within ``reach`` of a pixel's centre moves faster
    along an axis than its limit allows, for an orthonormal camera and a skewed one; for the
    orthonormal one (every camera voxfield makes) the limit is nearly met (within 1 %)."""
    from voxfield.kernels.camera_rays import camera_ray
    from voxfield.kernels.column_raster import direction_limits

    straight = Camera.look_at((3.0, 40.0, -2.0), (10.0, 0.0, 12.0), fov_deg=75, width=9,
                              height=7)
    params = straight.params.copy()
    params[7:10] += 0.3 * params[10:13]  # right tilted towards up: not orthogonal
    rng = np.random.default_rng(0)
    for cam in (straight.params, params):
        limits = direction_limits(cam, 9, 7, reach)
        for row in range(7):
            for col in range(9):
                offsets = rng.uniform(-reach, reach, (400, 2))
                offsets[:4] = [[-reach, -reach], [-reach, reach], [reach, -reach], [reach, reach]]
                fastest = np.zeros(3)
                for fx, fy in offsets:
                    d = camera_ray(cam, col + 0.5 + fx, row + 0.5 + fy, 9, 7)[3:]
                    fastest = np.maximum(fastest, np.abs(d))
                assert np.all(fastest * limits[row, col] <= 1.0 + 1e-12)
                if cam is straight.params:
                    assert np.all(fastest * limits[row, col] >= 0.99)


def test_slanting_rays_start_past_the_nearest_box_point():
    """A pixel keeps the larger of a box's nearest distance and its gaps over the pixel's
    direction limits: towards the edges of a view from above, the bound lies beyond the
    nearest point (``test_bound_never_passes_a_hit`` shows it still never passes a hit)."""
    from voxfield.kernels.column_raster import direction_limits, draw_cell_boxes

    octree = build_octree(overhanging_terrain(1))
    columns = octree_column_tops(octree)
    lo, hi = octree.voxel_bounds
    centre = (np.asarray(lo) + np.asarray(hi)) / 2.0
    cam = Camera.look_at((centre[0], hi[1] + 30, centre[2]), tuple(centre), (0.0, 0.0, -1.0),
                         fov_deg=80, width=37, height=29)
    params = cam.params
    to_camera = np.linalg.inv(np.array([params[4:7], params[7:10], params[10:13]]).T)
    bounds = []
    for limits in (np.ones((29, 37, 3)), direction_limits(params, 37, 29, 0.5)):
        nearest = np.full((1, 29, 37), np.inf)
        assert draw_cell_boxes(params, to_camera, 37, 29, columns.tops, columns.floors, 0,
                               int(columns.level_width[0]), int(columns.level_depth[0]), 0, 0,
                               0.5, limits, 1, nearest, np.zeros(1, np.int64))
        bounds.append(nearest[0])
    nearest_point, slanted = bounds
    finite = np.isfinite(nearest_point)
    assert np.array_equal(finite, np.isfinite(slanted))
    assert np.all(slanted[finite] >= nearest_point[finite])
    assert np.mean(slanted[finite] > nearest_point[finite] * 1.01) > 0.1
