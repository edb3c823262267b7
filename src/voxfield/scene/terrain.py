"""Voxel terrain from real elevation data (DEMs), with colours and scattered ``.vox`` assets.

Our stand-in for the EA thesis's production terrain (ch. 4: 2048³ voxels, 15–28M voxels per
area): real DEMs become a 2048×2048-column heightfield of solid voxels, coloured from an image
or a height/slope ramp, with trees and rocks from MagicaVoxel files standing on the surface.

Pipeline (each step a plain function, so tests can check one at a time)::

    load_heightmap ─► Heightmap ─► terrain_columns ─► TerrainColumns ─► terrain_scene ─► VoxelScene
     .hgt .tif .npz   metres+NaN    void fill, resample,   top/bottom per    colours, voxels,
     matplotlib       spacing, geo  integer heights        column, slope     scattered assets

Conventions: row 0 of a heightmap is its northern edge and column 0 its western edge. In the
voxel world a column ``(row, col)`` is ``(z, x) = (row, col)`` and heights run along +y, so
north is −z and east is +x (right-handed, y up). Heights are relative: the lowest filled voxel
is at y = 0.
"""

from __future__ import annotations

import logging
import math
import numbers
import re
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import ndimage, sparse

from voxfield.errors import DataNotFoundError, SceneFormatError, SceneTooLargeError, VoxfieldError
from voxfield.scene.voxel_scene import VoxelScene, srgb_to_linear

__all__ = [
    "MAX_FOOTPRINT",
    "RECIPES",
    "SAMPLE_DEMS",
    "AssetGroup",
    "AssetSpec",
    "ColorRamp",
    "GeoGrid",
    "Heightmap",
    "Placements",
    "Recipe",
    "TerrainColumns",
    "downsample_scene",
    "fill_voids",
    "load_heightmap",
    "place_assets",
    "poisson_disk",
    "read_geotiff",
    "read_hgt",
    "read_npz",
    "recipe_scene",
    "resample",
    "terrain_columns",
    "terrain_scene",
]

#: Largest footprint accepted (columns per side); 16384² columns is already ~1.3G voxels.
MAX_FOOTPRINT = 16384
#: Default cap on the voxels one terrain may hold (≈ 36 bytes each once built): a memory guard.
MAX_TERRAIN_VOXELS = 250_000_000
#: Metres per degree on a spherical Earth (mean radius 6,371,008.8 m).
METRES_PER_DEGREE = 2 * math.pi * 6_371_008.8 / 360
#: matplotlib's sample DEMs, by the short names ``load_heightmap`` accepts.
SAMPLE_DEMS = {"jacksboro": "jacksboro_fault_dem.npz", "topobathy": "topobathy.npz"}
#: Values that mean "no data" in DEMs whatever their tags say (SRTM's void and GDAL's habit).
_VOID_SENTINELS = (-32768.0, -9999.0)
#: SRTM tile edge lengths (samples) by file size in bytes.
_HGT_SIZES = {2 * 1201 * 1201: 1201, 2 * 3601 * 3601: 3601}


# --------------------------------------------------------------------------------------------
# Heightmaps


@dataclass(frozen=True)
class GeoGrid:
    """Where a sample grid lies: sample ``(row, col)``'s centre is at
    ``(x0 + col * dx, y0 - row * dy)``; row 0 is the northern edge.

    ``geographic``: x/y are longitude/latitude degrees; otherwise projected units (metres).
    Kept so a colour image can be laid onto a DEM by position, not just stretched over it.
    """

    x0: float
    y0: float
    dx: float
    dy: float
    geographic: bool = True

    def spacing_m(self, rows: int) -> tuple[float, float]:
        """Metres per sample (north–south, east–west), on a sphere at the grid's mid-latitude."""
        if not self.geographic:
            return (abs(self.dy), abs(self.dx))
        mid_lat = self.y0 - self.dy * (rows - 1) / 2
        ew = abs(self.dx) * METRES_PER_DEGREE * math.cos(math.radians(mid_lat))
        return (abs(self.dy) * METRES_PER_DEGREE, ew)

    def shifted(self, row: float, col: float) -> GeoGrid:
        """The grid whose sample (0, 0) is this grid's sample (row, col)."""
        return replace(self, x0=self.x0 + col * self.dx, y0=self.y0 - row * self.dy)


@dataclass(frozen=True)
class Heightmap:
    """Elevations in metres (2-D float64, NaN for voids), row 0 north, column 0 west.

    ``spacing`` is metres per sample (north–south, east–west) when known: it sets the true
    vertical scale. ``geo`` places the grid on the Earth (or a projection) when known.
    """

    elevation: np.ndarray
    spacing: tuple[float, float] | None = None
    geo: GeoGrid | None = None
    name: str = "heightmap"

    def __post_init__(self) -> None:
        arr = np.asarray(self.elevation)
        if arr.ndim != 2:
            raise SceneFormatError(
                f"{self.name}: a heightmap must be a 2-D array, got {arr.ndim}-D {arr.shape}"
            )
        if min(arr.shape) < 2:
            raise SceneFormatError(
                f"{self.name}: a heightmap needs at least 2×2 samples, got {arr.shape}"
            )
        if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
            raise SceneFormatError(f"{self.name}: heights must be numbers, got dtype {arr.dtype}")
        elev = arr.astype(np.float64)  # always a copy: the heightmap owns its samples
        elev[~np.isfinite(elev)] = np.nan
        if np.isnan(elev).all():
            raise SceneFormatError(
                f"{self.name}: every sample is a void (no data); nothing to build"
            )
        object.__setattr__(self, "elevation", elev)
        spacing = self.spacing
        if spacing is None and self.geo is not None:
            spacing = self.geo.spacing_m(elev.shape[0])
        if spacing is not None:
            spacing = tuple(float(s) for s in np.broadcast_to(np.asarray(spacing, float), (2,)))
            if not all(math.isfinite(s) and s > 0 for s in spacing):
                raise SceneFormatError(
                    f"{self.name}: spacing must be positive metres, got {spacing}"
                )
        object.__setattr__(self, "spacing", spacing)

    @property
    def shape(self) -> tuple[int, int]:
        return self.elevation.shape

    @property
    def voids(self) -> int:
        """Number of samples without data."""
        return int(np.isnan(self.elevation).sum())

    def crop(self, rows: slice, cols: slice) -> Heightmap:
        """A window of the map (geo position and spacing follow)."""
        r = range(*rows.indices(self.shape[0]))
        c = range(*cols.indices(self.shape[1]))
        if r.step != 1 or c.step != 1:
            raise VoxfieldError("crop takes contiguous slices (step 1)")
        geo = None if self.geo is None else self.geo.shifted(r.start, c.start)
        return Heightmap(self.elevation[rows, cols], self.spacing, geo, self.name)

    def window(self, r0: float, r1: float, c0: float, c1: float) -> Heightmap:
        """A window given as fractions of the map (0..1), so recipes do not depend on its size."""
        if not (0 <= r0 < r1 <= 1 and 0 <= c0 < c1 <= 1):
            raise VoxfieldError(f"window fractions need 0 <= lo < hi <= 1, got {(r0, r1, c0, c1)}")

        def span(lo: float, hi: float, n: int) -> slice:
            start = min(int(round(lo * n)), n - 2)
            return slice(start, max(int(round(hi * n)), start + 2))

        return self.crop(span(r0, r1, self.shape[0]), span(c0, c1, self.shape[1]))


