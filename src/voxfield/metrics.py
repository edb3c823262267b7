"""Image quality against a reference and render cost, measured as the EA thesis's chapter 5 does.

Quality metrics read linear RGB images in [0, 1] (H×W×3): PSNR, RMSE and SSIM through
scikit-image with ``data_range=1``; NVIDIA FLIP through ``flip-evaluator`` when it is installed.
FLIP's LDR mode models a display showing sRGB values, so its inputs are sRGB-encoded first.

Cost summaries count what the thesis counts (Tables 5.2–5.4): rays, of which only the ones that
hit a voxel enter its totals; rays per covered pixel; traversal steps; and per-pixel histograms
of ray counts and of the finest LOD sampled.
"""

from __future__ import annotations

import math

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.render.result import RenderResult
from voxfield.scene.voxel_scene import linear_to_srgb

#: Pixels whose rays hit nothing (thesis tables: "Didn't Hit").
MISSED = "didn't hit"
#: Ray-count columns of the adaptive-renderer table (EA Table 5.3).
RAY_BUCKETS = (1, 4, 16)
#: Most rays one error-aware pixel can take with two refinements: 1 + 4 + 16 (EA §5.1.3).
MAX_ERROR_AWARE_RAYS = 21
#: How far outside [0, 1] a pixel may stray (float rounding) before metrics refuse the image.
RANGE_TOLERANCE = 1e-4
#: scikit-image's default SSIM window; smaller images cannot be compared this way.
SSIM_WINDOW = 7


def _check_pair(reference, test, *, ssim_window: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Both images as float32 H×W×3 in [0, 1], or a VoxfieldError that says what is wrong;
    ``ssim_window``: also too small for SSIM's window (PSNR and RMSE take any size)."""
    images = []
    for name, image in (("reference", reference), ("test", test)):
        if isinstance(image, RenderResult):  # what a renderer returns: its colour image
            image = image.image
        a = np.asarray(image)
        if a.ndim != 3 or a.shape[2] != 3:
            raise VoxfieldError(f"the {name} image must be H×W×3 RGB, got shape {a.shape}")
        if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
            raise VoxfieldError(f"the {name} image must hold real numbers, got {a.dtype}")
        a = a.astype(np.float32, copy=False)
        if a.size == 0:
            raise VoxfieldError(f"the {name} image is empty (shape {a.shape})")
        if not np.isfinite(a).all():
            raise VoxfieldError(f"the {name} image contains NaN or infinite values")
        lo, hi = float(a.min()), float(a.max())
        if lo < -RANGE_TOLERANCE or hi > 1.0 + RANGE_TOLERANCE:
            raise VoxfieldError(
                f"the {name} image has values in [{lo:.4g}, {hi:.4g}]; metrics expect linear "
                "colours in [0, 1] (tone-map HDR images first)"
            )
        images.append(np.clip(a, 0.0, 1.0))
    if images[0].shape != images[1].shape:
        raise VoxfieldError(
            f"images differ in size: reference {images[0].shape}, test {images[1].shape}"
        )
    if ssim_window and min(images[0].shape[:2]) < SSIM_WINDOW:
        raise VoxfieldError(
            f"images must be at least {SSIM_WINDOW}×{SSIM_WINDOW} pixels for SSIM, "
            f"got {images[0].shape[1]}×{images[0].shape[0]}"
        )
    return images[0], images[1]


def rmse(reference, test) -> float:
    """Root of the mean squared difference over all pixels and channels."""
    return _rmse(*_check_pair(reference, test))


def psnr(reference, test) -> float:
    """Peak signal-to-noise ratio in dB for peak 1; ``inf`` for identical images."""
    return _psnr(*_check_pair(reference, test))


def psnr_text(value, spec: str = ".2f") -> str:
    """A PSNR as people read it: ``∞`` for images equal to the reference (an infinite PSNR,
    or the ``None`` JSON makes of one), ``—`` for NaN, else ``format(value, spec)``."""
    if value is None or (isinstance(value, float) and math.isinf(value)):
        return "∞"
    if isinstance(value, float) and math.isnan(value):
        return "—"
    return format(value, spec)


def ssim(reference, test) -> float:
    """Mean structural similarity over RGB (scikit-image, 7×7 window); 1 for identical images."""
    return _ssim(*_check_pair(reference, test, ssim_window=True))


def flip(reference, test) -> float | None:
    """Mean LDR-FLIP error (0 = identical) of the sRGB-encoded images; None without FLIP.

    FLIP's LDR mode assumes sRGB inputs, so the linear images are encoded with
    ``linear_to_srgb`` first: the error then describes what a viewer sees on a display.
    """
    return _flip(*_check_pair(reference, test))


def flip_available() -> bool:
    """Whether NVIDIA FLIP (the ``flip-evaluator`` package) can be imported."""
    try:
        import flip_evaluator  # noqa: F401
    except ImportError:
        return False
    return True


def compare_images(reference, test) -> dict:
    """``psnr`` (dB), ``rmse``, ``ssim`` on linear RGB and ``flip`` (None when not installed)."""
    ref, img = _check_pair(reference, test, ssim_window=True)
    return {"psnr": _psnr(ref, img), "rmse": _rmse(ref, img), "ssim": _ssim(ref, img),
            "flip": _flip(ref, img)}


def _rmse(ref: np.ndarray, img: np.ndarray) -> float:
    return float(np.sqrt(np.mean((ref.astype(np.float64) - img) ** 2)))


def _psnr(ref: np.ndarray, img: np.ndarray) -> float:
    # heavy: scikit-image loads only when images are compared
    from skimage.metrics import peak_signal_noise_ratio

    if np.array_equal(ref, img):
        return math.inf  # scikit-image would divide by zero (and warn) to get here
    return float(peak_signal_noise_ratio(ref, img, data_range=1.0))


def _ssim(ref: np.ndarray, img: np.ndarray) -> float:
    # heavy: scikit-image loads only when images are compared
    from skimage.metrics import structural_similarity

    return float(structural_similarity(ref, img, channel_axis=-1, data_range=1.0))


def _flip(ref: np.ndarray, img: np.ndarray) -> float | None:
    try:
        # optional: FLIP is measured only where its package is installed
        import flip_evaluator
    except ImportError:
        return None

    _, mean_error, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(linear_to_srgb(ref)), np.ascontiguousarray(linear_to_srgb(img)),
        "LDR", inputsRGB=True, applyMagma=False, computeMeanError=True,
    )
    return float(mean_error)


