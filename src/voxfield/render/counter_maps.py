"""Pictures of the cost counters: traversal steps, finest LOD and rays cast per pixel (EA figs
5.1–5.3), each with its colour bar."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import BoundaryNorm, ListedColormap, Normalize, SymLogNorm

from voxfield.json_output import json_text
from voxfield.render.image_io import save_png
from voxfield.render.result import RenderResult

#: The colour bar's width beside a map, and the least height it needs, in pixels.
LEGEND_WIDTH = 120
LEGEND_MIN_HEIGHT = 160


def steps_scale(result: RenderResult) -> float:
    """The step count the heat map's brightest colour stands for: the 99th percentile of the
    pixels that took any (so a few very long rays do not leave the rest dark)."""
    steps = result.steps
    return max(float(np.percentile(steps[steps > 0], 99)) if steps.any() else 1.0, 1.0)


def steps_norm(result: RenderResult) -> SymLogNorm:
    """Steps to the magma scale: logarithmic from 1 up to ``steps_scale`` (linear below 1).
    On a linear scale a cheap pixel (a coarse LOD's few steps against a refined pixel's
    hundreds) was as black as the empty background."""
    return SymLogNorm(linthresh=1.0, linscale=0.25, vmin=0.0, vmax=steps_scale(result),
                      base=10, clip=True)


def steps_heatmap(result: RenderResult) -> np.ndarray:
    """Traversal steps per pixel on the magma scale (``steps_norm``)."""
    steps = result.steps.astype(np.float64)
    return colormaps["magma"](steps_norm(result)(steps).filled(1.0))[..., :3]


def lod_colours(depth: int) -> np.ndarray:
    """The LOD map's colour of each LOD 0..``depth`` (viridis, LOD 0 brightest), (depth+1)×3."""
    return colormaps["viridis"](1.0 - np.arange(depth + 1) / max(depth, 1))[:, :3]


def lod_map(result: RenderResult, depth: int) -> np.ndarray:
    """Finest LOD sampled per pixel, one colour per LOD (``lod_colours``); black where
    nothing was hit."""
    lod = result.finest_lod.astype(np.int64)
    rgb = lod_colours(depth)[np.clip(lod, 0, depth)]
    rgb[lod < 0] = 0.0
    return rgb


def rays_map(result: RenderResult) -> tuple[np.ndarray, int]:
    """Rays cast per pixel (discarded ones included: the EA thesis's cost), viridis from 0
    to the most any pixel cast, one colour per count; returns the picture and that most."""
    rays = np.asarray(result.ray_count, np.int64)
    top = max(int(rays.max(initial=0)), 1)
    return colormaps["viridis"](np.clip(rays, 0, top) / top)[..., :3], top


def with_colour_bar(rgb: np.ndarray, cmap, norm, label: str, ticks=None) -> np.ndarray:
    """``rgb`` pixel for pixel at the top left, its colour bar to the right: a map is read
    by its numbers, and a bare heat map gives none."""
    # heavy: matplotlib's figure machinery loads only when a map is drawn
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.figure import Figure

    h, w = rgb.shape[:2]
    dpi = 100.0
    fig_w, fig_h = w + LEGEND_WIDTH, max(h, LEGEND_MIN_HEIGHT)
    fig = Figure(figsize=(fig_w / dpi, fig_h / dpi), dpi=dpi, facecolor="white")
    canvas = FigureCanvasAgg(fig)
    fig.figimage(np.clip(rgb, 0.0, 1.0), xo=0, yo=fig_h - h, origin="upper")
    bar_h = min(fig_h - 24, 360)
    cax = fig.add_axes(((w + 14) / fig_w, (fig_h - 12 - bar_h) / fig_h, 14 / fig_w,
                        bar_h / fig_h))
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=cax, ticks=ticks)
    bar.ax.tick_params(labelsize=7)
    bar.set_label(label, fontsize=7)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3] / np.float32(255.0)


def steps_figure(result: RenderResult) -> np.ndarray:
    """``steps_heatmap`` with its colour bar in steps."""
    top = steps_scale(result)
    return with_colour_bar(steps_heatmap(result), colormaps["magma"], steps_norm(result),
                           f"traversal steps per pixel, log scale\n(brightest: {top:g} or "
                           "more)")


def with_banded_bar(rgb: np.ndarray, colours: np.ndarray, label: str) -> np.ndarray:
    """``with_colour_bar`` for a map of whole values 0..n-1 drawn in ``colours`` (n×3): a
    band per value, at most about 12 of them labelled."""
    top = len(colours) - 1
    return with_colour_bar(rgb, ListedColormap(colours),
                           BoundaryNorm(np.arange(-0.5, top + 1.0), len(colours)), label,
                           ticks=np.arange(0, top + 1, max(1, (top + 12) // 12)))


def lod_figure(result: RenderResult, depth: int) -> np.ndarray:
    """``lod_map`` with a colour bar of its LODs."""
    return with_banded_bar(lod_map(result, depth), lod_colours(depth),
                           "finest LOD per pixel (0: voxels)\nblack: nothing hit")


def rays_figure(result: RenderResult) -> np.ndarray:
    """``rays_map`` with a colour bar of its counts (where the error-aware and adaptive
    renderers refined): a band per count up to 24, a continuous scale beyond."""
    rgb, top = rays_map(result)
    label = "rays cast per pixel"
    if top > 24:
        return with_colour_bar(rgb, colormaps["viridis"], Normalize(0.0, top), label)
    return with_banded_bar(rgb, colormaps["viridis"](np.arange(top + 1) / top)[:, :3], label)


def counter_map_paths(image_path: str | Path) -> list[Path]:
    """Where an image's counter maps go: ``<stem>_steps.png``, ``<stem>_lod.png``,
    ``<stem>_rays.png`` and ``<stem>_summary.json`` beside it."""
    stem = Path(image_path).with_suffix("")
    return [Path(f"{stem}_{name}") for name in
            ("steps.png", "lod.png", "rays.png", "summary.json")]


def write_counter_files(result: RenderResult, paths: list[Path], depth: int) -> None:
    """The steps, LOD and ray-count maps and the summary into ``paths``
    (``counter_map_paths``' order) as given: to write them atomically, pass the staged paths
    of ``atomic.atomic_paths``, with the image's if they belong to one."""
    steps_path, lod_path, rays_path, summary_path = paths
    save_png(steps_figure(result), steps_path, encode_srgb=False)
    save_png(lod_figure(result, depth), lod_path, encode_srgb=False)
    save_png(rays_figure(result), rays_path, encode_srgb=False)
    Path(summary_path).write_text(json_text(result.summary()))
