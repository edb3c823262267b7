"""Probe maps packed as the flat arrays the light-field kernels read.

A ``ProbeSet`` keeps radiance in float16 and normals as snorm16 codes, the compact form a bake
stores. Tracing reads them many times per ray, so they are decoded once here: float32
radiance, unit float32 normals, and the conservative min-distance mip chain laid end to end in
one array per probe.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import add_border
from voxfield.probes.probe_set import (
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    decode_normals,
    min_distance_mips,
)


@dataclass(frozen=True)
class PackedProbes:
    """Decoded probe maps, read-only, in the probe set's order (callers may rely on all fields).

    - ``positions`` (N, 3) float64 probe centres; ``enabled`` (N,) bool.
    - ``radiance`` (N, R, R, 3) float32, ``distance`` (N, R, R) float32 radial distance
      (inf: no surface), ``normals`` (N, R, R, 3) float32 unit normals (zero where none);
      texel (row, col) follows the octahedral layout of ``kernels.octahedral`` (row = v).
    - ``mips`` (N, total + 1) float32: the min-distance chain of ``min_distance_mips``,
      level 0 (the distance map itself) first; level ``k`` is ``mip_sizes[k]`` texels a side,
      stored row-major at ``mips[:, mip_offsets[k]:mip_offsets[k] + mip_sizes[k] ** 2]``.
      The last column is each probe's farthest finite distance (0 where it stores none): past
      it a ray moving away can meet no surface the probe knows
      (``kernels.probe_march.farthest_surface``).
    - ``grid_origin``, ``grid_spacing`` (3,) float64 and ``grid_counts`` (3,) int64: the probe
      lattice (x fastest, as ``ProbeGrid``), for finding the 8-probe cage around a point.
    - ``radiance_bordered`` (N, R + 2, R + 2, 3) and ``distance_bordered`` (N, R + 2, R + 2)
      float32: the maps with their octahedral wrap border (``add_border``), so a bilinear
      read at any direction finds its four texels.
    """

    positions: np.ndarray
    enabled: np.ndarray
    radiance: np.ndarray
    distance: np.ndarray
    normals: np.ndarray
    mips: np.ndarray
    mip_offsets: np.ndarray
    mip_sizes: np.ndarray
    grid_origin: np.ndarray
    grid_spacing: np.ndarray
    grid_counts: np.ndarray
    radiance_bordered: np.ndarray
    distance_bordered: np.ndarray

    def __repr__(self) -> str:  # the default printed every map in full
        r = self.resolution
        return (f"PackedProbes({self.count} probes, {int(np.count_nonzero(self.enabled))} "
                f"enabled, {r}x{r} maps)")

    @property
    def count(self) -> int:
        return len(self.positions)

    def derived(self, key, compute):
        """``compute()``, worked out once per probe set and ``key`` and kept with it: the
        maps' copies on a GPU, uploaded once however many frames are traced."""
        cache = self.__dict__.setdefault("_derived", {})
        if key not in cache:
            cache[key] = compute()
        return cache[key]

    @property
    def resolution(self) -> int:
        return int(self.distance.shape[-1])

    @property
    def levels(self) -> int:
        return len(self.mip_sizes)

    @classmethod
    def from_probe_set(cls, ps) -> PackedProbes:
        """Pack a ``ProbeSet``. Its ``grid`` must describe the lattice (``origin``,
        ``spacing``, ``counts``, as ``ProbeGrid`` does) so rays can find their probe cage."""
        grid = ps.grid
        try:
            origin = np.asarray(grid.origin, np.float64).reshape(3)
            spacing = np.asarray(grid.spacing, np.float64).reshape(3)
            counts = np.asarray(grid.counts, np.int64).reshape(3)
        except (AttributeError, ValueError) as exc:
            raise VoxfieldError("the probe set's grid must have origin, spacing and counts "
                                "(a ProbeGrid) to trace a light field") from exc
        if int(np.prod(counts)) != ps.count:
            raise VoxfieldError(f"the grid has {int(np.prod(counts))} probes but the set holds "
                                f"{ps.count}")
        return cls.from_arrays(ps.positions, ps.enabled, ps.radiance, ps.distance,
                               decode_normals(ps.normal), origin, spacing, counts)

    @classmethod
    def from_arrays(cls, positions, enabled, radiance, distance, normals, grid_origin,
                    grid_spacing, grid_counts) -> PackedProbes:
        """Pack plain arrays (normals already decoded, (N, R, R, 3)); shapes are checked."""
        positions = np.ascontiguousarray(positions, np.float64).reshape(-1, 3)
        n = len(positions)
        if n == 0:  # said plainly, not as "grid counts [1, 1, 1] do not hold 0 probes"
            raise VoxfieldError("a probe set needs at least one probe; got 0 positions")
        distance = np.ascontiguousarray(distance, np.float32)
        if distance.ndim != 3 or distance.shape[0] != n or distance.shape[1] != distance.shape[2]:
            raise VoxfieldError(f"distance maps must be (N, R, R) for {n} probes, got "
                                f"{distance.shape}")
        r = distance.shape[1]
        if r % 2 or not MIN_RESOLUTION <= r <= MAX_RESOLUTION:
            # Odd sides put fold lines through texel centres, a texel in two octants, which
            # the marchers' octant pieces do not allow for; the bake makes none.
            raise VoxfieldError(f"probe maps must be an even {MIN_RESOLUTION}..{MAX_RESOLUTION} "
                                f"texels a side, as a bake makes them; got {r}")
        radiance = np.ascontiguousarray(radiance, np.float32)
        normals = np.ascontiguousarray(normals, np.float32)
        enabled = np.ascontiguousarray(enabled, bool).reshape(-1)
        if radiance.shape != (n, r, r, 3) or normals.shape != (n, r, r, 3) or len(enabled) != n:
            raise VoxfieldError("radiance and normals must be (N, R, R, 3) and enabled (N,)")
        counts = np.asarray(grid_counts, np.int64).reshape(3)
        if int(np.prod(counts)) != n or np.any(counts < 1):
            raise VoxfieldError(f"grid counts {counts.tolist()} do not hold {n} probes")
        # The trace finds a point's cage by dividing by the spacing, and marches from the
        # positions along the stored distances: each must be a real place and length.
        origin = np.asarray(grid_origin, np.float64).reshape(3)
        spacing = np.asarray(grid_spacing, np.float64).reshape(3)
        if not np.isfinite(origin).all() or not np.isfinite(spacing).all() or np.any(
                spacing <= 0):
            raise VoxfieldError(f"the grid's origin {origin.tolist()} must be finite and its "
                                f"spacing {spacing.tolist()} finite and positive on every axis")
        if not np.isfinite(positions[enabled]).all():
            raise VoxfieldError("an enabled probe's position holds NaN or infinity")
        lengths = distance[enabled]
        if np.isnan(lengths).any() or np.any(lengths < 0):
            raise VoxfieldError("distance maps must hold lengths >= 0 (inf: no surface)")
        # A hit returns these as they are: NaN would reach the image and the normals' uses.
        if not np.isfinite(radiance[enabled]).all():
            raise VoxfieldError("an enabled probe's radiance holds NaN or infinity")
        if not np.isfinite(normals[enabled]).all():
            raise VoxfieldError("an enabled probe's normals hold NaN or infinity (zero: none)")
        chain = min_distance_mips(distance)
        sizes = np.array([level.shape[-1] for level in chain], np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes * sizes)[:-1]]).astype(np.int64)
        finite = np.where(np.isfinite(distance) & (distance > 0), distance, 0)
        farthest = finite.reshape(n, r * r).max(axis=1, initial=0)
        mips = np.concatenate([*(level.reshape(n, -1) for level in chain), farthest[:, None]],
                              axis=1)
        packed = cls(positions, enabled, radiance, distance, normals,
                     np.ascontiguousarray(mips, np.float32), offsets, sizes,
                     origin.copy(), spacing.copy(), counts.copy(),
                     np.ascontiguousarray(np.moveaxis(add_border(np.moveaxis(radiance, -1, 1)),
                                                      1, -1)),
                     np.ascontiguousarray(add_border(distance)))
        for value in vars(packed).values():
            value.flags.writeable = False
        return packed
