"""Direct light with LOD-chosen shadow rays (EA §3.2.2, figs 3.4–3.6), checked against:

- an analytic case: one emitting voxel over a floor, no occluder — the rendered pixel equals
  the irradiance integral over the voxel's faces (brute-force quadrature here);
- properties: refining every node reproduces the reference exactly, an infinite threshold is
  the distance baseline, any thread count gives the same image and counters;
- the issue's done-when: in the test scene the distance-LOD beam is cut off and the
  error-aware one is not, measured as light reaching the floor behind the grid.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from voxfield.cli.cmd_shadows import register as add_shadow_parser
from voxfield.errors import VoxfieldError
from voxfield.kernels.direct_light import distance_lod
from voxfield.render.camera import Camera, beam_camera
from voxfield.render.direct_light import (
    emitter_faces,
    light_on_surface,
    render_direct_light,
)
from voxfield.scene.shadow_box import shadow_box, shadow_box_layout
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

FLOOR_ALBEDO = 0.5
EMISSION = 12.0
LAMP = (8, 5, 8)


@pytest.fixture(scope="module")
def lamp():
    """A 16² floor (top face at y = 1) under one emitting voxel."""
    x, z = np.meshgrid(np.arange(16), np.arange(16), indexing="ij")
    floor = np.stack([x.ravel(), np.zeros(x.size, int), z.ravel()], axis=1)
    coords = np.concatenate([floor, [LAMP]])
    color = np.full((len(coords), 3), FLOOR_ALBEDO)
    color[-1] = 1.0
    emission = np.zeros_like(color)
    emission[-1] = EMISSION
    return build_octree(VoxelScene(coords, color, emission=emission, name="lamp"))


@pytest.fixture(scope="module")
def box():
    return build_octree(shadow_box())


def analytic_floor_light(point: np.ndarray, n: int = 300) -> float:
    """``1/π ∫ L_e cosθ_x cosθ_y / r² dA`` over the lamp voxel's six faces for a floor point
    facing up, by the midpoint rule on n×n points per face."""
    u = (np.arange(n) + 0.5) / n
    a, b = (g.ravel() for g in np.meshgrid(u, u))
    total = 0.0
    for axis in range(3):
        for side in (0.0, 1.0):
            q = np.empty((a.size, 3))
            others = [k for k in range(3) if k != axis]
            q[:, axis] = LAMP[axis] + side
            q[:, others[0]] = LAMP[others[0]] + a
            q[:, others[1]] = LAMP[others[1]] + b
            w = q - point
            r2 = (w**2).sum(axis=1)
            r = np.sqrt(r2)
            cos_x = np.clip(w[:, 1] / r, 0.0, None)
            face_normal = 1.0 if side else -1.0
            cos_y = np.clip(-face_normal * w[:, axis] / r, 0.0, None)
            total += float(np.mean(cos_x * cos_y / r2))  # face area 1
    return EMISSION * total / np.pi


def test_distance_lod_grows_with_log_distance():
    assert [distance_lod(t, 16.0, 8) for t in (0.0, 15.9, 16.0, 47.9, 48.0, 112.0)] == [
        0, 0, 1, 1, 2, 3]
    assert distance_lod(1e9, 16.0, 5) == 5


def test_emitter_faces_are_the_open_faces_of_emitting_voxels(lamp, box):
    faces = emitter_faces(lamp)
    assert len(faces) == 6
    assert np.isclose(faces.cdf[-1], 1.0) and np.allclose(np.diff(faces.cdf), 1 / 6)
    faces = emitter_faces(box)
    assert len(faces) == 64  # the light in the back wall emits towards the grid only
    assert (faces.axis == 2).all() and (faces.sign == 1).all()


def test_open_path_matches_the_inverse_square_integral(lamp):
    """A pixel looking at the floor shows albedo × the analytic irradiance integral / π."""
    centre = np.array([4.5, 1.0, 8.5])
    cam = Camera.orthographic((centre[0], 10.0, centre[2]), (0, -1, 0), (0, 0, -1),
                              view_height=0.25, width=8)
    result = render_direct_light(lamp, cam, shadow_lod="reference", light_samples=256, seed=1)
    expected = FLOOR_ALBEDO * analytic_floor_light(centre)
    assert expected > 0.05
    assert np.isclose(result.image.mean(), expected, rtol=0.02)
    # Only samples on the two faces turned towards the point (bottom, -x) cast a ray.
    assert 0 < result.maps["shadow_rays"].min() and result.maps["shadow_rays"].max() < 128
    # Far from everything but the floor, the baseline and error-aware rays see the same light.
    for mode in ("distance", "error-aware"):
        other = render_direct_light(lamp, cam, shadow_lod=mode, light_samples=256, seed=1)
        assert np.array_equal(other.image, result.image)


@pytest.mark.parametrize(
    "point", [(2.5, 1.0, 3.5), (8.5, 1.0, 12.5), (13.0, 1.0, 8.0), (8.5, 1.0, 8.5)]
)
def test_light_on_surface_matches_the_integral(lamp, point):
    # The last point is right under the lamp: only its bottom face lights it.
    p = np.array([point])
    radiance, steps, lod = light_on_surface(lamp, p, np.array([[0.0, 1.0, 0.0]]),
                                            light_samples=4096)
    assert np.allclose(radiance[0], analytic_floor_light(p[0]), rtol=0.02)
    assert steps[0] > 0 and lod[0] == 0


def test_a_blocked_point_gets_no_light(lamp):
    # Under the floor (facing down, the lamp above the floor slab): every ray is blocked.
    radiance, steps, _ = light_on_surface(lamp, np.array([[8.5, 0.0, 8.5]]),
                                          np.array([[0.0, -1.0, 0.0]]), light_samples=16)
    assert (radiance == 0).all() and steps[0] == 0  # faces turned away: no ray cast at all
    radiance, steps, _ = light_on_surface(lamp, np.array([[4.5, 0.0, 8.5]]),
                                          np.array([[0.0, 1.0, 0.0]]), light_samples=16)
    assert (radiance == 0).all() and steps[0] > 0  # inside the floor slab, facing up


def _floor_strip(layout, near: float, far: float):
    (x0, x1), (z0, _) = layout.behind_grid()
    xs = np.arange(x0, x1, 2.0) + 0.5
    zs = np.arange(z0 + near, z0 + far, 2.0) + 0.5
    gx, gz = np.meshgrid(xs, zs)
    points = np.stack([gx.ravel(), np.full(gx.size, float(layout.floor_top)), gz.ravel()], 1)
    return points, np.tile([0.0, 1.0, 0.0], (len(points), 1))


def _mean_light(octree, points, normals, mode, **options) -> float:
    radiance, _, _ = light_on_surface(octree, points, normals, shadow_lod=mode,
                                      light_samples=16, **options)
    return float(radiance.mean())


def test_done_when_distance_lod_cuts_the_beam_off_and_error_aware_does_not(box):
    """The issue's test: light on the floor behind the grid, beyond the distance where the
    baseline switches to LOD 1 (where the grid is a closed plane)."""
    layout = shadow_box_layout()
    points, normals = _floor_strip(layout, near=32.0, far=64.0)
    reference = _mean_light(box, points, normals, "reference")
    distance = _mean_light(box, points, normals, "distance", lod_distance=16.0)
    error_aware = _mean_light(box, points, normals, "error-aware", lod_distance=16.0)
    assert reference > 0.03
    assert distance < 0.01 * reference
    assert error_aware > 0.9 * reference
    # Close to the grid the baseline still samples the voxels and agrees with the reference.
    points, normals = _floor_strip(layout, near=2.0, far=8.0)
    near_ref = _mean_light(box, points, normals, "reference")
    assert near_ref > 0.05
    assert np.isclose(_mean_light(box, points, normals, "distance"), near_ref)


def test_done_when_in_the_rendered_image(box):
    """The same on pixels: the floor behind the grid is dark with the baseline, lit with the
    error-aware shadow rays."""
    cam = beam_camera(*box.voxel_bounds, size=48)
    images = {mode: render_direct_light(box, cam, shadow_lod=mode, light_samples=16).image
              for mode in ("reference", "distance", "error-aware")}
    floor = (slice(26, 48), slice(12, 36))  # the beam in front of the box, below the grid
    ref = images["reference"][floor].mean()
    assert ref > 0.01
    assert images["distance"][floor].mean() < 0.05 * ref
    # Less than on the strip: the picture reaches further out, where head-on rays meet the
    # grid at LOD 2 and the decayed child error stays under the threshold (oct encoding).
    assert images["error-aware"][floor].mean() > 0.6 * ref


def test_forced_refinement_is_the_reference_and_infinite_threshold_the_baseline(box):
    cam = beam_camera(*box.voxel_bounds, size=32)
    options = {"light_samples": 4, "seed": 5, "lod_distance": 8.0}
    reference = render_direct_light(box, cam, shadow_lod="reference", **options)
    forced = render_direct_light(box, cam, shadow_lod="error-aware", threshold=-1.0, **options)
    assert np.array_equal(forced.image, reference.image)
    assert forced.maps["shadow_refinements"].sum() > 0
    baseline = render_direct_light(box, cam, shadow_lod="distance", **options)
    never = render_direct_light(box, cam, shadow_lod="error-aware", threshold=np.inf, **options)
    assert np.array_equal(never.image, baseline.image)
    assert np.array_equal(never.maps["shadow_steps"], baseline.maps["shadow_steps"])
    assert never.maps["shadow_refinements"].sum() == 0
    # The baseline samples coarser LODs than the reference, which samples LOD 0 only.
    lod = baseline.maps["shadow_lod"]
    assert lod.max() >= 1 and set(np.unique(reference.maps["shadow_lod"])) <= {-1.0, 0.0}


def test_one_refinement_level_at_most(box):
    cam = beam_camera(*box.voxel_bounds, size=32)
    options = {"light_samples": 4, "lod_distance": 8.0, "shadow_lod": "error-aware"}
    capped = render_direct_light(box, cam, max_refinements=0, **options)
    baseline = render_direct_light(box, cam, shadow_lod="distance", light_samples=4,
                                   lod_distance=8.0)
    assert np.array_equal(capped.image, baseline.image)


def test_same_result_for_any_thread_count(box, small_jobs_in_parallel):
    cam = beam_camera(*box.voxel_bounds, size=32)
    one = render_direct_light(box, cam, shadow_lod="error-aware", light_samples=4, threads=1)
    two = render_direct_light(box, cam, shadow_lod="error-aware", light_samples=4, threads=2)
    for name in ("image", "depth", "ray_count", "steps"):
        assert np.array_equal(getattr(one, name), getattr(two, name))
    for name, values in one.maps.items():
        assert np.array_equal(values, two.maps[name]), name


def test_counters_add_up(box):
    cam = beam_camera(*box.voxel_bounds, size=24)
    result = render_direct_light(box, cam, shadow_lod="error-aware", light_samples=4)
    maps = result.maps
    assert (maps["shadow_traversals"] >= maps["shadow_rays"]).all()
    assert np.array_equal(result.ray_count, 4 + maps["shadow_traversals"])
    assert (result.steps >= maps["shadow_steps"]).all()
    assert ((maps["shadow_lod"] == -1) == (maps["shadow_rays"] == 0)).all()
    assert result.image.min() >= 0.0 and result.image.max() <= 1.0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"shadow_lod": "cone"}, "unknown shadow LOD"),
        ({"light_samples": 0}, "light samples"),
        ({"light_samples": 2.5}, "light samples must be an integer"),  # once 2 samples
        ({"seed": 0.5}, "seed must be an integer"),
        ({"max_refinements": 1.5}, "refinements"),
        ({"lod_distance": 0.0}, "LOD distance"),
        ({"lod_distance": float("nan")}, "LOD distance"),
        ({"threshold": float("nan")}, "threshold"),
        ({"decay": -1.0}, "decay"),
        ({"max_refinements": 99}, "refinements"),
        ({"encoding": "png"}, "encoding"),
    ],
)
def test_bad_options_raise(lamp, options, message):
    cam = Camera.look_at((8, 10, 20), (8, 0, 8), width=8)
    with pytest.raises(VoxfieldError, match=message):
        render_direct_light(lamp, cam, **options)


def test_scene_without_light_is_refused():
    octree = build_octree(VoxelScene(np.array([[0, 0, 0], [1, 1, 1]]), np.full((2, 3), 0.5)))
    with pytest.raises(VoxfieldError, match="emission"):
        render_direct_light(octree, Camera.look_at((5, 5, 5), (0, 0, 0), width=8))
    dark = build_octree(VoxelScene(np.array([[0, 0, 0]]), np.full((1, 3), 0.5),
                                   emission=np.zeros((1, 3))))
    with pytest.raises(VoxfieldError, match="positive emission"):
        render_direct_light(dark, Camera.look_at((5, 5, 5), (0, 0, 0), width=8))


def test_bad_points_raise(lamp):
    with pytest.raises(VoxfieldError, match="N×3"):
        light_on_surface(lamp, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(VoxfieldError, match="unit"):
        light_on_surface(lamp, np.zeros((1, 3)), np.array([[0.0, 2.0, 0.0]]))


def test_shadows_command_writes_the_study(tmp_path):
    parser = argparse.ArgumentParser()
    add_shadow_parser(parser.add_subparsers())
    out = tmp_path / "study"
    args = parser.parse_args([
        "shadows", "--size", "24", "--light-samples", "4", "--reference-samples", "9",
        "--floor-samples", "4", "--out", str(out),
    ])
    assert args.scene == "builtin:shadowbox"
    args.quiet = True
    assert args.func(args) == 0
    report = json.loads((out / "results.json").read_text())
    rows = {row["renderer"]: row for row in report["rows"]}
    assert set(rows) == {"reference", "full-res", "distance", "error-aware"}
    assert rows["distance"]["far_floor_light"] < 0.01 * rows["reference"]["far_floor_light"]
    assert rows["error-aware"]["far_floor_light"] > 0.9 * rows["reference"]["far_floor_light"]
    for name in ("reference.png", "distance.png", "error_aware.png", "lod_error_aware.png",
                 "lod_top_distance.png", "beam_profile.png", "contact_sheet.png", "results.md"):
        assert (out / name).is_file(), name
    assert "PSNR" in (out / "results.md").read_text()


def test_the_shadows_study_measures_a_view_too_small_for_ssim(tmp_path):
    """It measures PSNR alone, which has no window: at ``--size 4`` it rendered every row and
    then failed with 'images must be at least 7×7 pixels for SSIM'."""
    from voxfield.cli import main

    out = tmp_path / "small"
    assert main(["shadows", "--size", "4", "--light-samples", "1", "--reference-samples",
                 "4", "--floor-samples", "1", "--quiet", "--out", str(out)]) == 0
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert len(rows) == 4 and all("psnr" in row for row in rows if row["renderer"] != "reference")
