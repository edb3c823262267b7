"""The variance-adaptive baseline (EA thesis §5.1.2).

One ray per pixel at the base LOD; the luminance variance in each 3×3 window (sum of squared
differences from the window mean, background pixels excluded) divided by a fixed constant
sorts pixels into three classes: ≥ 0.75 → 4×4 rays at LOD 0, 0.25–0.75 → 2×2 rays at LOD 0,
else the single ray is kept. Refined pixels take the mean of their new rays; the first ray
still counts (as a discarded hit, ``maps["refined"]``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from voxfield.checks import integer_in, real_number
from voxfield.errors import VoxfieldError
from voxfield.kernels.bundles import BeamBounds, PixelOutputs, octree_view
from voxfield.kernels.primary import render_pixels
from voxfield.parallel import thread_count, threads_for
from voxfield.render.beam import Beam, primary_beam, raster_beam, raster_cells, raster_level
from voxfield.render.camera import Camera, check_camera
from voxfield.render.device import check_device, trace_pixels_cuda
from voxfield.render.primary import pixel_columns, render_lod
from voxfield.render.result import RenderResult
from voxfield.svo.column_tops import octree_column_tops
from voxfield.svo.octree import Octree, check_octree

#: Normalisation of the 3×3 sum of squared luminance differences, one constant for every
#: scene (the thesis normalises "across all datasets"): a window holding two flat regions
#: whose linear luminance differs by 0.2 (e.g. grass beside sand) scores about 1.
VARIANCE_NORMALISATION = 0.08
HIGH_CUT = 0.75
LOW_CUT = 0.25
#: Class → samples-per-pixel side: 0 keeps the first ray, 1 → 2×2, 2 → 4×4.
CLASS_SIDE = (1, 2, 4)


@dataclass(frozen=True)
class AdaptiveOptions:
    """The variance-adaptive baseline's parameters (EA §5.1.2)."""

    base_lod: int | None = field(default=2, metadata={
        "help": "LOD of the first ray, or 'cone' (default 2, the thesis's setup)",
        "type": "lod"})
    iterations: int = field(default=1, metadata={
        "help": "refinement iterations (default 1, as the thesis)"})
    variance_normalisation: float = field(default=VARIANCE_NORMALISATION, metadata={
        "help": "divisor of the 3×3 luminance SSD before the 0.25/0.75 cut-offs, > 0 "
        f"(default {VARIANCE_NORMALISATION}; `voxfield study normalisation` finds the "
        "thesis's one constant across a set of scenes)", "type": "positive_float"})


