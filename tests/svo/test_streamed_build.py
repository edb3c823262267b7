"""The streamed build gives the monolithic build's octree, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.errors import VoxfieldError
from voxfield.scene.terrain import Heightmap, terrain_layout
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.streamed_build import SceneBlocks, build_octree_streamed


def assert_same_octree(a, b):
    assert a.depth == b.depth
    assert np.array_equal(a.level_offsets, b.level_offsets)
    assert np.array_equal(a.descriptors, b.descriptors)
    assert set(a.attributes) == set(b.attributes)
    for name in a.attributes:
        assert a.attributes[name].dtype == b.attributes[name].dtype
        assert np.array_equal(a.attributes[name], b.attributes[name]), name
    assert np.array_equal(a.voxel_box, b.voxel_box)
    assert np.array_equal(a.scene_origin, b.scene_origin)


@pytest.mark.parametrize("block", [2, 8, 64])
@pytest.mark.parametrize("seed", [0, 1])
def test_random_scenes_in_any_block_size(seed, block):
    scene = random_scene(seed, n=900, size=37)
    scene = VoxelScene(scene.coords - 11, scene.color, emission=scene.color * 3, name="r")
    assert_same_octree(build_octree(scene), build_octree_streamed(SceneBlocks(scene), block=block))
    assert_same_octree(build_octree(scene, colour_storage="float32"),
                       build_octree_streamed(SceneBlocks(scene), block=block,
                                             colour_storage="float32"))


def test_a_terrain_with_assets_streams_to_the_same_octree():
    rng = np.random.default_rng(4)
    elevation = np.cumsum(np.cumsum(rng.normal(size=(40, 40)), axis=0), axis=1) * 0.3
    trunk = [(1, y, 1) for y in range(5)]
    crown = [(x, y, z) for y in (5, 6) for x in range(3) for z in range(3)]
    tree = VoxelScene(np.array(trunk + crown), np.full((len(trunk) + len(crown), 3), 0.3),
                      emission=np.full((len(trunk) + len(crown), 3), 0.5), name="tree")
    layout = terrain_layout(Heightmap(elevation, spacing=(1, 1)), 96, fill_depth=2,
                            assets=[tree], asset_density=0.5, seed=3)
    assert len(layout.extra) > 0  # the assets are part of the test
    expected = build_octree(layout.scene())
    for block in (4, 16, 128):
        assert_same_octree(expected, build_octree_streamed(layout, block=block))


def test_bad_blocks_are_refused():
    source = SceneBlocks(random_scene(2, n=50, size=8))
    with pytest.raises(VoxfieldError, match="power of two"):
        build_octree_streamed(source, block=12)
    with pytest.raises(VoxfieldError, match="colour storage"):
        build_octree_streamed(source, colour_storage="half")
