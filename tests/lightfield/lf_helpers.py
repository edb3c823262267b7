"""Probe helpers shared by the light-field tests."""

from __future__ import annotations

import numpy as np

from voxfield.lightfield import PackedProbes
from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions

#: A probe inside the Cornell box, clear of the box and the walls.
CORNELL_PROBE = np.array([16.3, 20.7, 20.1])


def bake_grid(octree, grid: ProbeGrid, resolution: int) -> PackedProbes:
    options = BakeOptions(resolution=resolution, renderer="lod", lod=0)
    return PackedProbes.from_probe_set(bake_probes(octree, grid, options))


def one_probe(octree, position, resolution: int) -> PackedProbes:
    return bake_grid(octree, ProbeGrid(position, [1, 1, 1], [1, 1, 1]), resolution)
