"""``voxfield probes show``: one PNG to check a bake by eye.

Three atlases, one tile per probe in probe order (x fastest, then y, then z), without the
octahedral border: radiance (sRGB), radial distance (colour-mapped, with a legend in voxels;
grey where the ray escaped) and normals (RGB = normal / 2 + 1/2, black where there is none).
Disabled probes are crossed out. Beside them, a 3D overview: the probe positions projected
onto an orbit render of the scene — hollow where geometry hides the probe, orange with a line
from its lattice point where relocation moved it, a red cross where it is disabled.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from voxfield.atomic import save_figure
from voxfield.probes.probe_set import decode_normals
from voxfield.render.camera import framing_camera
from voxfield.render.image_io import shade_for_display
from voxfield.render.primary import render_lod
from voxfield.scene.voxel_scene import linear_to_srgb

GAP = 1  # texels between tiles
ESCAPED_GREY = 0.35
LABELLED_PROBES = 64  # up to this many probes, tiles and dots carry their index


def tile(maps: np.ndarray, fill) -> np.ndarray:
    """(N, R, R[, C]) → one image of near-square tiles separated by ``GAP`` texels."""
    n, r = maps.shape[0], maps.shape[1]
    columns = max(1, math.ceil(math.sqrt(n)))
    rows = max(1, math.ceil(n / columns))
    step = r + GAP
    out = np.full((rows * step - GAP, columns * step - GAP) + maps.shape[3:], fill, maps.dtype)
    for i in range(n):
        row, col = divmod(i, columns)
        out[row * step:row * step + r, col * step:col * step + r] = maps[i]
    return out


def tile_origins(count: int, resolution: int) -> list[tuple[int, int]]:
    """(row, col) of each tile's top-left texel in ``tile``'s layout."""
    columns = max(1, math.ceil(math.sqrt(count)))
    step = resolution + GAP
    return [(row * step, col * step) for row, col in (divmod(i, columns) for i in range(count))]


def display_atlases(probe_set) -> dict[str, np.ndarray]:
    """The three atlases as displayable arrays: radiance linear RGB, distance (NaN where
    escaped) and normals RGB in [0, 1]."""
    radiance = np.asarray(probe_set.radiance, np.float32)
    distance = np.asarray(probe_set.distance, np.float32)
    normals = decode_normals(probe_set.normal)
    has_normal = np.any(normals != 0, axis=-1, keepdims=True)
    return {
        "radiance": tile(radiance, 1.0),
        "distance": tile(np.where(np.isfinite(distance), distance, np.nan), -1.0),
        "normal": tile(np.where(has_normal, normals * 0.5 + 0.5, 0.0), 1.0),
    }


def project(camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pinhole projection of world points: (x, y) pixel coordinates (x right, y down), the
    distance from the eye, and whether each point lies in front of the camera."""
    p = np.asarray(points, np.float64) - camera.position
    depth = p @ camera.forward
    front = depth > 1e-9
    safe = np.where(front, depth, 1.0)
    a = (p @ camera.right) / safe / camera.half_width
    b = (p @ camera.up) / safe / camera.half_height
    xy = np.stack([(a + 1.0) * camera.width / 2.0, (1.0 - b) * camera.height / 2.0], axis=1)
    return xy, np.linalg.norm(p, axis=1), front


def overview_camera(octree, positions: np.ndarray, size: int):
    """A view framing the scene and every probe."""
    points = np.asarray(positions, np.float64).reshape(-1, 3)
    if octree is not None:
        points = np.concatenate([points, np.asarray(octree.voxel_bounds, np.float64)])
    return framing_camera(points, size=size)


def render_overview(octree, camera):
    """A quick shaded render (one LOD-0 ray per pixel) and its per-pixel hit distance."""
    result = render_lod(octree, camera, lod=0, side=1)
    hit = np.isfinite(result.depth)
    image = np.where(hit[..., None], shade_for_display(result), 0.08)
    return image.astype(np.float32), result.depth


