"""Surface colour per terrain column: a seeded height/slope ramp (``ColorRamp``: sand, grass,
rock, snow, shallow and deep water) or a colour image, a GeoTIFF laid on by position where it
and the DEM both carry one, any other image stretched over the terrain.

Colours are linear RGB float32 (sRGB inputs are decoded here); ``TerrainLayout`` gives each
column's top voxel its colour and the voxels under it a darker earth mix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from voxfield.errors import SceneFormatError, VoxfieldError
from voxfield.scene.terrain.columns import TerrainColumns, square_crop
from voxfield.scene.terrain.dem import (
    GeoGrid,
    Heightmap,
    existing_file,
    geotiff_grid,
    quiet_tifffile,
    unreadable_tiff,
)
from voxfield.scene.terrain.resample import axis_weights, sample_centres
from voxfield.scene.voxel_scene import srgb_to_linear


def linear_rgb(rgb) -> np.ndarray:
    """An sRGB colour (components in [0, 1]) as linear float32 RGB."""
    return srgb_to_linear(np.asarray(rgb, dtype=np.float32))


@dataclass(frozen=True)
class ColorRamp:
    """Surface colours by height band and slope; sRGB triples (decoded to linear on use).

    Height fraction ``h`` runs 0 (lowest land, or sea level) to 1 (peak). Below ``beach_line``
    ground is ``low``; above it blends ``mid`` → ``high``; slopes steeper than ``rock_slope``
    (rise per run) are ``rock``; above ``snow_line`` and flatter than ``snow_max_slope``, snow.
    ``jitter`` moves band edges per column (ragged, partly covered borders, like the thesis's
    snow lines) and ``noise`` varies brightness per column (texture noise); both are seeded.
    ``smoothing`` blurs the finished colours, image or ramp, over that many columns (Gaussian
    sigma), so colour changes at the scale of a few voxels, not per column. ``earth`` is the
    colour the voxels under the surface mix in; ``None`` gives them the surface colour.
    """

    low: tuple[float, float, float] = (0.78, 0.70, 0.50)
    mid: tuple[float, float, float] = (0.30, 0.46, 0.18)
    high: tuple[float, float, float] = (0.42, 0.44, 0.28)
    rock: tuple[float, float, float] = (0.46, 0.43, 0.40)
    snow: tuple[float, float, float] = (0.93, 0.94, 0.97)
    shallow: tuple[float, float, float] = (0.16, 0.40, 0.50)
    deep: tuple[float, float, float] = (0.03, 0.11, 0.24)
    earth: tuple[float, float, float] | None = (0.35, 0.25, 0.17)
    beach_line: float = 0.03
    snow_line: float = 0.8
    rock_slope: float = 1.5
    snow_max_slope: float = 2.0
    jitter: float = 0.04
    noise: float = 0.06
    smoothing: float = 0.0


def ramp_colors(cols: TerrainColumns, ramp: ColorRamp, rng: np.random.Generator) -> np.ndarray:
    """Per-column linear surface colour (F×F×3 float32) from the ramp."""
    shape = cols.top.shape

    def uniform() -> np.ndarray:  # in [-1, 1), float32 throughout (this runs on 4M columns)
        return rng.random(shape, dtype=np.float32) * np.float32(2) - np.float32(1)

    u, v = uniform(), uniform()
    h = cols.height_fraction + np.float32(ramp.jitter) * u
    span = np.float32(max(ramp.snow_line - ramp.beach_line, 1e-6))
    t = np.clip((h - np.float32(ramp.beach_line)) / span, 0, 1)
    t = t * t * (3 - 2 * t)  # smoothstep
    mid, high = linear_rgb(ramp.mid), linear_rgb(ramp.high)
    rgb = mid + t[..., None] * (high - mid)
    del t
    rgb[h < ramp.beach_line] = linear_rgb(ramp.low)
    wobble = 1 + np.float32(0.25) * v
    rgb[cols.slope > np.float32(ramp.rock_slope) * wobble] = linear_rgb(ramp.rock)
    snowy = (h > ramp.snow_line) & (cols.slope < np.float32(ramp.snow_max_slope) * wobble)
    rgb[snowy] = linear_rgb(ramp.snow)
    if cols.water.any():
        below = (cols.sea_level - cols.elevation[cols.water]).astype(np.float32)
        depth = np.sqrt(below / max(float(below.max()), 1e-6))[:, None]
        shallow, deep = linear_rgb(ramp.shallow), linear_rgb(ramp.deep)
        rgb[cols.water] = shallow + depth * (deep - shallow)
    if ramp.noise:
        rgb *= (1 + np.float32(ramp.noise) * uniform())[..., None]
    return np.clip(rgb, 0.0, 1.0, out=rgb)


def smoothed(rgb: np.ndarray, sigma: float) -> np.ndarray:
    """Per-column colours blurred over ``sigma`` columns (Gaussian), edges held."""
    if sigma <= 0:
        return rgb
    # Deferred: SciPy's ndimage adds 0.1 s to every command's start; terrains use it.
    from scipy.ndimage import gaussian_filter

    return gaussian_filter(rgb, sigma=(sigma, sigma, 0), mode="nearest").astype(np.float32)


def _read_color_image(source) -> tuple[np.ndarray, GeoGrid | None]:
    """A linear RGB image (H×W×3 float32) and its GeoGrid if it is a GeoTIFF.

    Integer images are sRGB-encoded (decoded here); float images are taken as linear [0, 1].
    """
    if isinstance(source, np.ndarray):
        img, geo = source, None
        if img.ndim != 3 or img.shape[2] not in (3, 4):
            raise VoxfieldError(f"a colour image array must be H×W×3 linear RGB, got {img.shape}")
        return np.clip(img[..., :3].astype(np.float32), 0, 1), None
    path = existing_file(source)
    geo = None
    if path.suffix.lower() in (".tif", ".tiff"):
        import tifffile  # lazy: a heavy import that only .tif images need

        page = None
        try:
            with quiet_tifffile(), tifffile.TiffFile(path) as tif:
                if len(tif.pages) == 0:
                    raise SceneFormatError(f"{path}: a TIFF that holds no image (damaged or "
                                           "cut short)")
                page = tif.pages[0]
                img = page.asarray()
                geo = geotiff_grid(page)
        except SceneFormatError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file can fail anywhere in tifffile
            raise SceneFormatError(f"{path}: {unreadable_tiff(path, page)}") from exc
    else:
        from PIL import Image, UnidentifiedImageError  # lazy: only non-TIFF images need it

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


def image_colors(
    cols: TerrainColumns, hm: Heightmap, image, fit: str
) -> tuple[np.ndarray, np.ndarray]:
    """Per-column linear colour sampled from an image, and where the image covers the terrain.

    A GeoTIFF laid on a DEM with a position of the same kind is placed by position (parts of
    the terrain it misses are reported uncovered); otherwise it is stretched over the terrain.
    """
    rgb, img_geo = _read_color_image(image)
    f = cols.footprint
    if fit == "crop":
        hm = square_crop(hm)
    n_r, n_c = hm.shape
    rows = sample_centres(n_r, f)  # DEM sample coordinates of each column
    cs = sample_centres(n_c, f)
    h_i, w_i = rgb.shape[:2]
    if img_geo is not None and hm.geo is not None and img_geo.geographic == hm.geo.geographic:
        g = hm.geo
        pr = ((img_geo.y0 - (g.y0 - rows * g.dy)) / img_geo.dy).astype(np.float64)
        pc = ((g.x0 + cs * g.dx - img_geo.x0) / img_geo.dx).astype(np.float64)
    else:
        pr = sample_centres(h_i, f)
        pc = sample_centres(w_i, f)
    in_r = (pr >= -0.5) & (pr <= h_i - 0.5)
    in_c = (pc >= -0.5) & (pc <= w_i - 0.5)
    w_r = axis_weights(pr, h_i, "linear", max(1.0, h_i / f))
    w_c = axis_weights(pc, w_i, "linear", max(1.0, w_i / f))
    out = np.empty((f, f, 3), np.float32)
    for ch in range(3):
        out[..., ch] = (w_c @ (w_r @ rgb[..., ch].astype(np.float64)).T).T
    covered = in_r[:, None] & in_c[None, :]
    return np.clip(out, 0.0, 1.0), covered