def luminance(image: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of a linear RGB image."""
    return image @ np.array([0.2126, 0.7152, 0.0722], dtype=image.dtype)


def window_variance(lum: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Sum of squared differences from the mean over each 3×3 window's valid pixels.

    Uses SSD = Σ y² − (Σ y)² / n over the valid pixels, with window sums from a box filter.
    """
    # Deferred: SciPy's ndimage adds 0.1 s to every command's start; only this uses it.
    from scipy import ndimage

    y = np.where(valid, lum, 0.0).astype(np.float64)
    kernel = np.ones((3, 3))
    n = ndimage.convolve(valid.astype(np.float64), kernel, mode="constant")
    s1 = ndimage.convolve(y, kernel, mode="constant")
    s2 = ndimage.convolve(y * y, kernel, mode="constant")
    ssd = s2 - s1 * s1 / np.maximum(n, 1.0)
    return np.where(valid, np.maximum(ssd, 0.0), 0.0)


def normalisation_across(first_passes, quantile: float = 1.0) -> float:
    """The thesis's normalisation "across all datasets": one divisor that maps the largest
    3×3 luminance SSD of any scene's first pass (``RenderResult``s at the base LOD) to 1, so
    ray counts compare between scenes. ``quantile`` < 1 takes that quantile of all scenes'
    SSDs instead of the maximum (robust to a few outlier windows)."""
    return normalisation_of([first_pass_variance(result) for result in first_passes], quantile)


def first_pass_variance(result: RenderResult) -> np.ndarray:
    """The 3×3 luminance SSD of every pixel of a render that hit something."""
    valid = result.hit_count > 0
    return window_variance(luminance(result.image), valid)[valid]


def normalisation_of(variances, quantile: float = 1.0) -> float:
    """``normalisation_across`` from the scenes' ``first_pass_variance`` arrays."""
    if not 0.0 < quantile <= 1.0:
        raise VoxfieldError(f"quantile must be in (0, 1], got {quantile}")
    values = np.concatenate(list(variances)) if len(variances) else np.zeros(0)
    if not len(values) or not np.max(values) > 0.0:
        raise VoxfieldError("the first passes show no variance to normalise (empty or flat "
                            "images)")
    constant = float(np.quantile(values, quantile))
    if not constant > 0.0:
        # Flat windows (sky, uniform walls) are most of the image: a constant of 0 would
        # divide every variance by zero and refine every pixel.
        flat = float(np.mean(values <= 0.0))
        raise VoxfieldError(f"the {quantile:g} quantile of the first passes' variance is 0: "
                            f"{100 * flat:.1f} % of the 3×3 windows are flat; use a quantile "
                            f"above {flat:.3f}")
    return constant


def refine_by_variance(octree: Octree, camera: Camera, result: RenderResult,
                       normalisation: float, seed: int, colours, threads=None,
                       columns: bool = True, counted_bounds: Beam | None = None) -> np.ndarray:
    """Refine the pixels of a finished render whose 3×3 luminance variance (normalised by
    ``normalisation``) asks for more rays than they have: class 2 → 4×4 below 16 rays,
    class 1 → 2×2 below 4 rays. Returns the class each pixel asked for (-1: background).
    ``counted_bounds``: as ``PixelRefinement``'s."""
    valid = result.hit_count > 0
    wanted = refinement_classes(window_variance(luminance(result.image), valid)
                                / normalisation, valid)
    rays = result.ray_count.reshape(-1)
    refinement = PixelRefinement(octree, camera, result, seed, colours, threads,
                                 columns=columns, counted_bounds=counted_bounds)
    refinement.refine_round([
        (np.flatnonzero((wanted.reshape(-1) == cls) & (rays < CLASS_SIDE[cls] ** 2)),
         CLASS_SIDE[cls]) for cls in (2, 1)])
    return wanted


def refinement_classes(variance: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """-1 background, 0 keep, 1 → 2×2, 2 → 4×4 by the thesis's cut-offs."""
    classes = np.where(variance >= HIGH_CUT, 2, np.where(variance >= LOW_CUT, 1, 0))
    return np.where(valid, classes, -1).astype(np.int8)


def render_adaptive(
    octree: Octree, camera: Camera, *, base_lod: int | None = AdaptiveOptions.base_lod,
    iterations: int = AdaptiveOptions.iterations,
    variance_normalisation: float = AdaptiveOptions.variance_normalisation, seed: int = 0,
    channel: str = "albedo", threads: int | None = None, progress: bool = False,
    device: str = "cpu", columns: bool = True,
) -> RenderResult:
    """Render 1 ray per pixel, then refine high-variance pixels at LOD 0 (``iterations`` times;
    later iterations only raise a pixel's class). ``maps`` holds the last iteration's
    normalised ``variance`` and the final ``refinement_class``. ``device="cuda"`` traces the
    first pass and the refinements on a GPU (the variance and the beam bounds stay on the
    CPU), with the same image. ``columns``: as ``render_lod``'s."""
    check_device(device)
    check_octree(octree, "render_adaptive")
    check_camera(camera, "render_adaptive")
    if base_lod is not None:  # named here: render_lod's message would say "LOD"
        base_lod = integer_in(base_lod, "base LOD", 0, octree.depth)
    iterations = integer_in(iterations, "iterations", 0)
    if not real_number(variance_normalisation, "variance normalisation", finite=False) > 0:
        raise VoxfieldError("the variance normalisation must be positive")
    threads = threads_for(camera.width * camera.height, threads)
    first = render_lod(octree, camera, lod=base_lod, seed=seed, channel=channel,
                       threads=threads, progress=progress, device=device, columns=columns)
    start = time.perf_counter()
    result = RenderResult(
        first.image.copy(), first.depth.copy(), first.normal.copy(), first.ray_count.copy(),
        first.hit_count.copy(), first.steps.copy(), first.finest_lod.copy(),
        renderer="adaptive",
    )
    valid = first.hit_count > 0
    current = np.zeros(valid.shape, np.int8)
    variance = np.zeros(valid.shape)
    refinement = PixelRefinement(octree, camera, result, seed, octree.kernel_colours(channel),
                                 threads, device, channel, columns)
    for _ in range(iterations):
        # A tiny normalisation overflows to infinity: far over the cut-offs, which it is.
        with np.errstate(over="ignore"):
            variance = window_variance(luminance(result.image), valid) / variance_normalisation
        wanted = refinement_classes(variance, valid)
        todo = {cls: np.flatnonzero((wanted == cls) & (current < cls)) for cls in (1, 2)}
        refinement.refine_round([(pixels, CLASS_SIDE[cls]) for cls, pixels in todo.items()])
        for cls, pixels in todo.items():
            current.reshape(-1)[pixels] = cls
        if not any(len(pixels) for pixels in todo.values()):
            break  # the image is unchanged, so every further iteration would be this one
    result.seconds = first.seconds + time.perf_counter() - start
    result.maps["variance"] = variance
    result.maps["refinement_class"] = np.where(valid, current, -1).astype(np.int8)
    # The first ray of a refined pixel hit but no longer shows: counted like a discarded ray.
    result.maps["refined"] = (current > 0).astype(np.int32)
    result.params = {"base_lod": "cone" if base_lod is None else base_lod,
                     "iterations": iterations, "variance_normalisation": variance_normalisation,
                     "seed": seed, "channel": channel}
    return result


#: Steps a refinement ray saves starting at its pixel's drawn bound instead of the block
#: beam's: 8-13 on the 2048² mountain terrain (512² image, 2×2 and 4×4 rays a pixel, top
#: and 45°, 0.5-20 % of the pixels refined). The lower end, so that a pass draws only where
#: the drawing clearly pays for itself.
DRAWN_BOUND_SAVING = 8


class PixelRefinement:
    """Re-renders chosen pixels of a finished render ``result`` with side×side rays at LOD 0,
    pass after pass: the adaptive renderer's refinement, also the EA hybrid's and the oracle
    curve's.

    Its rays start where every primary renderer's do (``render.beam.pixel_start_bounds``),
    at their pixel's bound from the pyramid drawn into the image for rays anywhere in the
    pixel, once a pass (or the round of passes it is part of, ``refine_round``) has rays
    enough to pay for the drawing: its cells (one a pixel at most, ``raster_cells``) against
    ``DRAWN_BOUND_SAVING`` steps a ray. The drawing then serves every later pass, its cells
    shared out over the image as every render's drawing is. Passes before it, and every pass
    where nothing can be drawn (a GPU, no pyramid, a camera it cannot draw for), start at
    the block beam of their pixels' blocks, whose steps go to those pixels. On the 2048²
    mountain terrain (512² image) the adaptive renderer at its defaults then counts
    0.58-0.61× the steps of the block beam alone, in 0.90-0.97× the time, the same images.

    ``counted_bounds`` are start bounds the render being refined has already searched for
    and counted, good for every ray through a pixel down to LOD 0 (a bound before nodes of
    any level is before the voxels inside them): every pass starts there, with nothing
    more to search or charge."""

    def __init__(self, octree: Octree, camera: Camera, result: RenderResult, seed: int,
                 colours, threads=None, device: str = "cpu", channel: str = "albedo",
                 columns: bool = True, counted_bounds: Beam | None = None):
        self.octree, self.camera, self.result, self.seed = octree, camera, result, seed
        self.colours, self.threads, self.device, self.channel = colours, threads, device, channel
        self.columns = columns
        self.drawn = counted_bounds
        self.round_rays = 0  # the rays of the passes ``refine_round`` is running
        self.pyramid = octree_column_tops(octree) if device == "cpu" and columns else None
        level = None if self.pyramid is None or counted_bounds is not None else raster_level(
            camera, self.pyramid, stop_level=octree.depth, depth=octree.depth,
            whole_pixel=True)
        # The drawing's cost in steps; None where nothing can be drawn.
        self.drawing_cells = None if level is None else raster_cells(self.pyramid, level)

    def start_bounds(self, pixels: np.ndarray, side: int) -> Beam:
        """The pass's start bounds; a drawing's cells are charged to the result when it is
        drawn, the block beam's steps by ``refine``."""
        rays = max(len(pixels) * side * side, self.round_rays)
        if (self.drawn is None and self.drawing_cells is not None
                and rays * DRAWN_BOUND_SAVING >= self.drawing_cells):
            with thread_count(self.threads):
                self.drawn = raster_beam(self.camera, self.pyramid,
                                         stop_level=self.octree.depth,
                                         depth=self.octree.depth, whole_pixel=True)
            if self.drawn is None:
                self.drawing_cells = None  # a box across the eye plane: never drawable here
            else:
                self.result.steps += self.drawn.image_steps(self.camera.height,
                                                            self.camera.width)
        if self.drawn is not None:
            return self.drawn
        with thread_count(self.threads):
            return primary_beam(self.octree, self.camera, stop_level=self.octree.depth,
                                side=side, pixels=pixels)

    def refine_round(self, passes) -> None:
        """Run the ``(pixels, side)`` passes in order, whether to draw decided on all their
        rays together: passes too small to pay for the drawing alone may pay together."""
        passes = [(pixels, side) for pixels, side in passes if len(pixels)]
        self.round_rays = sum(len(pixels) * side * side for pixels, side in passes)
        try:
            for pixels, side in passes:
                self.refine(pixels, side)
        finally:
            self.round_rays = 0

    def refine(self, pixels: np.ndarray, side: int) -> None:
        """Re-render ``pixels`` (flat indices); their rays and steps add to what they had."""
        octree, camera, result = self.octree, self.camera, self.result
        n = len(pixels)
        pixels = np.asarray(pixels, np.int64)
        beam = self.start_bounds(pixels, side)
        if self.device == "cuda":
            (color, depth, normal, rays, hits, steps, lod), _ = trace_pixels_cuda(
                octree, camera, pixels, side=side, stop_level=octree.depth, cone_scale=0.0,
                seed=self.seed, channel=self.channel, beam_bound=beam.bound, block=beam.block)
        else:
            color = np.empty((n, 3), np.float32)
            depth = np.empty(n, np.float32)
            normal = np.empty((n, 3), np.float32)
            rays = np.empty(n, np.int32)
            hits = np.empty(n, np.int32)
            steps = np.empty(n, np.int64)
            lod = np.empty(n, np.int8)
            with thread_count(self.threads):
                render_pixels(camera.params, camera.width, camera.height, pixels, -1, side,
                              self.seed, octree_view(octree.inner_nodes, octree.depth,
                                                     *self.colours),
                              octree.depth, 0.0, BeamBounds(beam.bound, beam.block),
                              PixelOutputs(color, depth, normal, rays, hits, steps, lod),
                              pixel_columns(octree, self.columns, side, beam.bound),
                              numba.get_num_threads())
        if beam is not self.drawn:
            steps += beam.pixel_steps(pixels, camera.width)
        flat = {name: getattr(result, name).reshape(-1, *getattr(result, name).shape[2:])
                for name in ("image", "depth", "normal", "ray_count", "hit_count", "steps",
                             "finest_lod")}
        flat["image"][pixels] = color
        flat["depth"][pixels] = depth
        flat["normal"][pixels] = normal
        flat["ray_count"][pixels] += rays
        flat["hit_count"][pixels] = hits
        flat["steps"][pixels] += steps
        flat["finest_lod"][pixels] = np.where(hits > 0, 0, flat["finest_lod"][pixels])
