"""Argument bundles the CPU render kernels share: what a traversal reads of an octree, where a
pixel block's rays may start, and the per-pixel output rows.

Named tuples, so a kernel takes a handful of named things instead of thirty positional
arrays; Numba unpacks them at compile time, so they cost nothing at run time. Kernels that
the CUDA target also compiles keep flat arguments.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from voxfield.kernels.colour import StoredColours, stored_colours


class OctreeView(NamedTuple):
    """What a traversal reads of an octree: packed descriptors, depth, one colour channel
    (the three arrays of a ``kernels.colour.StoredColours``, kept flat because a ``prange``
    body cannot take a tuple inside a tuple; ``view_colours`` joins them) and its directional
    colours (``kernels.facing_colour``; empty when it has none)."""

    inner_nodes: np.ndarray
    depth: int
    srgb8: np.ndarray
    rgb9e5: np.ndarray
    linear: np.ndarray
    facing: np.ndarray


def octree_view(inner_nodes: np.ndarray, depth: int, stored: np.ndarray,
                facing: np.ndarray) -> OctreeView:
    """The view of an octree with the channel ``stored`` (as ``Octree.kernel_colours`` gives
    it, in any storage): one kernel type whatever the storage."""
    return OctreeView(inner_nodes, depth, *stored_colours(stored), facing)


@njit(cache=True, nogil=True, inline="always")
def view_colours(view: OctreeView) -> StoredColours:
    """The view's colour channel, as ``kernels.colour.node_rgb`` reads it."""
    return StoredColours(view.srgb8, view.rgb9e5, view.linear)


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
