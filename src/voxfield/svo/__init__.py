"""Sparse voxel octree: build, layout, save/load."""

from voxfield.svo.build import build_octree, morton_encode
from voxfield.svo.io import load_octree, save_octree
from voxfield.svo.octree import Octree
from voxfield.svo.open import open_octree

__all__ = ["Octree", "build_octree", "load_octree", "morton_encode", "open_octree", "save_octree"]
