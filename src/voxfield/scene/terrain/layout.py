"""The assembled terrain: ``terrain_layout`` runs the steps (heightmap → columns → colours and
assets) into a ``TerrainLayout``, which makes the voxels all at once (``scene``, what
``terrain_scene`` returns) or one square of columns at a time (``column_block``, the
``svo.streamed_build.BlockSource`` that builds worlds too large to hold as one scene).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from voxfield.errors import SceneTooLargeError, VoxfieldError
from voxfield.kernels.terrain_columns import expand_columns
from voxfield.scene.terrain.asset_scatter import AssetGroup, AssetVoxels, scatter_assets
from voxfield.scene.terrain.columns import TerrainColumns, terrain_columns
from voxfield.scene.terrain.dem import load_heightmap
from voxfield.scene.terrain.ground_colours import (
    ColorRamp,
    image_colors,
    linear_rgb,
    ramp_colors,
    smoothed,
)
from voxfield.scene.voxel_scene import VoxelScene

#: Default cap on the voxels one terrain may hold (≈ 36 bytes each once built): a memory guard.
MAX_TERRAIN_VOXELS = 250_000_000
#: Asset bucket side (columns) for ``TerrainLayout.column_block``.
_BUCKET = 64
#: Rows of columns laid out per step of ``TerrainLayout.scene``.
GROUND_BAND_ROWS = 256


def terrain_layout(
    heightmap,
    footprint: int = 2048,
    *,
    vertical_scale: float = 1.0,
    max_height: int | None = None,
    fill_depth: int = 4,
    colors=None,
    ramp: ColorRamp | None = None,
    seed: int = 0,
    assets: Sequence[VoxelScene] | Sequence[AssetGroup] | None = None,
    asset_density: float = 0.3,
    sea_level: float | None = None,
    fit: str = "stretch",
    interpolation: str = "cubic",
    name: str | None = None,
) -> TerrainLayout:
    """The layout of a solid voxel terrain of ``footprint``² columns from a DEM, coloured,
    with assets (``TerrainLayout.scene`` makes its voxels).

    ``heightmap``: a Heightmap, a path or sample name (see ``load_heightmap``) or a 2-D array.
    ``colors``: ``None``/``"ramp"`` (height/slope ramp, ``ramp`` sets its palette), an image
    path or an H×W×3 linear array (GeoTIFFs are placed by position where both carry one;
    columns the image misses fall back to the ramp). Voxels under the surface voxel get a
    darker earth variant. ``assets``: VoxelScene models scattered with ``asset_density``, or
    AssetGroups with their own rules. Same inputs and ``seed`` → identical scene.
    See ``terrain_columns`` for the height parameters.
    """
    hm = load_heightmap(heightmap)
    ramp = ramp or ColorRamp()
    groups: list[AssetGroup] = []
    if assets:
        if all(isinstance(a, AssetGroup) for a in assets):
            groups = list(assets)
        elif all(isinstance(a, VoxelScene) for a in assets):
            groups = [AssetGroup(models=list(assets), density=asset_density)]
        else:
            raise VoxfieldError("assets must be a list of VoxelScene models or of AssetGroups")
    reserve = max((g.height for g in groups), default=0)
    cols = terrain_columns(
        hm,
        footprint,
        vertical_scale=vertical_scale,
        max_height=max_height,
        fill_depth=fill_depth,
        sea_level=sea_level,
        fit=fit,
        interpolation=interpolation,
        reserve=reserve,
    )
    extra = scatter_assets(cols, groups, seed)
    # Colour per column.
    surface = ramp_colors(cols, ramp, np.random.default_rng([seed, 0]))
    if colors is not None and not (isinstance(colors, str) and colors == "ramp"):
        img, covered = image_colors(cols, hm, colors, fit)
        surface = np.where(covered[..., None], img, surface)
    surface = smoothed(surface, ramp.smoothing)
    earth = None if ramp.earth is None else linear_rgb(ramp.earth)
    return TerrainLayout(cols, surface, earth, extra,
                         name or f"terrain:{cols.name}")


def terrain_scene(heightmap, footprint: int = 2048, *, max_voxels: int = MAX_TERRAIN_VOXELS,
                  **options) -> VoxelScene:
    """A solid voxel terrain of ``footprint``² columns from a DEM, coloured, with assets:
    every voxel of ``terrain_layout(heightmap, footprint, **options)`` at once. Over
    ``max_voxels`` voxels it refuses; ``svo.streamed_build`` builds such worlds from the
    layout's column blocks instead."""
    return terrain_layout(heightmap, footprint, **options).scene(max_voxels)


