"""Light probes with depth (probe thesis ch. 4, §5.2): grids, bakes straight from the octree
into octahedral maps, storage, and distributed baking."""
