"""Pictures of the cost counters: traversal steps and finest LOD per pixel (EA figs 5.1–5.3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from matplotlib import colormaps

from voxfield.render.image_io import save_png
from voxfield.render.result import RenderResult


def steps_heatmap(result: RenderResult) -> np.ndarray:
    """Traversal steps per pixel on the magma scale, normalised at the 99th percentile."""
    steps = result.steps.astype(np.float64)
    top = float(np.percentile(steps[steps > 0], 99)) if steps.any() else 1.0
    return colormaps["magma"](np.clip(steps / max(top, 1.0), 0.0, 1.0))[..., :3]


def lod_map(result: RenderResult, depth: int) -> np.ndarray:
    """Finest LOD sampled per pixel, one viridis colour per LOD (LOD 0 brightest); black where
    nothing was hit."""
    lod = result.finest_lod.astype(np.float64)
    rgb = colormaps["viridis"](1.0 - np.clip(lod, 0, depth) / max(depth, 1))[..., :3]
    rgb[lod < 0] = 0.0
    return rgb


def counter_map_paths(image_path: str | Path) -> list[Path]:
    """Where an image's counter maps go: ``<stem>_steps.png``, ``<stem>_lod.png`` and
    ``<stem>_summary.json`` beside it."""
    stem = Path(image_path).with_suffix("")
    return [Path(f"{stem}_steps.png"), Path(f"{stem}_lod.png"), Path(f"{stem}_summary.json")]


def write_counter_files(result: RenderResult, paths: list[Path], depth: int) -> None:
    """The steps heat map, the LOD map and the summary into ``paths`` (``counter_map_paths``'
    order) as given: to write them atomically, pass the staged paths of
    ``atomic.atomic_paths``, with the image's if they belong to one."""
    steps_path, lod_path, summary_path = paths
    save_png(steps_heatmap(result), steps_path, encode_srgb=False)
    save_png(lod_map(result, depth), lod_path, encode_srgb=False)
    Path(summary_path).write_text(json.dumps(result.summary(), indent=2))