@dataclass
class TerrainLayout:
    """A terrain before its voxels exist: columns, their surface colours and the assets.

    It makes every voxel at once (``scene``) or those of one square of columns at a time
    (``column_block``, a ``svo.streamed_build.BlockSource``): the same voxels either way.
    Ground voxels get their column's surface colour on top and a darker earth variant of it
    below.
    """

    cols: TerrainColumns
    surface: np.ndarray  # (footprint, footprint, 3) float32 linear, indexed [z, x]
    earth: np.ndarray | None  # (3,) linear earth colour the fill mixes in; None: no mix
    extra: AssetVoxels
    name: str

    @property
    def voxel_count(self) -> int:
        return self.cols.voxel_count + len(self.extra)

    @property
    def attribute_names(self) -> tuple[str, ...]:
        return ("color", "emission") if self.extra.emission is not None else ("color",)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.cols.footprint
        lo = np.array([0, int(self.cols.bottom.min()), 0], np.int64)
        hi = np.array([f, int(self.cols.top.max()) + 1, f], np.int64)
        if len(self.extra):
            lo = np.minimum(lo, [self.extra.x.min(), self.extra.y.min(), self.extra.z.min()])
            hi = np.maximum(hi, [self.extra.x.max() + 1, self.extra.y.max() + 1,
                                 self.extra.z.max() + 1])
        return lo.astype(np.int64), hi.astype(np.int64)

    def _fill(self, surface: np.ndarray) -> np.ndarray:
        if self.earth is None:
            return surface.astype(np.float32)
        return (0.8 * (0.4 * surface + 0.6 * self.earth)).astype(np.float32)

    def _ground(self, zs: slice, xs: slice) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates and colours of the ground voxels of the columns ``[zs, xs]``: columns
        in row-major order, each from bottom to top."""
        top = self.cols.top[zs, xs]
        bottom = self.cols.bottom[zs, xs]
        n = int((top - bottom + 1).sum(dtype=np.int64))
        coords = np.empty((n, 3), dtype=np.int64)
        color = np.empty((n, 3), dtype=np.float32)
        surface = self.surface[zs, xs]
        expand_columns(top, bottom, xs.start or 0, zs.start or 0, surface, self._fill(surface),
                       coords, color)
        return coords, color

    def scene(self, max_voxels: int = MAX_TERRAIN_VOXELS) -> VoxelScene:
        """Every voxel: the ground, then the assets."""
        n = self.cols.voxel_count
        m = len(self.extra)
        if n + m > max_voxels:
            raise SceneTooLargeError(
                f"this terrain would hold {n + m:,} voxels (over max_voxels={max_voxels:,}, "
                f"about {(n + m) * 36 / 2**30:.1f} GiB as a scene); lower footprint, "
                "vertical_scale or fill_depth, or build the octree streamed "
                "(voxfield.svo.streamed_build, which the terrain: scenes use)"
            )
        coords = np.empty((n + m, 3), dtype=np.int64)
        color = np.empty((n + m, 3), dtype=np.float32)
        # Bands of rows, so no single array operation runs long enough to hold off Ctrl-C
        # (and no full-size temporaries): rows in order give the same voxel order as one go.
        first = 0
        rows = self.cols.top.shape[0]
        for row0 in range(0, rows, GROUND_BAND_ROWS):
            band, band_color = self._ground(slice(row0, min(rows, row0 + GROUND_BAND_ROWS)),
                                            slice(None))
            coords[first:first + len(band)] = band
            color[first:first + len(band)] = band_color
            first += len(band)
        coords[n:] = self._extra_coords(slice(None))
        color[n:] = self.extra.color
        emission = None
        if self.extra.emission is not None:
            emission = np.zeros((n + m, 3), dtype=np.float32)
            emission[n:] = self.extra.emission
        return VoxelScene(coords, color, emission, name=self.name)

    def _extra_coords(self, keep) -> np.ndarray:
        x, y, z = self.extra.x[keep], self.extra.y[keep], self.extra.z[keep]
        return np.stack([x, y, z], axis=1).astype(np.int64)

    def column_block(self, x0: int, z0: int, size: int) -> tuple[np.ndarray, dict]:
        """The voxels with ``x0 <= x < x0 + size`` and ``z0 <= z < z0 + size``."""
        f = self.cols.footprint
        xs = slice(max(x0, 0), min(x0 + size, f))
        zs = slice(max(z0, 0), min(z0 + size, f))
        if xs.start >= xs.stop or zs.start >= zs.stop:
            coords, color = np.zeros((0, 3), np.int64), np.zeros((0, 3), np.float32)
        else:
            coords, color = self._ground(zs, xs)
        keep = self._assets_in(x0, z0, size)
        if len(keep):  # (a copy of the block's ground only where assets join it)
            coords = np.concatenate([coords, self._extra_coords(keep)])
            color = np.concatenate([color, self.extra.color[keep]])
        attributes = {"color": color}
        if self.extra.emission is not None:
            emission = np.zeros((len(coords), 3), np.float32)
            emission[len(coords) - len(keep):] = self.extra.emission[keep]
            attributes["emission"] = emission
        return coords, attributes

    def _assets_in(self, x0: int, z0: int, size: int) -> np.ndarray:
        """Indices (ascending) of the asset voxels with ``x0 <= x < x0 + size`` and
        ``z0 <= z < z0 + size``: buckets of ``_BUCKET``² columns, sorted once, are gathered
        and filtered, so a window costs its own asset voxels, not all of them."""
        if "_asset_buckets" not in self.__dict__:
            key = (self.extra.z.astype(np.int64) // _BUCKET) * (1 << 31) + (
                self.extra.x.astype(np.int64) // _BUCKET)
            order = np.argsort(key, kind="stable")
            self.__dict__["_asset_buckets"] = (key[order], order)
        keys, order = self.__dict__["_asset_buckets"]
        parts = []
        for bz in range(z0 // _BUCKET, (z0 + size - 1) // _BUCKET + 1):
            row = bz * (1 << 31)
            lo = np.searchsorted(keys, row + x0 // _BUCKET, "left")
            hi = np.searchsorted(keys, row + (x0 + size - 1) // _BUCKET, "right")
            parts.append(order[lo:hi])
        idx = np.sort(np.concatenate(parts)) if parts else np.zeros(0, np.int64)
        x, z = self.extra.x[idx], self.extra.z[idx]
        return idx[(x >= x0) & (x < x0 + size) & (z >= z0) & (z < z0 + size)]
