"""Cube symmetries acting on child masks and directions (error_table/symmetry.py).

Pins: ``cube_symmetries`` is exactly the 48 orthogonal integer matrices (found here by brute
force); ``transform_masks`` moves octants as the matrix moves their corner points (checked with
a corner-set construction written here); 22 mask classes under the full group — by this file's
own canonicalisation and by Burnside's lemma — and 23 under rotations alone; the ray-cast error
is invariant, e(g·m, g·d) ≈ e(m, d) for all 48 g, and e(m, −d) ≈ e(m, d).
"""

from __future__ import annotations

import itertools

import numpy as np

from voxfield.error_table import raycast_errors
from voxfield.error_table.symmetry import (
    cube_symmetries,
    distinct_mask_count,
    mask_orbits,
    transform_masks,
)

# 256²: see test_raycast.py's docstring for the jittered-sampling tolerance (Table 3.1: 0.1875).
TOL_256 = 0.01


def _orthogonal_integer_matrices() -> list[np.ndarray]:
    """All 3×3 matrices with entries in {−1, 0, 1} and M·Mᵀ = I (brute force over 3⁹)."""
    found = []
    for entries in itertools.product((-1, 0, 1), repeat=9):
        m = np.array(entries).reshape(3, 3)
        if np.array_equal(m @ m.T, np.eye(3, dtype=int)):
            found.append(m)
    return found


GROUP = _orthogonal_integer_matrices()


def _corner(c: int) -> tuple[int, int, int]:
    """Centre direction of child octant c (c = x | y<<1 | z<<2, set bit = high half)."""
    return (1 if c & 1 else -1, 1 if c & 2 else -1, 1 if c & 4 else -1)


def _octant(corner) -> int:
    x, y, z = (int(v > 0) for v in corner)
    return x | y << 1 | z << 2


def _move_mask(g: np.ndarray, mask: int) -> int:
    corners = {_corner(c) for c in range(8) if mask >> c & 1}
    return sum(1 << _octant(g @ np.array(p)) for p in corners)


def test_group_is_the_48_signed_permutations():
    assert len(GROUP) == 48
    mine = {m.tobytes() for m in GROUP}
    theirs = cube_symmetries()
    assert theirs.shape == (48, 3, 3)
    assert {np.asarray(g, dtype=GROUP[0].dtype).tobytes() for g in theirs} == mine
    dets = np.round(np.linalg.det(theirs)).astype(int)
    assert sorted(dets.tolist()) == [-1] * 24 + [1] * 24


def test_transform_masks_moves_octants_like_their_corners():
    masks = np.arange(256)
    for g in cube_symmetries():
        expected = np.array([_move_mask(g, m) for m in range(256)])
        got = transform_masks(g, masks)
        assert np.array_equal(got, expected), g
        assert sorted(got.tolist()) == list(range(256))  # a bijection on masks
        # popcount is preserved
        assert all(bin(a).count("1") == bin(b).count("1") for a, b in zip(masks, got, strict=True))


def test_a_specific_symmetry_by_hand():
    # Swap x and y: octant 1 (high x, mask bit 1) ↔ octant 2 (high y, bit 2); octants 3 (high
    # x and y) and 4 (high z) stay.
    swap_xy = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1]])
    assert transform_masks(swap_xy, np.array([1 << 1, 1 << 2, 1 << 3, 1 << 4])).tolist() == [
        1 << 2, 1 << 1, 1 << 3, 1 << 4,
    ]
    # Mirror x: octant c ↔ c ^ 1.
    mirror_x = np.diag([-1, 1, 1])
    assert transform_masks(mirror_x, np.array([1 << c for c in range(8)])).tolist() == [
        1 << (c ^ 1) for c in range(8)
    ]


def _orbit_count(group) -> int:
    canonical = {min(_move_mask(g, m) for g in group) for m in range(256)}
    return len(canonical)


def _burnside(group) -> int:
    """(1/|G|) Σ_g 2^(cycles of g on the 8 corners)."""
    total = 0
    for g in group:
        perm = [_octant(g @ np.array(_corner(c))) for c in range(8)]
        seen, cycles = set(), 0
        for start in range(8):
            if start in seen:
                continue
            cycles += 1
            c = start
            while c not in seen:
                seen.add(c)
                c = perm[c]
        total += 2**cycles
    assert total % len(group) == 0
    return total // len(group)


def test_distinct_mask_count_is_22():
    assert _orbit_count(GROUP) == 22
    assert _burnside(GROUP) == 22
    rotations = [g for g in GROUP if round(np.linalg.det(g)) == 1]
    assert _orbit_count(rotations) == _burnside(rotations) == 23  # known: cube vertex 2-colourings
    assert distinct_mask_count() == 22


def test_mask_orbits_are_the_orbits():
    orbit = mask_orbits()
    assert orbit.shape == (256,)
    for m in range(256):
        images = {_move_mask(g, m) for g in GROUP}
        assert orbit[m] == min(images)
        assert all(orbit[i] == orbit[m] for i in images)


def test_error_is_invariant_under_cube_symmetries():
    dirs = np.random.default_rng(21).normal(size=(6, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    group = cube_symmetries()
    base = raycast_errors(dirs, 256, 0)
    moved = raycast_errors(np.concatenate([dirs @ g.T for g in group]), 256, 0)
    masks = np.arange(256)
    worst, where = 0.0, None
    for i, g in enumerate(group):
        e_moved = moved[transform_masks(g, masks), i * len(dirs) : (i + 1) * len(dirs)]
        diff = np.abs(e_moved - base)
        if diff.max() > worst:
            worst, where = diff.max(), (i, np.unravel_index(diff.argmax(), diff.shape))
    assert worst < TOL_256, f"max |e(g·m, g·d) − e(m, d)| = {worst:.2e} at (g, (mask, d)) {where}"


def test_error_is_the_same_from_opposite_sides():
    dirs = np.random.default_rng(22).normal(size=(16, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    diff = np.abs(raycast_errors(dirs, 256, 0) - raycast_errors(-dirs, 256, 0))
    assert diff.max() < TOL_256, f"max |e(m, −d) − e(m, d)| = {diff.max():.2e}"
