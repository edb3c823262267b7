"""Light probes with depth (probe thesis ch. 4, §5.2): grids, bakes straight from the octree
into octahedral maps, storage, and distributed baking."""

from voxfield.probes.bake import bake_probe, bake_probes
from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid, parse_grid, relocate
from voxfield.probes.probe_folder import open_probe_set
from voxfield.probes.probe_set import BakeOptions, ProbeMaps, ProbeSet

__all__ = ["BakeOptions", "ProbeGrid", "ProbeMaps", "ProbeSet", "bake_probe", "bake_probes",
           "bake_to_folder", "open_probe_set", "parse_grid", "relocate"]