# --- cost --------------------------------------------------------------------------------------


def _check_result(result: RenderResult) -> tuple[int, int]:
    """The counters' common H×W shape, or a VoxfieldError naming the counter that is off."""
    if not isinstance(result, RenderResult):
        raise VoxfieldError(f"expected a RenderResult, got {type(result).__name__}")
    shape = tuple(np.shape(result.image)[:2])
    if np.ndim(result.image) != 3:
        raise VoxfieldError(f"result image must be H×W×3, got shape {np.shape(result.image)}")
    for name in ("ray_count", "hit_count", "steps", "finest_lod"):
        counter = np.asarray(getattr(result, name))
        if counter.shape != shape:
            raise VoxfieldError(f"result {name} has shape {counter.shape}, image has {shape}")
        if not np.issubdtype(counter.dtype, np.integer):
            raise VoxfieldError(f"result {name} must be integer counts, got {counter.dtype}")
    if (np.asarray(result.ray_count) < 0).any() or (np.asarray(result.hit_count) < 0).any():
        raise VoxfieldError("result ray or hit counts are negative")
    return shape


def discarded_rays(result: RenderResult) -> np.ndarray:
    """Rays per pixel that hit a node but were discarded for finer ones (``maps["discarded"]``,
    else ``maps["refined"]``; zero for renderers that keep every ray)."""
    refined = result.maps.get("discarded", result.maps.get("refined"))
    if refined is None:
        return np.zeros(result.shape, np.int64)
    refined = np.asarray(refined)
    if refined.shape != result.shape:
        raise VoxfieldError(f"result map 'refined' has shape {refined.shape}, not {result.shape}")
    return refined.astype(np.int64)


