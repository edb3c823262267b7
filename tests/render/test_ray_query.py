"""``trace``'s answers say which LOD they hit in the LOD's own terms."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.render import orbit_camera
from voxfield.render.ray_query import trace
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree


@pytest.mark.parametrize("lod", [0, 1, 3])
def test_a_hit_s_lod_is_the_one_asked_for_and_its_level_counts_from_the_root(lod):
    """``level`` counts from the root, as the kernels do, where ``trace(lod=...)`` counts from
    the voxels: ``lod`` answers in the caller's terms. The hit node's index lies in its
    level's range of the octree's node array (``level_offsets``), whatever either says."""
    octree = build_octree(pillars(32))
    origins, directions = orbit_camera(*octree.voxel_bounds, size=24).rays()
    hits = trace(octree, origins, directions, lod=lod)
    assert hits.hit.any() and not hits.hit.all()
    offsets = octree.level_offsets
    level = octree.depth - lod
    node = hits.node[hits.hit]
    assert np.all((offsets[level] <= node) & (node < offsets[level + 1]))
    assert np.all(hits.level[hits.hit] == level)
    assert np.all(hits.lod[hits.hit] == lod) and np.all(hits.lod[~hits.hit] == -1)


@pytest.mark.parametrize("columns", ["yes", "no", 1, None])
def test_the_column_switch_takes_true_or_false_alone(columns):
    """``columns="no"`` walked the pyramid: any non-empty string is true to Python."""
    from voxfield.errors import VoxfieldError
    from voxfield.render.ray_query import occluded

    octree = build_octree(pillars(16))
    rays = (np.array([[3.0, 20.0, 3.0]]), np.array([[0.0, -1.0, 0.0]]))
    for query in (trace, occluded):
        with pytest.raises(VoxfieldError, match="columns must be True or False"):
            query(octree, *rays, columns=columns)
    assert trace(octree, *rays, columns=np.bool_(True)).node[0] >= 0  # NumPy's bool is one
