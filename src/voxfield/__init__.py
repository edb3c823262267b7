"""voxfield: sparse voxel octrees with error-aware LOD, light probes with depth, ray queries."""

from voxfield.errors import VoxfieldError

__all__ = ["VoxfieldError"]
__version__ = "0.1.0"