def ray_histogram(result: RenderResult) -> dict[str, int]:
    """Pixels by rays per pixel in the columns of EA Table 5.3: didn't hit / 1 / 4 / 16 / other.

    The adaptive renderer's ``maps["refinement_class"]`` (−1 background, 0 keep, 1 → 2×2,
    2 → 4×4) names its columns directly, as the thesis counts them (a pixel refined to 2×2 is a
    "4 rays" pixel although its first ray was cast too); other renderers are binned by their
    per-pixel ray counts.
    """
    _check_result(result)
    covered = np.asarray(result.hit_count) > 0
    classes = result.maps.get("refinement_class")
    if classes is not None:
        classes = np.asarray(classes)
        if classes.shape != result.shape:
            raise VoxfieldError(
                f"result map 'refinement_class' has shape {classes.shape}, not {result.shape}"
            )
        counts = {MISSED: int((classes < 0).sum())}
        for value, rays in enumerate(RAY_BUCKETS):
            counts[str(rays)] = int((classes == value).sum())
        counts["other"] = int((classes > len(RAY_BUCKETS) - 1).sum())
        return counts
    rays = np.asarray(result.ray_count)
    counts = {MISSED: int((~covered).sum())}
    for bucket in RAY_BUCKETS:
        counts[str(bucket)] = int((covered & (rays == bucket)).sum())
    counts["other"] = int((covered & ~np.isin(rays, RAY_BUCKETS)).sum())
    return counts


def ray_distribution(result: RenderResult, max_rays: int = MAX_ERROR_AWARE_RAYS) -> dict[str, int]:
    """Pixels by exact ray count 1..``max_rays`` (EA fig. 5.2a's 1 → 21 scale), discarded rays
    included; ``didn't hit`` and ``other`` (more than ``max_rays``) complete the image."""
    _check_result(result)
    covered = np.asarray(result.hit_count) > 0
    rays = np.asarray(result.ray_count)[covered].astype(np.int64)
    binned = np.bincount(np.clip(rays, 0, max_rays + 1), minlength=max_rays + 2)
    counts = {MISSED: int((~covered).sum())}
    counts.update({str(n): int(binned[n]) for n in range(1, max_rays + 1)})
    counts["other"] = int(binned[0] + binned[max_rays + 1])
    return counts


def lod_histogram(result: RenderResult) -> dict[str, int]:
    """Pixels by the finest LOD any of their rays sampled, coarsest first (EA Table 5.4:
    "maximum LOD level used"); pixels whose rays hit nothing are ``didn't hit``."""
    _check_result(result)
    covered = np.asarray(result.hit_count) > 0
    lod = np.asarray(result.finest_lod).astype(np.int64)
    valid = covered & (lod >= 0)
    counts = {MISSED: int((~covered).sum())}
    if valid.any():
        binned = np.bincount(lod[valid])
        counts.update({f"LOD {n}": int(binned[n]) for n in range(len(binned) - 1, -1, -1)})
    unknown = int((covered & (lod < 0)).sum())
    if unknown:
        counts["unknown"] = unknown  # a renderer that hit without recording a LOD
    return counts


def cost_summary(result: RenderResult) -> dict:
    """Totals and histograms of one render, JSON-ready.

    ``rays`` counts every ray cast (misses and discarded rays included); ``rays_hit`` counts as
    the thesis does — "rays that do not hit a voxel are not counted" — the sampling rays that
    hit plus the discarded ones (which hit the node that made them refine).
    ``rays_per_pixel`` divides that by the pixels that show geometry, as Table 5.2 does
    (395,162 rays / 209,258 pixels = 1.888); ``steps_per_ray`` divides traversal steps (nodes
    visited by every ray, misses included) by all rays cast.
    """
    h, w = _check_result(result)
    rays = int(np.asarray(result.ray_count, np.int64).sum())
    discarded = int(discarded_rays(result).sum())
    rays_hit = int(np.asarray(result.hit_count, np.int64).sum()) + discarded
    covered = int((np.asarray(result.hit_count) > 0).sum())
    steps = int(np.asarray(result.steps, np.int64).sum())
    seconds = float(result.seconds)
    return {
        "renderer": result.renderer,
        "width": int(w),
        "height": int(h),
        "pixels": int(w * h),
        "covered_pixels": covered,
        "rays": rays,
        "rays_hit": rays_hit,
        "rays_discarded": discarded,
        "rays_per_pixel": rays_hit / covered if covered else 0.0,
        "rays_per_pixel_all": rays / (w * h) if w * h else 0.0,
        "traversal_steps": steps,
        "steps_per_ray": steps / rays if rays else 0.0,
        "seconds": seconds,
        "mrays_per_second": rays / seconds / 1e6 if seconds > 0 else None,
        "ray_histogram": ray_histogram(result),
        "ray_distribution": ray_distribution(result),
        "lod_histogram": lod_histogram(result),
    }