@contextmanager
def _quiet_tifffile():
    """Hide tifffile's log noise (it complains about ``GDAL_NODATA = nan`` while decoding)."""
    logger = logging.getLogger("tifffile")
    previous = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(previous)


def _existing(path) -> Path:
    path = Path(path)
    if not path.is_file():
        raise DataNotFoundError(f"{path}: no such file")
    return path


def read_hgt(path) -> Heightmap:
    """An SRTM ``.hgt`` tile: big-endian int16 metres, square 1201² (3″) or 3601² (1″).

    The edge length comes from the file size; −32768 marks voids. A name like ``N40W074``
    (the tile's south-west corner) gives its position; sample centres sit on whole degrees.
    """
    path = _existing(path)
    size = path.stat().st_size
    n = _HGT_SIZES.get(size)
    if n is None:
        raise SceneFormatError(
            f"{path}: {size:,} bytes is not an SRTM .hgt tile (expected {2 * 1201**2:,} bytes "
            f"for 1201×1201 or {2 * 3601**2:,} for 3601×3601 big-endian int16 samples)"
        )
    raw = np.fromfile(path, dtype=">i2").reshape(n, n)
    elev = raw.astype(np.float64)
    elev[raw == -32768] = np.nan
    geo = None
    m = re.fullmatch(r"([NS])(\d{1,2})([EW])(\d{1,3})", path.stem.upper())
    if m:
        lat = int(m.group(2)) * (1 if m.group(1) == "N" else -1)
        lon = int(m.group(4)) * (1 if m.group(3) == "E" else -1)
        step = 1.0 / (n - 1)
        geo = GeoGrid(x0=float(lon), y0=float(lat + 1), dx=step, dy=step)
    return Heightmap(elev, geo=geo, name=path.stem)


def _geotiff_grid(page) -> GeoGrid | None:
    """The GeoGrid of a GeoTIFF page from its pixel-scale, tie-point and geo-key tags."""
    tags = page.tags
    scale = tags.get(33550)
    tie = tags.get(33922)
    if scale is None or tie is None:
        return None
    sx, sy = float(scale.value[0]), float(scale.value[1])
    i, j, _, x, y, _ = (float(v) for v in tie.value[:6])
    keys = tags.get(34735)
    model_type, raster_type = 2, 1  # geographic, pixel-is-area: GeoTIFF's usual defaults
    if keys is not None:
        k = list(keys.value)
        for e in range(4, 4 + 4 * k[3], 4):
            key, loc, _count, val = k[e : e + 4]
            if loc == 0 and key == 1024:
                model_type = val
            elif loc == 0 and key == 1025:
                raster_type = val
    if sx <= 0 or sy <= 0:
        return None
    # The tie point names pixel (i, j)'s corner (area) or centre (point); we store centres.
    half = 0.5 if raster_type == 1 else 0.0
    x0 = x + (half - i) * sx
    y0 = y - (half - j) * sy
    return GeoGrid(x0=x0, y0=y0, dx=sx, dy=sy, geographic=model_type != 1)


def _gdal_nodata(page) -> float | None:
    tag = page.tags.get(42113)
    if tag is None:
        return None
    try:
        return float(str(tag.value).strip("\x00 "))
    except ValueError:
        return None


def read_geotiff(path) -> Heightmap:
    """A single-band GeoTIFF DEM (int or float). Voids: the GDAL_NODATA tag, −32768, −9999, NaN."""
    import tifffile

    path = _existing(path)
    try:
        with _quiet_tifffile(), tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            arr = page.asarray()
            nodata = _gdal_nodata(page)
            geo = _geotiff_grid(page)
    except (tifffile.TiffFileError, ValueError, OSError) as exc:
        raise SceneFormatError(f"{path}: not a readable TIFF ({exc})") from exc
    arr = np.squeeze(arr)
    if arr.ndim != 2:
        raise SceneFormatError(
            f"{path}: a DEM needs one band of heights, this TIFF holds an array of shape "
            f"{arr.shape} (an RGB image? pass it as colors= instead)"
        )
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise SceneFormatError(f"{path}: unsupported sample type {arr.dtype}")
    elev = arr.astype(np.float64)
    void = ~np.isfinite(elev) | np.isin(elev, _VOID_SENTINELS)
    if nodata is not None and math.isfinite(nodata):
        void |= elev == nodata
    elev[void] = np.nan
    return Heightmap(elev, geo=geo, name=path.stem)


def _npz_grid(data: Mapping[str, np.ndarray], shape: tuple[int, int]):
    """(GeoGrid or None, flip rows?) from the coordinate arrays some DEM .npz files carry."""
    n_r, n_c = shape
    if "latitude" in data and "longitude" in data:
        lat = np.asarray(data["latitude"], float).ravel()
        lon = np.asarray(data["longitude"], float).ravel()
        if len(lat) == n_r and len(lon) == n_c and n_r > 1 and n_c > 1:
            lon = np.where(lon > 180, lon - 360, lon)
            flip = lat[-1] > lat[0]  # rows run south to north: flip so row 0 is north
            north = lat.max()
            return GeoGrid(
                x0=float(lon[0]),
                y0=float(north),
                dx=float((lon[-1] - lon[0]) / (n_c - 1)),
                dy=float(abs(lat[-1] - lat[0]) / (n_r - 1)),
            ), flip
    keys = ("dx", "dy", "xmin", "xmax", "ymin", "ymax")
    if all(k in data for k in keys):
        dx, dy, xmin, xmax, ymin, ymax = (float(np.asarray(data[k])) for k in keys)
        if dx > 0 and dy > 0:
            geographic = max(abs(xmin), abs(xmax)) <= 360 and max(abs(ymin), abs(ymax)) <= 90
            # Bounds are pixel edges when they span n samples, centres when they span n - 1.
            edges = abs(abs(xmax - xmin) / dx - n_c) < abs(abs(xmax - xmin) / dx - (n_c - 1))
            half = 0.5 if edges else 0.0
            grid = GeoGrid(
                x0=min(xmin, xmax) + half * dx,
                y0=max(ymin, ymax) - half * dy,
                dx=dx,
                dy=dy,
                geographic=geographic,
            )
            return grid, False
    return None, False