def figure(probe_set, *, octree=None, title: str = "", size: int = 512):
    """The matplotlib Figure: three atlases and the 3D overview."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D


    atlases = display_atlases(probe_set)
    # Constrained layout keeps the distance bar's label inside the figure whatever its ticks'
    # width (fixed margins cut it off at three digits).
    fig = Figure(figsize=(14, 12), facecolor="white", layout="constrained")
    if title:
        fig.suptitle(title, fontsize=12)
    axes = fig.subplots(2, 2).ravel()
    for ax in axes:
        ax.set_axis_off()

    r = probe_set.resolution
    origins = tile_origins(probe_set.count, r)
    disabled = np.flatnonzero(~np.asarray(probe_set.enabled, bool))

    axes[0].imshow(linear_to_srgb(np.clip(atlases["radiance"], 0.0, 1.0)),
                   interpolation="nearest")
    axes[0].set_title(f"radiance (sRGB), {probe_set.count} probes of {r}² texels", fontsize=10)

    distance = atlases["distance"]
    finite = distance[np.isfinite(distance)]
    vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    cmap = matplotlib.colormaps["viridis"].with_extremes(bad=(ESCAPED_GREY,) * 3, under="white")
    shown = axes[1].imshow(np.ma.masked_invalid(distance), cmap=cmap, vmin=0.0, vmax=vmax,
                           interpolation="nearest")
    bar = fig.colorbar(shown, ax=axes[1], shrink=0.8, pad=0.02)
    bar.set_label("radial distance (voxels); grey: no surface", fontsize=9)
    axes[1].set_title("distance", fontsize=10)

    axes[2].imshow(np.clip(atlases["normal"], 0.0, 1.0), interpolation="nearest")
    axes[2].set_title("normals (RGB = n/2 + 1/2; black: none)", fontsize=10)

    if probe_set.count <= LABELLED_PROBES:
        for i, (top, left) in enumerate(origins):
            axes[0].text(left, top, str(i), fontsize=6, va="top", ha="left", color="white",
                         bbox={"facecolor": "black", "alpha": 0.5, "pad": 0.5, "lw": 0})
    for ax in axes[:3]:
        for i in disabled:
            top, left = origins[i]
            ax.plot([left - 0.5, left + r - 0.5], [top - 0.5, top + r - 0.5], color="red", lw=1)
            ax.plot([left - 0.5, left + r - 0.5], [top + r - 0.5, top - 0.5], color="red", lw=1)

    _draw_overview(axes[3], probe_set, octree, size)
    legend = [
        Line2D([], [], marker="o", ls="", color="#22d3ee", label="probe"),
        Line2D([], [], marker="o", ls="", mfc="none", color="#22d3ee", label="hidden by geometry"),
        Line2D([], [], marker="o", ls="", color="#f59e0b", label="moved by relocation"),
        Line2D([], [], marker="x", ls="", color="red", label="disabled"),
    ]
    axes[3].legend(handles=legend, loc="lower left", fontsize=8, framealpha=0.8)
    return fig


def _draw_overview(ax, probe_set, octree, size: int) -> None:
    positions = np.asarray(probe_set.positions, np.float64)
    grid = probe_set.grid
    base = np.asarray(getattr(grid, "base_positions", positions), np.float64)
    camera = overview_camera(octree, positions, size)
    if octree is not None:

        image, depth = render_overview(octree, camera)
        ax.imshow(linear_to_srgb(image), interpolation="nearest")
        ax.set_title("probes over the scene (orbit view)", fontsize=10)
    else:
        depth = np.full((camera.height, camera.width), np.inf)
        ax.imshow(np.full((camera.height, camera.width, 3), 0.12), interpolation="nearest")
        ax.set_title("probe positions (scene not available: pass --scene)", fontsize=10)
    xy, dist, front = project(camera, positions)
    base_xy, _, base_front = project(camera, base)
    h, w = depth.shape
    col = np.clip(xy[:, 0].astype(np.int64), 0, w - 1)
    row = np.clip(xy[:, 1].astype(np.int64), 0, h - 1)
    hidden = depth[row, col] < dist - 0.5
    enabled = np.asarray(probe_set.enabled, bool)
    moved = np.any(np.asarray(getattr(grid, "offsets", np.zeros_like(positions))) != 0, axis=1)
    dot = max(2.0, 8.0 - 0.5 * math.log2(max(len(positions), 1)))
    for i in np.flatnonzero(front):
        x, y = xy[i]
        if not enabled[i]:
            ax.plot(x, y, marker="x", color="red", ms=dot + 1, mew=1.5)
            continue
        colour = "#f59e0b" if moved[i] else "#22d3ee"
        if moved[i] and base_front[i]:
            ax.plot([base_xy[i, 0], x], [base_xy[i, 1], y], color=colour, lw=0.8)
        ax.plot(x, y, marker="o", ms=dot, color=colour,
                mfc="none" if hidden[i] else colour, mew=1.2)
    if len(positions) <= LABELLED_PROBES:
        for i in np.flatnonzero(front):
            ax.annotate(str(i), xy[i], xytext=(3, 3), textcoords="offset points", fontsize=6,
                        color="white")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)


def write_show(probe_set, out: str | os.PathLike, *, octree=None, title: str = "",
               size: int = 512, dpi: int = 100) -> Path:
    """Write the figure as PNG (atomically)."""
    return save_figure(figure(probe_set, octree=octree, title=title, size=size), out, dpi=dpi)
