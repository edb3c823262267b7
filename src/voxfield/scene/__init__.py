"""Scenes: the VoxelScene container, readers for real data, built-in procedural scenes."""

from voxfield.scene.vox import load_vox, load_vox_models
from voxfield.scene.voxel_scene import VoxelScene, compose, linear_to_srgb, srgb_to_linear

__all__ = [
    "VoxelScene",
    "compose",
    "linear_to_srgb",
    "load_vox",
    "load_vox_models",
    "srgb_to_linear",
]
