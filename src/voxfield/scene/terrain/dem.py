"""Heightmaps and the DEM readers: ``Heightmap`` and ``GeoGrid``, the SRTM ``.hgt``, GeoTIFF,
``.npz`` and ``.npy`` readers, and ``load_heightmap``, which picks one.

Every later terrain step starts from a Heightmap, so the file formats and their quirks (SRTM
voids, GeoTIFF tie points and no-data tags, south-first ``.npz`` rows) stay in this file.
Row 0 of a heightmap is its northern edge and column 0 its western edge.
"""

from __future__ import annotations

import logging
import math
import re
import warnings
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.errors import DataNotFoundError, SceneFormatError, VoxfieldError

#: Metres per degree on a spherical Earth (mean radius 6,371,008.8 m).
METRES_PER_DEGREE = 2 * math.pi * 6_371_008.8 / 360
#: matplotlib's sample DEMs, by the short names ``load_heightmap`` accepts.
SAMPLE_DEMS = {"jacksboro": "jacksboro_fault_dem.npz", "topobathy": "topobathy.npz"}
#: SRTM's void, below any sea floor: no data in a GeoTIFF whatever its tags say.
_ALWAYS_VOID = -32768.0
#: GDAL's habitual no-data value: a void only in a GeoTIFF whose tags name no other.
_UNTAGGED_VOID = -9999.0
#: SRTM tile edge lengths (samples) by file size in bytes.
_HGT_SIZES = {2 * 1201 * 1201: 1201, 2 * 3601 * 3601: 3601}


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
                f"{self.name}: every sample is a void (no data) or infinite; nothing to build"
            )
        object.__setattr__(self, "elevation", elev)
        spacing = self.spacing
        if spacing is None and self.geo is not None:
            spacing = self.geo.spacing_m(elev.shape[0])
        if spacing is not None:
            spacing = tuple(float(s) for s in np.broadcast_to(np.asarray(spacing, float), (2,)))
            if not all(math.isfinite(s) and s >= MIN_PIXEL_SCALE for s in spacing):
                raise SceneFormatError(
                    f"{self.name}: spacing must be at least {MIN_PIXEL_SCALE:g} m, got "
                    f"{spacing}"
                )
        object.__setattr__(self, "spacing", spacing)

    @property
    def shape(self) -> tuple[int, int]:
        return self.elevation.shape

    @property
    def ground(self) -> tuple[float, float]:
        """(north–south, east–west) extent: metres where the spacing is known, else
        samples."""
        n_r, n_c = self.shape
        dy, dx = self.spacing or (1.0, 1.0)
        return n_r * dy, n_c * dx

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
def quiet_tifffile():
    """Hide tifffile's log noise (it complains about ``GDAL_NODATA = nan`` while decoding)."""
    logger = logging.getLogger("tifffile")
    previous = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(previous)


def existing_file(path) -> Path:
    """``path`` as a Path, or DataNotFoundError if no such file exists (SceneFormatError if
    it is a folder, pipe or device)."""
    path = Path(path)
    if not path.is_file():
        if path.exists():
            raise SceneFormatError(f"{path}: a folder, pipe or device, not a DEM file")
        raise DataNotFoundError(f"{path}: no such file")
    return path


def read_hgt(path) -> Heightmap:
    """An SRTM ``.hgt`` tile: big-endian int16 metres, square 1201² (3″) or 3601² (1″).

    The edge length comes from the file size; −32768 marks voids. A name like ``N40W074``
    (the tile's south-west corner, first in the name) gives its position and so its ground
    spacing; sample centres sit on whole degrees.
    """
    path = existing_file(path)
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
    # NASA's own names carry more after the tile's: N46E010.SRTMGL1.hgt
    m = re.match(r"([NS])(\d{1,2})([EW])(\d{1,3})(?![0-9])", path.stem.upper())
    if m:
        lat = int(m.group(2)) * (1 if m.group(1) == "N" else -1)
        lon = int(m.group(4)) * (1 if m.group(3) == "E" else -1)
        if not (-90 <= lat < 90 and -180 <= lon < 180):
            # N99W999 was refused for a spacing "at least 1e-09 m", later and far from why.
            raise SceneFormatError(
                f"{path}: the name places the tile's south-west corner at {m.group(0)}, "
                "outside the globe (latitude -90..89, longitude -180..179); rename it, or "
                "drop the position from the name to build it unplaced")
        step = 1.0 / (n - 1)
        geo = GeoGrid(x0=float(lon), y0=float(lat + 1), dx=step, dy=step)
    return Heightmap(_checked_heights(elev, path), geo=geo, name=path.stem)


