"""Terrain columns: a Heightmap void-filled, resampled to ``footprint``² columns and quantised
to integer heights with a watertight fill (``terrain_columns`` → ``TerrainColumns``).

This is the geometry every later step reads: colours by height band and slope, asset sites,
and the ground voxels themselves. A column ``(row, col)`` of the DEM is ``(z, x)`` in the voxel
world and heights run along +y, so north is −z and east is +x; the lowest voxel is at y = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from voxfield.checks import is_integer, is_real
from voxfield.errors import SceneFormatError, VoxfieldError
from voxfield.scene.terrain.dem import Heightmap, load_heightmap
from voxfield.scene.terrain.resample import fill_voids, resample

#: Largest footprint accepted (columns per side); 16384² columns is already ~1.3G voxels.
MAX_FOOTPRINT = 16384
#: Smallest: a terrain needs two columns a side to have a slope.
MIN_FOOTPRINT = 2


@dataclass(frozen=True)
class TerrainColumns:
    """The heightfield as voxel columns, indexed ``[z, x]`` (= DEM ``[row, col]``).

    Column ``(z, x)`` holds voxels ``y = bottom .. top`` (inclusive). ``elevation`` is the
    resampled, void-filled DEM in metres; ``water`` marks columns below sea level (their top is
    the flat sea surface); ``slope`` is rise per run in voxel units. ``scale_capped``: the
    relief would have risen above the cube at the asked vertical scale and was scaled down to
    fit (``voxels_per_metre`` is what was used). ``flattened``: the DEM has relief, but at
    that scale all of it came to less than a voxel, so every column has the same top.
    """

    top: np.ndarray
    bottom: np.ndarray
    elevation: np.ndarray
    water: np.ndarray
    slope: np.ndarray
    voxels_per_metre: float
    metres_per_voxel: tuple[float, float] | None
    sea_level: float | None
    name: str = "terrain"
    scale_capped: bool = False
    flattened: bool = False
    relief_metres: float = 0.0

    @property
    def footprint(self) -> int:
        return self.top.shape[0]

    @property
    def counts(self) -> np.ndarray:
        """Voxels per column."""
        return (self.top - self.bottom + 1).astype(np.int64)

    @property
    def voxel_count(self) -> int:
        return int(self.counts.sum())

    @property
    def height_fraction(self) -> np.ndarray:
        """Height of each column top in [0, 1] between the lowest land (or sea) and the peak."""
        lo = int(self.top[self.water].max()) if self.water.any() else int(self.top.min())
        hi = int(self.top.max())
        return np.clip((self.top - lo) / max(hi - lo, 1), 0.0, 1.0).astype(np.float32)


def check_footprint(footprint) -> int:
    """``footprint`` as an int: an integer number of columns in MIN_FOOTPRINT..MAX_FOOTPRINT."""
    if not is_integer(footprint):
        raise VoxfieldError(f"footprint must be an integer number of columns, got {footprint!r}")
    if not MIN_FOOTPRINT <= footprint <= MAX_FOOTPRINT:
        raise VoxfieldError(
            f"footprint must be between {MIN_FOOTPRINT} and {MAX_FOOTPRINT} columns, "
            f"got {footprint}"
        )
    return int(footprint)


#: How a DEM not square on the ground fills the square of columns (``terrain_columns``).
DEM_FITS = ("stretch", "crop")


def square_crop(hm: Heightmap) -> Heightmap:
    """The centred window of the map that is square on the ground (in metres when known)."""
    n_r, n_c = hm.shape
    sy, sx = hm.spacing or (1.0, 1.0)
    side_m = min(hm.ground)
    k_r = max(2, min(n_r, int(round(side_m / sy))))
    k_c = max(2, min(n_c, int(round(side_m / sx))))
    r0, c0 = (n_r - k_r) // 2, (n_c - k_c) // 2
    return hm.crop(slice(r0, r0 + k_r), slice(c0, c0 + k_c))


def terrain_columns(
    heightmap,
    footprint: int = 2048,
    *,
    vertical_scale: float = 1.0,
    max_height: int | None = None,
    fill_depth: int = 4,
    sea_level: float | None = None,
    fit: str = "stretch",
    interpolation: str = "cubic",
    reserve: int = 0,
    void_iterations: int = 64,
) -> TerrainColumns:
    """Void-fill, resample to ``footprint``² columns and quantise heights to voxels.

    Vertical scale: with known spacing, 1 voxel of height = 1 voxel of ground (true scale,
    geometric mean of the two horizontal voxel sizes) times ``vertical_scale``; without it the
    relief spans ``footprint // 4`` voxels times ``vertical_scale``. If the relief would rise
    above ``max_height`` (default: the footprint less ``reserve`` voxels of headroom for
    assets) the scale is reduced to fit, so the scene's bounding box stays a cube.
    Each column is filled from its top down to ``min(top − fill_depth, lowest 4-neighbour
    top)``: steep slopes get no holes. ``fit="crop"`` uses the centred square window of the
    DEM instead of stretching a non-square one.
    """
    footprint = check_footprint(footprint)
    if not is_integer(fill_depth) or fill_depth < 0:
        raise VoxfieldError(f"fill_depth must be a non-negative integer, got {fill_depth!r}")
    real = is_real(vertical_scale)
    if not (real and math.isfinite(vertical_scale) and vertical_scale > 0):
        raise VoxfieldError(f"vertical_scale must be a positive number, got {vertical_scale!r}")
    if fit not in DEM_FITS:
        raise VoxfieldError(f"fit must be 'stretch' or 'crop', got {fit!r}")
    if sea_level is not None and not math.isfinite(sea_level):
        raise VoxfieldError(f"sea_level must be a finite number of metres, got {sea_level!r}")
    hm = load_heightmap(heightmap)
    if fit == "crop":
        hm = square_crop(hm)
    if max_height is None:
        max_height = footprint - 1 - int(reserve)
        smallest = int(fill_depth) + int(reserve) + 1
        if footprint < smallest:  # (the cube's height is the footprint: no room for the fill)
            voxels = "voxel" if reserve == 1 else "voxels"
            kept = f" under {reserve} {voxels} kept for its assets" if reserve else ""
            raise VoxfieldError(
                f"footprint {footprint} is too small for this terrain: it needs at least "
                f"{smallest} columns a side, as its ground is filled {fill_depth} voxels deep"
                f"{kept}")
    elif not 0 <= max_height <= footprint - 1:
        raise VoxfieldError(
            f"max_height must be in 0..{footprint - 1} so the terrain fits a {footprint}³ cube, "
            f"got {max_height}"
        )
    relief_cap = max_height - int(fill_depth)
    if relief_cap < 0:
        raise VoxfieldError(
            f"no room for the terrain: footprint {footprint} leaves {max_height} voxels of height "
            f"after {reserve} reserved for assets, less than fill_depth {fill_depth}"
        )

    elev = resample(
        fill_voids(hm.elevation, void_iterations), (footprint, footprint), interpolation
    )
    water = np.zeros(elev.shape, dtype=bool)
    surface = elev
    if sea_level is not None:
        water = elev < sea_level
        surface = np.maximum(elev, sea_level)
    lo = float(surface.min())
    relief = float(surface.max()) - lo
    if math.isfinite(relief) and relief <= 64 * np.finfo(np.float64).eps * max(
            abs(lo), abs(lo + relief)):
        # The resampling's round-off, not relief: a constant map is flat at any magnitude
        # (at 1e20 m its cubic weights' round-off alone spanned 1e4 m, scaled up to hills).
        surface = np.full_like(surface, lo)
        relief = 0.0
    if not math.isfinite(relief):  # a NaN or infinity anywhere reaches the min or max
        low, high = np.nanmin(hm.elevation), np.nanmax(hm.elevation)
        raise SceneFormatError(f"{hm.name}: heights from {low:g} to {high:g} m span more than "
                               "a number can hold; nothing to build")

    metres_per_voxel = None
    if hm.spacing is not None:
        n_r, n_c = hm.shape
        metres_per_voxel = (n_r * hm.spacing[0] / footprint, n_c * hm.spacing[1] / footprint)
        vpm = vertical_scale / math.sqrt(metres_per_voxel[0] * metres_per_voxel[1])
    else:
        vpm = vertical_scale * (footprint // 4) / relief if relief > 0 else 1.0
    scale_capped = relief * vpm > relief_cap
    if scale_capped:
        vpm = relief_cap / relief
    if not math.isfinite(vpm):  # a relief of a few denormal metres
        raise SceneFormatError(f"{hm.name}: heights span only {relief:g} m, too little to "
                               "scale into voxels")

    top = np.minimum(np.rint((surface - lo) * vpm), relief_cap).astype(np.int32)
    low_nbr = top.copy()
    np.minimum(low_nbr[1:], top[:-1], out=low_nbr[1:])
    np.minimum(low_nbr[:-1], top[1:], out=low_nbr[:-1])
    np.minimum(low_nbr[:, 1:], top[:, :-1], out=low_nbr[:, 1:])
    np.minimum(low_nbr[:, :-1], top[:, 1:], out=low_nbr[:, :-1])
    bottom = np.minimum(top - int(fill_depth), low_nbr)
    shift = int(bottom.min())
    top -= shift
    bottom -= shift
    gz, gx = np.gradient(top.astype(np.float32))
    slope = np.hypot(gz, gx).astype(np.float32)
    return TerrainColumns(
        top=top,
        bottom=bottom,
        elevation=elev,
        water=water,
        slope=slope,
        voxels_per_metre=float(vpm),
        metres_per_voxel=metres_per_voxel,
        sea_level=sea_level,
        name=hm.name,
        scale_capped=bool(scale_capped),
        flattened=bool(relief > 0 and top.max() == top.min()),
        relief_metres=relief,
    )

