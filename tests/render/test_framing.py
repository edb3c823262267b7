"""The orbit view frames content, not a dominant floor; scenes without one keep their box."""

from __future__ import annotations

import numpy as np

from voxfield.render.camera import orbit_camera
from voxfield.render.framing import content_box
from voxfield.render.primary import render_lod
from voxfield.scene.builtin import BUILTIN_SCENES
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo.build import build_octree


def _statue_on_a_stage(stage: int = 256, statue: int = 16) -> VoxelScene:
    """A one-voxel floor ``stage`` wide and a cube ``statue`` wide standing in its middle."""
    xs, zs = np.meshgrid(np.arange(stage), np.arange(stage), indexing="ij")
    floor = np.stack([xs.ravel(), np.zeros(xs.size, int), zs.ravel()], axis=1)
    g = np.arange(statue)
    cx, cy, cz = np.meshgrid(g, g, g, indexing="ij")
    middle = stage // 2 - statue // 2
    cube = np.stack([cx.ravel() + middle, cy.ravel() + 1, cz.ravel() + middle], axis=1)
    coords = np.concatenate([floor, cube])
    color = np.where((coords[:, 1] > 0)[:, None], [[0.9, 0.2, 0.1]], [[0.5, 0.5, 0.5]])
    return VoxelScene(coords, color.astype(np.float32), name="stage")


def test_a_dominant_floor_is_cropped_to_the_content_and_a_margin():
    octree = build_octree(_statue_on_a_stage())
    lo, hi = content_box(octree)
    full_lo, full_hi = octree.voxel_bounds
    assert lo[1] == full_lo[1]  # the floor stays in view
    assert hi[1] >= 17  # the statue's top
    width = hi[0] - lo[0]
    assert 16 <= width <= 0.25 * (full_hi[0] - full_lo[0])
    assert lo[0] <= 120 and hi[0] >= 136 and lo[2] <= 120 and hi[2] >= 136  # holds the cube

    # The statue fills a useful part of the orbit view, and a speck of the whole box's view.
    def statue_share(box):
        image = render_lod(octree, orbit_camera(*box, size=64), lod=0).image
        return float(np.mean((image[..., 0] > 0.6) & (image[..., 2] < 0.3)))

    assert statue_share((lo, hi)) > 0.1
    assert statue_share(octree.voxel_bounds) < 0.02


def test_scenes_without_a_dominant_floor_keep_their_box():
    for name in ("sphere", "menger", "pillars", "cornell"):
        octree = build_octree(BUILTIN_SCENES[name]())
        lo, hi = content_box(octree)
        full_lo, full_hi = octree.voxel_bounds
        np.testing.assert_array_equal(lo, full_lo, err_msg=name)
        np.testing.assert_array_equal(hi, full_hi, err_msg=name)