#: Share of a DEM's samples without a height past which filling them earns a note: an SRTM
#: tile holds a few voids (N40W074: 0.07%), filled unremarked; a grid of mostly voids was
#: filled flat from a handful of heights without a word.
VOIDS_NOTED = 0.01


def _checked_heights(elev: np.ndarray, path: Path) -> np.ndarray:
    """``elev`` (a file's heights, NaN for its voids), refused where no sample is a finite
    height, with a note where the voids pass ``VOIDS_NOTED`` or any height is infinite (a
    damaged value, filled like a void: the terrain there is made up, not measured)."""
    if elev.ndim != 2 or min(elev.shape) < 2 or elev.dtype.kind != "f":
        return elev  # Heightmap says what is wrong with it; whole numbers hold no voids
    voids = int(np.count_nonzero(np.isnan(elev)))
    infinite = int(np.count_nonzero(np.isinf(elev)))
    missing = voids + infinite
    if not missing:
        return elev
    kinds = ", ".join(text for count, text in (
        (voids, f"{voids:,} no-data void" + ("s" if voids != 1 else "")),
        (infinite, f"{infinite:,} infinite")) if count)
    if missing == elev.size:
        raise SceneFormatError(f"{path}: none of its {elev.size:,} samples is a height "
                               f"({kinds}); nothing to build")
    share = missing / elev.size
    if infinite or share > VOIDS_NOTED:
        warnings.warn(f"{path}: {missing:,} of its {elev.size:,} samples ({100 * share:.3g}%) "
                      f"have no height ({kinds}); they were filled in smoothly from the "
                      f"{elev.size - missing:,} that do", stacklevel=3)
    return elev


#: Smallest believable pixel size, in degrees or metres (1e-9° is about 0.1 mm).
MIN_PIXEL_SCALE = 1e-9


def geotiff_grid(page) -> GeoGrid | None:
    """The GeoGrid of a GeoTIFF page from its pixel-scale and tie-point tags, or from its
    model transformation where it has no rotation, and its geo-key tags."""
    tags = page.tags
    scale = tags.get(33550)
    tie = tags.get(33922)
    matrix = tags.get(34264)  # ModelTransformationTag: 4×4, row-major, raster → model
    if scale is not None and tie is not None:
        sx, sy = float(scale.value[0]), float(scale.value[1])
        i, j, _, x, y, _ = (float(v) for v in tie.value[:6])
    elif matrix is not None and len(matrix.value) >= 8:
        m = [float(v) for v in matrix.value[:8]]
        if m[1] != 0.0 or m[4] != 0.0:  # a rotated or sheared grid: no north-up spacing
            warnings.warn("the GeoTIFF's model transformation rotates its grid; its ground "
                          "spacing is ignored and the DEM's own is used", stacklevel=2)
            return None
        sx, sy, i, j, x, y = m[0], -m[5], 0.0, 0.0, m[3], m[7]
    else:
        return None
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
    if not all(math.isfinite(v) for v in (sx, sy, i, j, x, y)) or min(sx, sy) < MIN_PIXEL_SCALE:
        # A damaged tag (a zeroed byte makes a scale of 1e-309): no georeference beats a
        # terrain whose metres per voxel divide by zero.
        warnings.warn(f"ignoring an implausible GeoTIFF pixel scale ({sx:.3g}, {sy:.3g}) or "
                      "tie point; the DEM's own spacing is used", stacklevel=2)
        return None
    # The tie point names pixel (i, j)'s corner (area) or centre (point); we store centres.
    half = 0.5 if raster_type == 1 else 0.0
    x0 = x + (half - i) * sx
    y0 = y - (half - j) * sy
    return GeoGrid(x0=x0, y0=y0, dx=sx, dy=sy, geographic=model_type != 1)