def read_npz(path, name: str | None = None) -> Heightmap:
    """A DEM in ``.npz``: the ``elevation`` array, or the only 2-D array in the file.

    Position comes from ``latitude``/``longitude`` vectors (rows flipped to north-first when
    latitude ascends, as in matplotlib's ``topobathy.npz``) or from ``dx, dy, xmin, xmax, ymin,
    ymax`` (``jacksboro_fault_dem.npz``, whose rows already run north to south); a ``spacing``
    entry gives metres per sample directly.
    """
    path = _existing(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
    except Exception as exc:  # noqa: BLE001 - numpy raises many kinds for a bad archive
        raise SceneFormatError(f"{path}: not a readable .npz archive ({exc})") from exc
    name = name or path.stem
    if "elevation" in data:
        elev = data["elevation"]
    else:
        grids = [k for k, v in data.items() if np.ndim(v) == 2]
        if len(grids) != 1:
            raise SceneFormatError(
                f"{path}: expected an 'elevation' array or exactly one 2-D array, found 2-D "
                f"arrays {grids or 'none'} among {sorted(data)}"
            )
        elev = data[grids[0]]
    elev = np.asarray(elev)
    if elev.ndim != 2:
        raise SceneFormatError(f"{path}: 'elevation' must be 2-D, got shape {elev.shape}")
    geo, flip = _npz_grid(data, elev.shape)
    if flip:
        elev = elev[::-1]
    spacing = None
    if "spacing" in data:
        spacing = tuple(np.broadcast_to(np.asarray(data["spacing"], float), (2,)))
    return Heightmap(elev, spacing=spacing, geo=geo, name=name)


def load_heightmap(source) -> Heightmap:
    """A Heightmap from a path (``.hgt``, ``.tif``/``.tiff``, ``.npz``, ``.npy``), a 2-D array,
    or the name of one of matplotlib's sample DEMs (``jacksboro``, ``topobathy``)."""
    if isinstance(source, Heightmap):
        return source
    if isinstance(source, np.ndarray):
        return Heightmap(source)
    if isinstance(source, str) and source.lower() in SAMPLE_DEMS:
        from matplotlib import cbook

        path = cbook.get_sample_data(SAMPLE_DEMS[source.lower()], asfileobj=False)
        return read_npz(path, name=source.lower())
    path = Path(source)
    if not path.exists():
        raise DataNotFoundError(
            f"{path}: no such file (or name a sample DEM: {', '.join(sorted(SAMPLE_DEMS))})"
        )
    suffix = path.suffix.lower()
    if suffix == ".hgt":
        return read_hgt(path)
    if suffix in (".tif", ".tiff"):
        return read_geotiff(path)
    if suffix == ".npz":
        return read_npz(path)
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001
            raise SceneFormatError(f"{path}: not a readable .npy array ({exc})") from exc
        return Heightmap(arr, name=path.stem)
    raise SceneFormatError(
        f"{path}: unknown DEM format {suffix!r} (expected .hgt, .tif, .npz, .npy)"
    )


# --------------------------------------------------------------------------------------------
# Void filling and resampling


def fill_voids(elevation: np.ndarray, iterations: int = 64) -> np.ndarray:
    """Voids (NaN) replaced: nearest valid sample, then ``iterations`` Jacobi steps of Laplace
    smoothing over the void samples only.

    Nearest-fill alone leaves flat terraces with seams (Voronoi cells of the rim); the
    smoothing relaxes them towards the harmonic (membrane) fill. Both steps only average rim
    values, so filled heights stay within the range of the valid samples around each void.
    """
    elev = np.asarray(elevation, dtype=np.float64)
    void = np.isnan(elev)
    if not void.any():
        return elev.copy()
    if void.all():
        raise SceneFormatError("every sample is a void; nothing to fill from")
    idx = ndimage.distance_transform_edt(void, return_distances=False, return_indices=True)
    filled = elev[tuple(idx)]
    if iterations > 0:
        n_r, n_c = elev.shape
        r, c = np.nonzero(void)
        flat = filled.ravel()
        vi = r * n_c + c
        # Neighbours clamped at the border (a mirror boundary: no flux through the map edge).
        nbrs = [
            np.maximum(r - 1, 0) * n_c + c,
            np.minimum(r + 1, n_r - 1) * n_c + c,
            r * n_c + np.maximum(c - 1, 0),
            r * n_c + np.minimum(c + 1, n_c - 1),
        ]
        for _ in range(iterations):
            flat[vi] = 0.25 * (flat[nbrs[0]] + flat[nbrs[1]] + flat[nbrs[2]] + flat[nbrs[3]])
    return filled


def _keys_cubic(t: np.ndarray) -> np.ndarray:
    """Keys' cubic convolution kernel (a = −0.5, Catmull–Rom): interpolating, exact on ramps."""
    t = np.abs(t)
    return np.where(
        t <= 1,
        1.5 * t**3 - 2.5 * t**2 + 1,
        np.where(t < 2, -0.5 * t**3 + 2.5 * t**2 - 4 * t + 2, 0.0),
    )


def _axis_weights(pos: np.ndarray, n_in: int, kind: str, scale: float) -> sparse.csr_matrix:
    """Sparse (len(pos) × n_in) interpolation weights at fractional sample positions ``pos``.

    ``scale`` > 1 widens the kernel (antialiasing when shrinking); taps past the ends are
    clamped to the edge samples; each row sums to 1.
    """
    support = {"cubic": 2.0, "linear": 1.0}[kind]
    kernel = _keys_cubic if kind == "cubic" else lambda t: np.maximum(0.0, 1.0 - np.abs(t))
    reach = support * scale
    taps = np.arange(-math.ceil(reach), math.ceil(reach) + 1)
    base = np.floor(pos).astype(np.int64)
    idx = base[:, None] + taps[None, :]
    w = kernel((idx - pos[:, None]) / scale)
    w /= w.sum(axis=1, keepdims=True)
    rows = np.repeat(np.arange(len(pos)), len(taps))
    cols = np.clip(idx, 0, n_in - 1).ravel()
    return sparse.csr_matrix((w.ravel(), (rows, cols)), shape=(len(pos), n_in))


def _centres(n_in: int, n_out: int) -> np.ndarray:
    """Input positions of ``n_out`` samples spanning the same extent (pixel-centre aligned)."""
    return (np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5


def resample(grid: np.ndarray, shape: tuple[int, int], kind: str = "cubic") -> np.ndarray:
    """A 2-D array resampled to ``shape`` (separable cubic or linear, antialiased when shrinking).

    Same extent in and out (pixel-centre alignment). Separable sparse weights: one matrix
    product per axis, ~0.1 s for 2048² from any DEM here.
    """
    if kind not in ("cubic", "linear"):
        raise VoxfieldError(f"resample kind must be 'cubic' or 'linear', got {kind!r}")
    grid = np.asarray(grid, dtype=np.float64)
    if grid.shape == tuple(shape):
        return grid.copy()
    (n_r, n_c), (m_r, m_c) = grid.shape, shape
    w_r = _axis_weights(_centres(n_r, m_r), n_r, kind, max(1.0, n_r / m_r))
    w_c = _axis_weights(_centres(n_c, m_c), n_c, kind, max(1.0, n_c / m_c))
    tmp = w_r @ grid  # (m_r, n_c)
    return np.ascontiguousarray((w_c @ tmp.T).T)


# --------------------------------------------------------------------------------------------
# Columns: integer heights with watertight fill


@dataclass(frozen=True)
class TerrainColumns:
    """The heightfield as voxel columns, indexed ``[z, x]`` (= DEM ``[row, col]``).

    Column ``(z, x)`` holds voxels ``y = bottom .. top`` (inclusive). ``elevation`` is the
    resampled, void-filled DEM in metres; ``water`` marks columns below sea level (their top is
    the flat sea surface); ``slope`` is rise per run in voxel units.
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


def _check_footprint(footprint) -> int:
    if isinstance(footprint, bool) or not isinstance(footprint, (int, np.integer)):
        raise VoxfieldError(f"footprint must be an integer number of columns, got {footprint!r}")
    if not 2 <= footprint <= MAX_FOOTPRINT:
        raise VoxfieldError(
            f"footprint must be between 2 and {MAX_FOOTPRINT} columns, got {footprint}"
        )
    return int(footprint)


def _square_crop(hm: Heightmap) -> Heightmap:
    """The centred window of the map that is square on the ground (in metres when known)."""
    n_r, n_c = hm.shape
    sy, sx = hm.spacing or (1.0, 1.0)
    side_m = min(n_r * sy, n_c * sx)
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
    footprint = _check_footprint(footprint)
    if (
        isinstance(fill_depth, bool)
        or not isinstance(fill_depth, (int, np.integer))
        or fill_depth < 0
    ):
        raise VoxfieldError(f"fill_depth must be a non-negative integer, got {fill_depth!r}")
    real = isinstance(vertical_scale, numbers.Real) and not isinstance(vertical_scale, bool)
    if not (real and math.isfinite(vertical_scale) and vertical_scale > 0):
        raise VoxfieldError(f"vertical_scale must be a positive number, got {vertical_scale!r}")
    if fit not in ("stretch", "crop"):
        raise VoxfieldError(f"fit must be 'stretch' or 'crop', got {fit!r}")
    if sea_level is not None and not math.isfinite(sea_level):
        raise VoxfieldError(f"sea_level must be a finite number of metres, got {sea_level!r}")
    hm = load_heightmap(heightmap)
    if fit == "crop":
        hm = _square_crop(hm)
    if max_height is None:
        max_height = footprint - 1 - int(reserve)
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

    metres_per_voxel = None
    if hm.spacing is not None:
        n_r, n_c = hm.shape
        metres_per_voxel = (n_r * hm.spacing[0] / footprint, n_c * hm.spacing[1] / footprint)
        vpm = vertical_scale / math.sqrt(metres_per_voxel[0] * metres_per_voxel[1])
    else:
        vpm = vertical_scale * (footprint // 4) / relief if relief > 0 else 1.0
    if relief * vpm > relief_cap:
        vpm = relief_cap / relief

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
    )


# --------------------------------------------------------------------------------------------
# Colours


def _lin(rgb) -> np.ndarray:
    return srgb_to_linear(np.asarray(rgb, dtype=np.float32))


@dataclass(frozen=True)
class ColorRamp:
    """Surface colours by height band and slope; sRGB triples (decoded to linear on use).

    Height fraction ``h`` runs 0 (lowest land, or sea level) to 1 (peak). Below ``beach_line``
    ground is ``low``; above it blends ``mid`` → ``high``; slopes steeper than ``rock_slope``
    (rise per run) are ``rock``; above ``snow_line`` and flatter than ``snow_max_slope``, snow.
    ``jitter`` moves band edges per column (ragged, partly covered borders, like the thesis's
    snow lines) and ``noise`` varies brightness per column (texture noise); both are seeded.
    """

    low: tuple[float, float, float] = (0.78, 0.70, 0.50)
    mid: tuple[float, float, float] = (0.30, 0.46, 0.18)
    high: tuple[float, float, float] = (0.42, 0.44, 0.28)
    rock: tuple[float, float, float] = (0.46, 0.43, 0.40)
    snow: tuple[float, float, float] = (0.93, 0.94, 0.97)
    shallow: tuple[float, float, float] = (0.16, 0.40, 0.50)
    deep: tuple[float, float, float] = (0.03, 0.11, 0.24)
    earth: tuple[float, float, float] = (0.35, 0.25, 0.17)
    beach_line: float = 0.03
    snow_line: float = 0.8
    rock_slope: float = 1.5
    snow_max_slope: float = 2.0
    jitter: float = 0.04
    noise: float = 0.06


def _ramp_colors(cols: TerrainColumns, ramp: ColorRamp, rng: np.random.Generator) -> np.ndarray:
    """Per-column linear surface colour (F×F×3 float32) from the ramp."""
    shape = cols.top.shape

    def uniform() -> np.ndarray:  # in [-1, 1), float32 throughout (this runs on 4M columns)
        return rng.random(shape, dtype=np.float32) * np.float32(2) - np.float32(1)

    u, v = uniform(), uniform()
    h = cols.height_fraction + np.float32(ramp.jitter) * u
    span = np.float32(max(ramp.snow_line - ramp.beach_line, 1e-6))
    t = np.clip((h - np.float32(ramp.beach_line)) / span, 0, 1)
    t = t * t * (3 - 2 * t)  # smoothstep
    mid, high = _lin(ramp.mid), _lin(ramp.high)
    rgb = mid + t[..., None] * (high - mid)
    del t
    rgb[h < ramp.beach_line] = _lin(ramp.low)
    wobble = 1 + np.float32(0.25) * v
    rgb[cols.slope > np.float32(ramp.rock_slope) * wobble] = _lin(ramp.rock)
    snowy = (h > ramp.snow_line) & (cols.slope < np.float32(ramp.snow_max_slope) * wobble)
    rgb[snowy] = _lin(ramp.snow)
    if cols.water.any():
        below = (cols.sea_level - cols.elevation[cols.water]).astype(np.float32)
        depth = np.sqrt(below / max(float(below.max()), 1e-6))[:, None]
        shallow, deep = _lin(ramp.shallow), _lin(ramp.deep)
        rgb[cols.water] = shallow + depth * (deep - shallow)
    if ramp.noise:
        rgb *= (1 + np.float32(ramp.noise) * uniform())[..., None]
    return np.clip(rgb, 0.0, 1.0, out=rgb)


def _read_color_image(source) -> tuple[np.ndarray, GeoGrid | None]:
    """A linear RGB image (H×W×3 float32) and its GeoGrid if it is a GeoTIFF.

    Integer images are sRGB-encoded (decoded here); float images are taken as linear [0, 1].
    """
    if isinstance(source, np.ndarray):
        img, geo = source, None
        if img.ndim != 3 or img.shape[2] not in (3, 4):
            raise VoxfieldError(f"a colour image array must be H×W×3 linear RGB, got {img.shape}")
        return np.clip(img[..., :3].astype(np.float32), 0, 1), None
    path = _existing(source)
    geo = None
    if path.suffix.lower() in (".tif", ".tiff"):
        import tifffile

        try:
            with _quiet_tifffile(), tifffile.TiffFile(path) as tif:
                page = tif.pages[0]
                img = page.asarray()
                geo = _geotiff_grid(page)
        except (tifffile.TiffFileError, ValueError, OSError) as exc:
            raise SceneFormatError(f"{path}: not a readable TIFF image ({exc})") from exc
    else:
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(path) as im:
                img = np.asarray(im.convert("RGB") if im.mode not in ("I;16", "F") else im)
        except (UnidentifiedImageError, OSError) as exc:
            raise SceneFormatError(f"{path}: not a readable image ({exc})") from exc
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] < 3:
        raise SceneFormatError(f"{path}: expected an RGB image, got shape {img.shape}")
    img = img[..., :3]
    if np.issubdtype(img.dtype, np.integer):
        top = 65535.0 if img.dtype.itemsize > 1 else 255.0
        rgb = srgb_to_linear(img.astype(np.float32) / top)
    else:
        rgb = np.clip(np.nan_to_num(img.astype(np.float32)), 0.0, 1.0)
    return rgb, geo


def _image_colors(
    cols: TerrainColumns, hm: Heightmap, image, fit: str
) -> tuple[np.ndarray, np.ndarray]:
    """Per-column linear colour sampled from an image, and where the image covers the terrain.

    A GeoTIFF laid on a DEM with a position of the same kind is placed by position (parts of
    the terrain it misses are reported uncovered); otherwise it is stretched over the terrain.
    """
    rgb, img_geo = _read_color_image(image)
    f = cols.footprint
    if fit == "crop":
        hm = _square_crop(hm)
    n_r, n_c = hm.shape
    rows = _centres(n_r, f)  # DEM sample coordinates of each column
    cs = _centres(n_c, f)
    h_i, w_i = rgb.shape[:2]
    if img_geo is not None and hm.geo is not None and img_geo.geographic == hm.geo.geographic:
        g = hm.geo
        pr = ((img_geo.y0 - (g.y0 - rows * g.dy)) / img_geo.dy).astype(np.float64)
        pc = ((g.x0 + cs * g.dx - img_geo.x0) / img_geo.dx).astype(np.float64)
    else:
        pr = _centres(h_i, f)
        pc = _centres(w_i, f)
    in_r = (pr >= -0.5) & (pr <= h_i - 0.5)
    in_c = (pc >= -0.5) & (pc <= w_i - 0.5)
    w_r = _axis_weights(pr, h_i, "linear", max(1.0, h_i / f))
    w_c = _axis_weights(pc, w_i, "linear", max(1.0, w_i / f))
    out = np.empty((f, f, 3), np.float32)
    for ch in range(3):
        out[..., ch] = (w_c @ (w_r @ rgb[..., ch].astype(np.float64)).T).T
    covered = in_r[:, None] & in_c[None, :]
    return np.clip(out, 0.0, 1.0), covered


# --------------------------------------------------------------------------------------------
# Asset scattering


@dataclass(frozen=True)
class AssetGroup:
    """Models scattered together under one set of placement rules.

    ``density`` is the fraction (0..1) of a packed Poisson-disk set of sites kept; ``spacing``
    the minimum distance between sites in voxels (default: the widest model's footprint, so
    models do not intersect). Sites need slope ≤ ``max_slope`` (rise per run), dry land and a
    height fraction within ``height_range``. ``clumping`` > 0 gathers sites into groves (a
    smooth seeded density field); ``rotate`` turns each model by a random multiple of 90°
    about y; ``embed`` sinks models that many voxels into the ground (0: base at top + 1).
    """

    models: Sequence[VoxelScene]
    density: float = 0.3
    spacing: float | None = None
    max_slope: float = 1.0
    height_range: tuple[float, float] = (0.0, 1.0)
    clumping: float = 0.0
    rotate: bool = True
    embed: int = 0

    def __post_init__(self) -> None:
        models = tuple(self.models)
        if not models or not all(isinstance(m, VoxelScene) and len(m) for m in models):
            raise VoxfieldError("an asset group needs at least one non-empty VoxelScene model")
        object.__setattr__(self, "models", models)
        if not 0.0 <= self.density <= 1.0:
            raise VoxfieldError(f"asset density must be in [0, 1], got {self.density}")
        if self.spacing is not None and not self.spacing >= 1:
            raise VoxfieldError(f"asset spacing must be at least 1 voxel, got {self.spacing}")
        if self.embed < 0:
            raise VoxfieldError(f"embed must be >= 0 voxels, got {self.embed}")

    @property
    def height(self) -> int:
        """Tallest model height in voxels (headroom the terrain must leave)."""
        return max(int(m.extent[1]) for m in self.models) - int(self.embed)

    @property
    def width(self) -> int:
        return max(int(max(m.extent[0], m.extent[2])) for m in self.models)


@dataclass(frozen=True)
class Placements:
    """Where assets stand: anchor column ``(x, z)``, base height ``y`` (lowest model voxel),
    model index and quarter turns about y; one entry per placed asset."""

    x: np.ndarray
    z: np.ndarray
    y: np.ndarray
    model: np.ndarray
    turns: np.ndarray

    def __len__(self) -> int:
        return len(self.x)


def poisson_disk(size: int, spacing: float, rng: np.random.Generator, tries: int = 8) -> np.ndarray:
    """Points (n×2, x then z) in ``[0, size)²`` at least ``spacing`` apart, nearly packed.

    Parallel dart throwing on a grid of cells ``spacing/√2`` wide (one point per cell): cells
    are processed in 9 phase groups whose members are 3 cells apart, so a group's candidates
    cannot conflict and each group is one vectorised test against the 5×5 cells around it.
    """
    r = float(spacing)
    cell = r / math.sqrt(2)
    g = int(math.ceil(size / cell))
    pts = np.full((g + 4, g + 4, 2), np.nan)  # padded by 2 cells each side
    for phase in rng.permutation(9):
        ci, cj = np.meshgrid(np.arange(phase // 3, g, 3), np.arange(phase % 3, g, 3), indexing="ij")
        ci, cj = ci.ravel(), cj.ravel()
        for _ in range(tries):
            empty = np.isnan(pts[ci + 2, cj + 2, 0])
            if not empty.any():
                break
            ei, ej = ci[empty], cj[empty]
            cand = (np.stack([ei, ej], axis=1) + rng.random((len(ei), 2))) * cell  # (z, x)
            ok = (cand < size).all(axis=1)
            for di in range(-2, 3):
                for dj in range(-2, 3):
                    if di == 0 and dj == 0:
                        continue
                    nb = pts[ei + 2 + di, ej + 2 + dj]
                    d2 = ((nb - cand) ** 2).sum(axis=1)
                    ok &= ~(d2 < r * r)  # NaN (empty cell) compares False: no conflict
            pts[ei[ok] + 2, ej[ok] + 2] = cand[ok]
    inner = pts[2:-2, 2:-2].reshape(-1, 2)
    inner = inner[~np.isnan(inner[:, 0])]
    return inner[:, ::-1].copy()  # (x, z)


def _rotated(model: VoxelScene, turns: int) -> tuple[np.ndarray, np.ndarray]:
    """Model voxels turned ``turns`` × 90° about y, relative to its anchor (base layer's centre,
    base at y = 0), and the (x, z) bounds of that relative box."""
    c = model.coords.copy()
    for _ in range(turns % 4):
        c[:, 0], c[:, 2] = c[:, 2].copy(), -c[:, 0]
    base = c[:, 1] == c[:, 1].min()
    anchor = np.array(
        [np.floor(c[base, 0].mean() + 0.5), c[:, 1].min(), np.floor(c[base, 2].mean() + 0.5)],
        dtype=np.int64,
    )
    rel = c - anchor
    return rel, np.array([rel[:, 0].min(), rel[:, 0].max(), rel[:, 2].min(), rel[:, 2].max()])


def place_assets(cols: TerrainColumns, group: AssetGroup, rng: np.random.Generator) -> Placements:
    """Seeded sites for one asset group: Poisson-disk, filtered by slope, water and height band,
    thinned to ``density`` (modulated by clumping), each model fully inside the map."""
    f = cols.footprint
    spacing = group.spacing if group.spacing is not None else max(group.width, 1)
    pts = poisson_disk(f, spacing, rng)
    n_models = len(group.models)
    model = rng.integers(n_models, size=len(pts))
    turns = rng.integers(4, size=len(pts)) if group.rotate else np.zeros(len(pts), np.int64)
    keep_u = rng.random(len(pts))
    if group.clumping > 0:
        noise = rng.standard_normal((max(f // 16, 2),) * 2)
        noise = ndimage.gaussian_filter(noise, sigma=max(f // 16, 2) / 12, mode="wrap")
        noise = (noise - noise.mean()) / (noise.std() + 1e-12)
        field_ = np.exp(3.0 * group.clumping * noise)
        field_ /= field_.mean()
        field_ = resample(field_, (f, f), "linear")
    x = np.floor(pts[:, 0]).astype(np.int64)
    z = np.floor(pts[:, 1]).astype(np.int64)
    hfrac = cols.height_fraction[z, x]
    ok = (cols.slope[z, x] <= group.max_slope) & ~cols.water[z, x]
    ok &= (hfrac >= group.height_range[0]) & (hfrac <= group.height_range[1])
    p = np.full(len(pts), group.density)
    if group.clumping > 0:
        p = np.minimum(1.0, group.density * field_[z, x])
    ok &= keep_u < p
    boxes = np.array([[_rotated(mod, t)[1] for t in range(4)] for mod in group.models])
    box = boxes[model, turns].reshape(-1, 4)
    ok &= (x + box[:, 0] >= 0) & (x + box[:, 1] < f) & (z + box[:, 2] >= 0) & (z + box[:, 3] < f)
    x, z, model, turns = x[ok], z[ok], model[ok], turns[ok]
    y = cols.top[z, x].astype(np.int64) + 1 - int(group.embed)
    return Placements(x=x, z=z, y=y, model=model, turns=turns)


@dataclass
class _AssetVoxels:
    """Asset voxels as flat arrays (int32 x, y, z; float32 colours), before they join the ground."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    color: np.ndarray
    emission: np.ndarray | None

    def __len__(self) -> int:
        return len(self.x)

    def take(self, idx: np.ndarray) -> _AssetVoxels:
        em = None if self.emission is None else self.emission[idx]
        return _AssetVoxels(self.x[idx], self.y[idx], self.z[idx], self.color[idx], em)

    @staticmethod
    def join(parts: Sequence[_AssetVoxels]) -> _AssetVoxels:
        if not parts:
            z = np.zeros(0, np.int32)
            return _AssetVoxels(z, z, z, np.zeros((0, 3), np.float32), None)
        emission = None
        if any(p.emission is not None for p in parts):
            emission = np.concatenate(
                [p.emission if p.emission is not None else np.zeros_like(p.color) for p in parts]
            )
        return _AssetVoxels(
            np.concatenate([p.x for p in parts]),
            np.concatenate([p.y for p in parts]),
            np.concatenate([p.z for p in parts]),
            np.concatenate([p.color for p in parts]),
            emission,
        )


def _instantiate(cols: TerrainColumns, group: AssetGroup, placed: Placements) -> _AssetVoxels:
    """Voxels of the placed models, minus those buried in the ground (the ground wins)."""
    f = cols.footprint
    any_emission = any(m.emission is not None for m in group.models)
    top = cols.top.ravel()
    parts = []
    for m, model in enumerate(group.models):
        for t in range(4):
            sel = (placed.model == m) & (placed.turns == t)
            if not sel.any():
                continue
            rel, _ = _rotated(model, t)
            rel = rel.astype(np.int32)
            # int32 and one axis at a time: this is the hot loop of a dense forest (~10M voxels).
            x = (placed.x[sel].astype(np.int32)[:, None] + rel[None, :, 0]).ravel()
            z = (placed.z[sel].astype(np.int32)[:, None] + rel[None, :, 2]).ravel()
            y = (placed.y[sel].astype(np.int32)[:, None] + rel[None, :, 1]).ravel()
            keep = (y < f) & (y > np.take(top, z.astype(np.int64) * f + x))
            keep_inst = keep.reshape(int(sel.sum()), -1)
            color = np.broadcast_to(model.color, keep_inst.shape + (3,))[keep_inst]
            emission = None
            if any_emission:
                em = model.emission if model.emission is not None else np.zeros_like(model.color)
                emission = np.broadcast_to(em, keep_inst.shape + (3,))[keep_inst]
            parts.append(_AssetVoxels(x[keep], y[keep], z[keep], color, emission))
    return _AssetVoxels.join(parts)


def _first_occurrences(keys: np.ndarray) -> np.ndarray:
    """Sorted indices of the first occurrence of each distinct non-negative key.

    Sorts ``key * n + index`` values rather than arg-sorting keys (about 2× faster for the
    millions of voxels of a forest) when that fits in int64.
    """
    n = len(keys)
    if n == 0:
        return np.zeros(0, np.int64)
    if int(keys.max()) < (2**62) // max(n, 1):
        packed = keys.astype(np.int64) * n + np.arange(n, dtype=np.int64)
        packed.sort()
        k = packed // n
        first = np.ones(n, dtype=bool)
        first[1:] = k[1:] != k[:-1]
        idx = packed[first] % n
    else:
        order = np.argsort(keys, kind="stable")
        k = keys[order]
        first = np.ones(n, dtype=bool)
        first[1:] = k[1:] != k[:-1]
        idx = order[first]
    idx.sort()
    return idx


def downsample_scene(scene: VoxelScene, factor: int) -> VoxelScene:
    """A coarser copy: each ``factor``³ block with any voxel becomes one voxel of the mean colour.

    Fits a model to a footprint (a 128-voxel pine is a 64-voxel pine at factor 2); thin parts
    survive because any occupied voxel keeps its block.
    """
    factor = int(factor)
    if factor < 1:
        raise VoxfieldError(f"downsampling factor must be >= 1, got {factor}")
    if factor == 1 or len(scene) == 0:
        return scene
    lo = scene.coords.min(axis=0)
    q = (scene.coords - lo) // factor
    keys, inv = np.unique(q, axis=0, return_inverse=True)
    inv = inv.ravel()
    count = np.bincount(inv, minlength=len(keys)).astype(np.float64)[:, None]

    def mean(values):
        return (
            np.stack(
                [np.bincount(inv, weights=values[:, k], minlength=len(keys)) for k in range(3)],
                axis=1,
            )
            / count
        )

    emission = None if scene.emission is None else mean(scene.emission)
    channels = {k: mean(v) for k, v in scene.channels.items()}
    return VoxelScene(keys, mean(scene.color), emission, channels, scene.name)


# --------------------------------------------------------------------------------------------
# The scene


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
    extra = _scatter(cols, groups, seed)
    # Colour per column.
    surface = _ramp_colors(cols, ramp, np.random.default_rng([seed, 0]))
    if colors is not None and not (isinstance(colors, str) and colors == "ramp"):
        img, covered = _image_colors(cols, hm, colors, fit)
        surface = np.where(covered[..., None], img, surface)
    return TerrainLayout(cols, surface, _lin(ramp.earth), extra,
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
    earth: np.ndarray  # (3,) linear earth colour the fill mixes in
    extra: _AssetVoxels
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
        return (0.8 * (0.4 * surface + 0.6 * self.earth)).astype(np.float32)

    def _ground(self, zs: slice, xs: slice) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates and colours of the ground voxels of the columns ``[zs, xs]``: columns
        in row-major order, each from bottom to top."""
        top = self.cols.top[zs, xs]
        bottom = self.cols.bottom[zs, xs]
        counts = (top - bottom + 1).astype(np.int64).ravel()
        n = int(counts.sum())
        rows, width = top.shape
        # Repeats run on small dtypes and are written into the final arrays, so temporaries
        # stay a fraction of the output (~36 bytes per voxel).
        coords = np.empty((n, 3), dtype=np.int64)
        small = np.int16 if max(self.cols.footprint, rows) <= np.iinfo(np.int16).max else np.int32
        zz, xx = np.divmod(np.arange(rows * width, dtype=np.int64), width)
        coords[:, 0] = np.repeat((xx + (xs.start or 0)).astype(small), counts)
        coords[:, 2] = np.repeat((zz + (zs.start or 0)).astype(small), counts)
        del zz, xx
        ends = np.cumsum(counts)
        coords[:, 1] = np.arange(n, dtype=np.int64)
        coords[:, 1] -= np.repeat(ends - counts - bottom.ravel(), counts)
        surface = self.surface[zs, xs].reshape(-1, 3)
        color = np.empty((n, 3), dtype=np.float32)
        color[:] = np.repeat(self._fill(surface), counts, axis=0)
        color[ends - 1] = surface
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
        ground, color = self._ground(slice(None), slice(None))
        coords = np.concatenate([ground, self._extra_coords(slice(None))])
        color = np.concatenate([color, self.extra.color])
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
        coords = np.concatenate([coords, self._extra_coords(keep)])
        attributes = {"color": np.concatenate([color, self.extra.color[keep]])}
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


#: Asset bucket side (columns) for ``TerrainLayout.column_block``.
_BUCKET = 64


def _scatter(cols: TerrainColumns, groups: Sequence[AssetGroup], seed: int) -> _AssetVoxels:
    """All asset voxels of all groups, none in the ground; where models overlap, the first
    placed wins (groups in order)."""
    parts = []
    for k, group in enumerate(groups):
        placed = place_assets(cols, group, np.random.default_rng([seed, 1, k]))
        parts.append(_instantiate(cols, group, placed))
    voxels = _AssetVoxels.join(parts)
    if len(voxels) == 0:
        return voxels
    f = np.int64(cols.footprint)
    keys = (voxels.y.astype(np.int64) * f + voxels.z) * f + voxels.x
    keep = _first_occurrences(keys)
    return voxels if len(keep) == len(voxels) else voxels.take(keep)


# --------------------------------------------------------------------------------------------
# Recipes: analogues of the EA thesis's four areas (ch. 4)


@dataclass(frozen=True)
class AssetSpec:
    """A ``.vox`` model to scatter in a recipe, sized relative to the footprint.

    ``height`` is the model's height as a fraction of the footprint (it picks an integer
    downsampling), ``spacing`` is in model widths, ``color`` (sRGB) repaints the model (e.g.
    a single-colour rock), ``embed`` sinks it by that fraction of its height.
    """

    file: str
    height: float
    density: float
    spacing: float = 1.0
    max_slope: float = 1.0
    height_range: tuple[float, float] = (0.0, 1.0)
    clumping: float = 0.0
    embed: float = 0.0
    color: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Recipe:
    """A declarative terrain: which DEM, which part, how tall, how coloured, what grows on it."""

    description: str
    dem: str
    window: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)
    vertical_scale: float = 1.0
    fill_depth: int = 4
    ramp: ColorRamp = field(default_factory=ColorRamp)
    colors: str = "ramp"
    sea_level: float | None = None
    fit: str = "stretch"
    assets: tuple[AssetSpec, ...] = ()


_PINE = "PineFluffy.vox"  # a 128-voxel pine (trunk and foliage are two models in one group)
_ROCK = "nature.vox"  # a 120×60×120 cave-riddled noise block: repainted, it is a rock outcrop

RECIPES: dict[str, Recipe] = {
    "desert": Recipe(
        description=(
            "Smooth basins and plateaus (topobathy, coarse data upsampled ~20×, sea floor kept "
            "as dry basins), sand ramp with strong texture noise, a few isolated pines plus one "
            "clumped grove, scattered rock outcrops. EA ch. 4.1."
        ),
        dem="topobathy",
        fit="crop",
        vertical_scale=6.0,
        fill_depth=3,
        ramp=ColorRamp(
            low=(0.80, 0.66, 0.45),
            mid=(0.86, 0.74, 0.52),
            high=(0.76, 0.60, 0.42),
            rock=(0.62, 0.44, 0.32),
            earth=(0.55, 0.38, 0.25),
            snow_line=1.1,
            rock_slope=1.2,
            noise=0.12,
            jitter=0.06,
        ),
        assets=(
            AssetSpec(_PINE, height=1 / 32, density=0.03, clumping=1.0, max_slope=0.6),
            AssetSpec(
                _ROCK,
                height=1 / 96,
                density=0.015,
                embed=0.3,
                max_slope=2.0,
                color=(0.60, 0.45, 0.33),
            ),
        ),
    ),
    "forest": Recipe(
        description=(
            "Dissected Appalachian ridges and valleys (jacksboro, ~15 m/voxel), dense pines on "
            "all but the steepest slopes and highest ridges, exposed rock on cliffs, a dusting "
            "of snow on the highest ground. EA ch. 4.2."
        ),
        dem="jacksboro",
        vertical_scale=3.0,
        fill_depth=3,
        ramp=ColorRamp(
            mid=(0.22, 0.36, 0.14), high=(0.36, 0.38, 0.24), snow_line=0.92, rock_slope=1.3
        ),
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.9,
                spacing=0.8,
                max_slope=1.2,
                height_range=(0.0, 0.9),
            ),
        ),
    ),
    "mountain": Recipe(
        description=(
            "The Japanese Northern Alps (dem_srtm30, north-west window), steep and tall, rock "
            "and snow above a tree line, pines at medium density below it, rock outcrops. "
            "EA ch. 4.3."
        ),
        dem="terrain/dem_srtm30.tif",
        window=(0.0, 0.5, 0.05, 0.55),
        vertical_scale=9.0,
        fill_depth=4,
        ramp=ColorRamp(
            mid=(0.28, 0.38, 0.18),
            high=(0.45, 0.43, 0.36),
            snow_line=0.55,
            rock_slope=1.4,
            snow_max_slope=2.5,
            jitter=0.08,
        ),
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.45,
                max_slope=1.5,
                height_range=(0.0, 0.5),
                clumping=0.5,
            ),
            AssetSpec(
                _ROCK,
                height=1 / 96,
                density=0.02,
                embed=0.3,
                max_slope=3.0,
                color=(0.45, 0.43, 0.41),
            ),
        ),
    ),
    "biomes": Recipe(
        description=(
            "Central Japan from the sea to Mt Fuji (dem_srtm30 under the SRTM3 shaded-relief "
            "image, laid on by position): sea, plains, forests, mountains and snow in one "
            "scene, pines in clumps on low and middle ground. EA ch. 4.4."
        ),
        dem="terrain/dem_srtm30.tif",
        window=(0.2, 1.0, 0.1, 0.9),
        vertical_scale=5.0,
        fill_depth=2,
        colors="terrain/shadedrelief_srtm3.tif",
        sea_level=0.5,
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.6,
                clumping=0.8,
                max_slope=1.2,
                height_range=(0.02, 0.5),
            ),
        ),
    ),
}


def _asset_models(spec: AssetSpec, root: Path, footprint: int) -> list[VoxelScene]:
    """The model of one AssetSpec, loaded, repainted and downsampled to its footprint size."""
    from voxfield.scene.vox import load_vox

    model = load_vox(_data_file(root, "vox", spec.file))
    factor = max(1, int(round(model.extent[1] / max(spec.height * footprint, 1.0))))
    model = downsample_scene(model, factor).normalized()
    if spec.color is not None:
        # Repaint with a little height shading so a one-colour model still reads as a shape.
        shade = 0.75 + 0.25 * model.coords[:, 1:2] / max(int(model.extent[1]) - 1, 1)
        model = VoxelScene(model.coords, np.clip(_lin(spec.color) * shade, 0, 1), name=model.name)
    return [model]


def _data_file(root: Path, *parts: str) -> Path:
    path = root.joinpath(*parts)
    if not path.exists():
        raise DataNotFoundError(
            f"{path} does not exist; set VOXFIELD_DATA (or pass data_root) to the shared data "
            "folder"
        )
    return path


def recipe_scene(
    name: str, footprint: int = 2048, data_root=None, seed: int = 0,
    max_voxels: int = MAX_TERRAIN_VOXELS, **overrides
) -> VoxelScene:
    """The terrain a named recipe describes (``desert``, ``forest``, ``mountain``, ``biomes``).

    DEMs and images come from ``data_root`` (default ``voxfield.data.data_root()``) or from
    matplotlib's samples; ``overrides`` go to ``terrain_layout`` (e.g. ``fill_depth=1``).
    """
    return recipe_layout(name, footprint, data_root, seed, **overrides).scene(max_voxels)


def recipe_layout(
    name: str, footprint: int = 2048, data_root=None, seed: int = 0, **overrides
) -> TerrainLayout:
    """The layout of a recipe's terrain (``recipe_scene`` without making the voxels)."""
    recipe = RECIPES.get(name)
    if recipe is None:
        raise VoxfieldError(f"unknown terrain recipe {name!r}; choose one of {', '.join(RECIPES)}")
    footprint = _check_footprint(footprint)
    if data_root is None:
        from voxfield.data import data_root as default_root

        data_root = default_root()
    root = Path(data_root)
    dem = recipe.dem if recipe.dem in SAMPLE_DEMS else _data_file(root, recipe.dem)
    hm = load_heightmap(dem).window(*recipe.window)
    groups = []
    for spec in recipe.assets:
        models = _asset_models(spec, root, footprint)
        width = max(int(max(m.extent[0], m.extent[2])) for m in models)
        height = max(int(m.extent[1]) for m in models)
        groups.append(
            AssetGroup(
                models=models,
                density=spec.density,
                spacing=max(1.0, spec.spacing * width),
                max_slope=spec.max_slope,
                height_range=spec.height_range,
                clumping=spec.clumping,
                embed=int(round(spec.embed * height)),
            )
        )
    colors = recipe.colors if recipe.colors == "ramp" else _data_file(root, recipe.colors)
    kwargs = dict(
        vertical_scale=recipe.vertical_scale,
        fill_depth=recipe.fill_depth,
        colors=colors,
        ramp=recipe.ramp,
        seed=seed,
        assets=groups or None,
        sea_level=recipe.sea_level,
        fit=recipe.fit,
        name=f"terrain:{name}",
    )
    kwargs.update(overrides)
    return terrain_layout(hm, footprint, **kwargs)
