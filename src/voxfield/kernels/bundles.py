"""Argument bundles the CPU render kernels share: what a traversal reads of an octree, where a
pixel block's rays may start, and the per-pixel output rows.

Named tuples, so a kernel takes a handful of named things instead of thirty positional
arrays; Numba unpacks them at compile time, so they cost nothing at run time. Kernels that
the CUDA target also compiles keep flat arguments.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class OctreeView(NamedTuple):
    """What a traversal reads of an octree: packed descriptors, depth, one colour channel and
    its directional colours (``kernels.facing_colour``; empty when it has none)."""

    inner_nodes: np.ndarray
    depth: int
    colors: np.ndarray
    facing: np.ndarray


class BeamBounds(NamedTuple):
    """Per pixel block, the distance its rays may start at (``kernels.beam``)."""

    bound: np.ndarray
    block: int


class PixelOutputs(NamedTuple):
    """Per-pixel output rows, the ``RenderResult`` buffers in order: colour, depth, normal,
    rays, hits, steps and finest LOD."""

    color: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    rays: np.ndarray
    hits: np.ndarray
    steps: np.ndarray
    lod: np.ndarray
