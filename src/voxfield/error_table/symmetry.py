"""The 48 symmetries of the cube acting on child masks and directions (EA §6.1's idea).

A symmetry is a signed permutation matrix ``g``; it moves child octant ``c`` (corner
``(±½, ±½, ±½)``) to the octant at ``g · corner`` and a direction ``d`` to ``g · d``, and the
sampling error is invariant: ``e(g·mask, g·d) = e(mask, d)``.
"""

from __future__ import annotations

import itertools

import numpy as np


def cube_symmetries() -> np.ndarray:
    """(48, 3, 3) signed permutation matrices (rotations and reflections)."""
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            g = np.zeros((3, 3), np.int64)
            for row, (col, sign) in enumerate(zip(perm, signs, strict=True)):
                g[row, col] = sign
            mats.append(g)
    return np.array(mats)


def _octant_corners() -> np.ndarray:
    c = np.arange(8)
    return np.stack([c & 1, (c >> 1) & 1, (c >> 2) & 1], axis=1) * 2 - 1  # ±1 per axis


def octant_permutation(g: np.ndarray) -> np.ndarray:
    """``perm[c]`` = octant that ``g`` moves octant ``c`` to."""
    moved = _octant_corners() @ np.asarray(g).T
    bits = (moved > 0).astype(np.int64)
    return bits[:, 0] | bits[:, 1] << 1 | bits[:, 2] << 2


def transform_masks(g: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """Masks with every present octant moved by ``g``."""
    masks = np.asarray(masks, dtype=np.int64)
    perm = octant_permutation(g)
    out = np.zeros_like(masks)
    for c in range(8):
        out |= ((masks >> c) & 1) << perm[c]
    return out


def mask_orbits() -> np.ndarray:
    """``orbit[m]`` = smallest mask equivalent to ``m`` under the 48 symmetries."""
    masks = np.arange(256)
    images = np.stack([transform_masks(g, masks) for g in cube_symmetries()])
    return images.min(axis=0)


def distinct_mask_count() -> int:
    """How many child masks differ up to cube symmetry (22 for the full group)."""
    return len(np.unique(mask_orbits()))
