"""The study pictures of EA figs 5.1–5.3: grey-level cost maps and a labelled contact sheet.

Maps are grey levels in [0, 1] (write them with ``encode_srgb=False``); background is black in
every map, as in the thesis.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.render.image_io import shade_for_display
from voxfield.render.result import RenderResult
from voxfield.scene.voxel_scene import linear_to_srgb


def _map(result: RenderResult, name: str) -> np.ndarray:
    if name not in result.maps:
        raise VoxfieldError(f"the {result.renderer or 'given'} result has no {name!r} map")
    values = np.asarray(result.maps[name])
    if values.shape != result.shape:
        raise VoxfieldError(f"map {name!r} has shape {values.shape}, image {result.shape}")
    return values


def refinement_map(result: RenderResult) -> np.ndarray:
    """EA fig. 5.1c: black background, then darker to white for 1, 4 and 16 rays per pixel,
    from the adaptive renderer's ``refinement_class`` map (−1 background, 0, 1, 2)."""
    classes = _map(result, "refinement_class").astype(np.int64)
    return (np.clip(classes, -1, 2) + 1).astype(np.float32) / 3.0


def variance_map(result: RenderResult) -> np.ndarray:
    """EA fig. 5.1b: the adaptive renderer's normalised variance, clipped to [0, 1], black where
    not finite (background)."""
    variance = _map(result, "variance").astype(np.float32)
    return np.clip(np.nan_to_num(variance, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)


def ray_count_map(result: RenderResult, max_rays: int = 21) -> np.ndarray:
    """EA fig. 5.2a: rays cast per pixel, discarded ones included, black = 1 to white =
    ``max_rays``; pixels that hit nothing are black."""
    rays = np.asarray(result.ray_count, np.float32)
    grey = np.clip((rays - 1.0) / max(max_rays - 1, 1), 0.0, 1.0)
    grey[np.asarray(result.hit_count) <= 0] = 0.0
    return grey


def finest_lod_map(result: RenderResult, base_lod: int) -> np.ndarray:
    """EA fig. 5.2b: the finest LOD a pixel's rays sampled; white = LOD 0, one grey step per
    coarser LOD down to ``base_lod`` (or the coarsest sampled), black where nothing was hit."""
    lod = np.asarray(result.finest_lod, np.float32)
    steps = max(int(base_lod), int(lod.max(initial=0))) + 1
    grey = np.clip((steps - lod) / steps, 0.0, 1.0)
    grey[(lod < 0) | (np.asarray(result.hit_count) <= 0)] = 0.0
    return grey


@dataclass
class Panel:
    """One picture of a contact sheet: a linear RGB image (sRGB-encoded for display) or a grey
    map shown as is."""

    title: str
    image: np.ndarray
    linear_rgb: bool = True


def contact_sheet(cells: Sequence[Panel | str], *, columns: int, title: str = "",
                  panel_inches: float = 4.0):
    """A matplotlib Figure of the cells in a grid, row by row: each Panel pixel-exact (nearest)
    under its title, each string as monospaced text (a results table, settings)."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure


    rows = max(1, -(-len(cells) // columns))
    # Wrapped to the sheet, the sheet grown by the lines it adds: a one-panel sheet cut a
    # long title at both sides.
    title_lines = textwrap.wrap(title, width=int(panel_inches * columns * 8)) if title else []
    added = 0.25 * max(len(title_lines) - 1, 0)
    height = panel_inches * rows + 0.6
    fig = Figure(figsize=(panel_inches * columns, height + added), facecolor="white")
    if title:
        fig.suptitle("\n".join(title_lines), fontsize=13)
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax in axes:
        ax.set_axis_off()
    for ax, cell in zip(axes, cells, strict=False):
        if isinstance(cell, str):
            ax.text(0.0, 1.0, cell, family="monospace", fontsize=7.5, va="top", ha="left",
                    transform=ax.transAxes)
            continue
        image = np.asarray(cell.image, np.float32)
        if cell.linear_rgb:
            ax.imshow(linear_to_srgb(image), interpolation="nearest")
        else:
            ax.imshow(np.clip(image, 0.0, 1.0), cmap="gray", vmin=0.0, vmax=1.0,
                      interpolation="nearest")
        # Wrapped to the panel: a long title ran past the sheet's edge.
        ax.set_title(textwrap.fill(cell.title, width=int(panel_inches * 12)), fontsize=9)
    top = (0.90 * height) / (height + added) if title else 0.96
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=top, wspace=0.04, hspace=0.25)
    return fig


def view_sheet(references: dict[str, RenderResult], *, title: str = ""):
    """The view a study measured, one panel per camera or size: its 4×4 reference, lit for
    display by the key light (the metrics use the unlit colours). A study's numbers mean
    nothing for a camera under the terrain or looking past the scene; this shows which."""
    panels = [Panel(f"{name} (lit for display)", shade_for_display(result))
              for name, result in references.items()]
    return contact_sheet(panels, columns=min(len(panels), 4), title=title,
                         panel_inches=3.2 if len(panels) > 1 else 4.0)
