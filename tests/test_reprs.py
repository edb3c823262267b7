"""The objects a notebook user holds print as one line of what they are, not as every
array they hold (an octree's default repr ran to pages, a render's to about 4 KB)."""

from __future__ import annotations

import numpy as np

from voxfield.lightfield import PackedProbes, trace_light_field, trace_single
from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions
from voxfield.render import orbit_camera, render
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree


def test_every_result_object_prints_as_one_short_line():
    scene = pillars()
    octree = build_octree(scene)
    result = render(octree, orbit_camera(*octree.voxel_bounds, size=8), "lod", lod=1)
    lo, hi = octree.voxel_bounds
    grid = ProbeGrid.fit(lo, hi, (2, 1, 1))
    probe_set = bake_probes(octree, grid, BakeOptions(resolution=4, renderer="lod", lod=0))
    packed = PackedProbes.from_probe_set(probe_set)
    origins, dirs = np.repeat([(lo + hi) / 2], 5, axis=0), np.tile([0.0, -1.0, 0.0], (5, 1))
    expected = [
        (octree, [f"{octree.voxel_count:,} voxels", f"depth {octree.depth}"]),
        (scene, [f"{len(scene.coords):,} voxels"]),
        (result, ["8x8", f"{int(result.ray_count.sum()):,} rays"]),
        (grid, ["2x1x1"]),
        (probe_set, ["2 probes", "4x4 maps"]),
        (packed, ["2 probes"]),
        (trace_light_field(packed, origins, dirs), ["5 rays"]),
        (trace_single(packed, 0, origins, dirs), ["5 rays"]),
    ]
    for thing, words in expected:
        text = repr(thing)
        assert "\n" not in text and len(text) < 160, text
        assert text.startswith(type(thing).__name__ + "(")
        for word in words:
            assert word in text, (text, word)