def _nodata_mask(arr: np.ndarray, nodata: float | None) -> np.ndarray:
    """Where the band holds its no-data value, compared in the band's own type, as GDAL does;
    a value within 1e-5 of a float band's extreme is that extreme (GDAL's
    ``GDALAdjustNoDataCloseToFloatMax``: it writes "-3.40282e+38", six digits of -FLT_MAX)."""
    if nodata is None or not math.isfinite(nodata):
        return np.zeros(arr.shape, bool)
    if np.issubdtype(arr.dtype, np.integer):
        info = np.iinfo(arr.dtype)
        if nodata != int(nodata) or not info.min <= nodata <= info.max:
            return np.zeros(arr.shape, bool)
        return arr == arr.dtype.type(int(nodata))
    extreme = float(np.finfo(arr.dtype).max)
    if abs(abs(nodata) - extreme) <= 1e-5 * extreme:
        nodata = math.copysign(extreme, nodata)
    with np.errstate(over="ignore"):
        return arr == arr.dtype.type(nodata)


def _gdal_nodata(page) -> float | None:
    tag = page.tags.get(42113)
    if tag is None:
        return None
    try:
        return float(str(tag.value).strip("\x00 "))
    except ValueError:
        return None


#: The first bytes of a TIFF (little- or big-endian) and of a BigTIFF.
TIFF_MAGIC = (b"II*\0", b"MM\0*", b"II+\0", b"MM\0+")


def unreadable_tiff(path: Path, page=None) -> str:
    """Why tifffile could not read ``path``, in plain words: not a TIFF, a compression it
    cannot decode, or a damaged file. Its own messages name its internals ("IndexError:
    index 0 out of range(0)" for a file cut short after its header)."""
    import tifffile  # lazy: a heavy import that only .tif inputs need

    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as exc:  # not there to be read: no finding about its contents
        return f"cannot read the file ({exc.strerror or exc})"
    if magic not in TIFF_MAGIC:
        return "not a TIFF file (it does not begin with a TIFF header)"
    compression = getattr(page, "compression", None)
    if compression is not None and compression not in tifffile.TIFF.DECOMPRESSORS:
        try:
            return (f"its compression ({tifffile.COMPRESSION(compression).name}) cannot be "
                    "decoded here")
        except ValueError:
            return f"its compression code {int(compression)} is none this reader knows"
    return "a TIFF that cannot be read: the file is damaged or cut short"


def read_geotiff(path) -> Heightmap:
    """A single-band GeoTIFF DEM (int or float). Voids: NaN, −32768 (deeper than any sea),
    and the GDAL_NODATA tag's value where it has one, else −9999 (a tag naming another value
    keeps −9999 a height: a bathymetry grid can be 9,999 m deep)."""
    import tifffile  # lazy: a heavy import that only .tif inputs need

    path = existing_file(path)
    page = None
    try:
        with quiet_tifffile(), tifffile.TiffFile(path) as tif:
            if len(tif.pages) == 0:
                raise SceneFormatError(f"{path}: a TIFF that holds no image (damaged or cut "
                                       "short)")
            page = tif.pages[0]
            arr = page.asarray()
            nodata = _gdal_nodata(page)
            geo = geotiff_grid(page)
    except (FileNotFoundError, SceneFormatError):
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged file can fail anywhere in tifffile
        raise SceneFormatError(f"{path}: {unreadable_tiff(path, page)}") from exc
    if geo is not None and not (math.isfinite(geo.dx) and math.isfinite(geo.dy)
                                and geo.dx > 0 and geo.dy > 0 and math.isfinite(geo.x0)
                                and math.isfinite(geo.y0)):
        raise SceneFormatError(f"{path}: its georeference gives a pixel size of "
                               f"{geo.dx} × {geo.dy}; a DEM needs a positive, finite one")
    raw_shape = arr.shape
    arr = np.squeeze(arr)
    if arr.ndim < 2:  # one pixel, or one row or column of them
        raise SceneFormatError(
            f"{path}: a DEM needs at least 2×2 heights, this TIFF holds {arr.size} "
            f"(shape {raw_shape})"
        )
    if arr.ndim != 2:
        raise SceneFormatError(
            f"{path}: a DEM needs one band of heights, this TIFF holds an array of shape "
            f"{raw_shape} (an RGB image? pass it as colors= instead)"
        )
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise SceneFormatError(f"{path}: unsupported sample type {arr.dtype}")
    elev = arr.astype(np.float64)
    declared = _nodata_mask(arr, nodata) if nodata is not None else elev == _UNTAGGED_VOID
    if nodata is not None and math.isinf(nodata):  # an infinity the tag names as no data
        declared = elev == nodata
    elev[(elev == _ALWAYS_VOID) | declared] = np.nan  # infinities stay, to be counted
    return Heightmap(_checked_heights(elev, path), geo=geo, name=path.stem)


def _npz_grid(data: Mapping[str, np.ndarray], shape: tuple[int, int]):
    """(GeoGrid or None, flip rows?) from the coordinate arrays some DEM .npz files carry."""
    n_r, n_c = shape
    if "latitude" in data and "longitude" in data:
        lat = np.asarray(data["latitude"], float).ravel()
        lon = np.asarray(data["longitude"], float).ravel()
        # Each was dropped without a word before, and the terrain built as if unplaced.
        if len(lat) != n_r or len(lon) != n_c:
            raise ValueError(f"latitude has {len(lat)} values for {n_r} rows and longitude "
                             f"{len(lon)} for {n_c} columns")
        if not (np.isfinite(lat).all() and np.isfinite(lon).all()):
            raise ValueError("latitude or longitude holds NaN or infinity")
        if np.abs(lat).max() > 90:
            raise ValueError(f"latitudes run {lat.min():g}..{lat.max():g}, past ±90°")
        if n_r > 1 and n_c > 1:
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
        if not (dx > 0 and dy > 0 and math.isfinite(dx) and math.isfinite(dy)):
            raise ValueError(f"dx and dy must be positive sample spacings, got {dx:g} and "
                             f"{dy:g}")
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
    path = existing_file(path)
    try:
        with load_arrays(path) as npz:
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
    try:
        geo, flip = _npz_grid(data, elev.shape)
        spacing = None
        if "spacing" in data:
            spacing = tuple(np.broadcast_to(np.asarray(data["spacing"], float), (2,)))
    except (ValueError, TypeError) as exc:  # coordinates or spacing not numbers, or shaped
        raise SceneFormatError(f"{path}: unreadable coordinates or spacing ({exc})") from exc
    if flip:
        elev = elev[::-1]
    return Heightmap(_checked_heights(elev, path), spacing=spacing, geo=geo, name=name)


def load_heightmap(source) -> Heightmap:
    """A Heightmap from a path (``.hgt``, ``.tif``/``.tiff``, ``.npz``, ``.npy``), a 2-D array,
    or the name of one of matplotlib's sample DEMs (``jacksboro``, ``topobathy``)."""
    if isinstance(source, Heightmap):
        return source
    if isinstance(source, np.ndarray):
        return Heightmap(source)
    if isinstance(source, str) and source.lower() in SAMPLE_DEMS:
        from matplotlib import cbook  # lazy: a heavy import that only the sample DEMs need

        path = cbook.get_sample_data(SAMPLE_DEMS[source.lower()], asfileobj=False)
        return read_npz(path, name=source.lower())
    samples = ", ".join(sorted(SAMPLE_DEMS))
    if isinstance(source, str) and not source.strip():  # Path("") would be the current folder
        raise DataNotFoundError(f"no DEM named: give a DEM file or a sample DEM ({samples})")
    path = Path(source)
    if not path.exists():
        raise DataNotFoundError(f"{path}: no such file (or name a sample DEM: {samples})")
    if path.is_dir():
        raise SceneFormatError(f"{path}: a folder, not a DEM file (.hgt, .tif, .npz, .npy)")
    suffix = path.suffix.lower()
    if suffix == ".hgt":
        return read_hgt(path)
    if suffix in (".tif", ".tiff"):
        return read_geotiff(path)
    if suffix == ".npz":
        return read_npz(path)
    if suffix == ".npy":
        try:
            arr = load_arrays(path, kind="npy")
        except Exception as exc:  # noqa: BLE001
            raise SceneFormatError(f"{path}: not a readable .npy array ({exc})") from exc
        return Heightmap(_checked_heights(arr, path), name=path.stem)
    raise SceneFormatError(
        f"{path}: unknown DEM format {suffix!r} (expected .hgt, .tif, .npz, .npy)"
    )

