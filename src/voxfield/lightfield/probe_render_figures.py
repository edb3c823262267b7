"""Pictures and totals of a probe render's per-pixel maps: probes tried, texel fetches, what
answered each pixel, and the probe render beside the octree's own render of the same rays."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from voxfield.atomic import save_figure
from voxfield.lightfield.probe_render import kind_names
from voxfield.metrics import psnr_text
from voxfield.scene.voxel_scene import linear_to_srgb


def map_summary(result) -> dict:
    """Totals and means of the probe maps, and how many pixels got each kind of answer."""
    maps = result.maps
    pixels = max(result.ray_count.size, 1)
    names = kind_names()
    kinds, counts = np.unique(maps["result_kind"], return_counts=True)
    return {
        "probes_tried": int(maps["probes_tried"].sum()),
        "probes_tried_per_pixel": float(maps["probes_tried"].sum() / pixels),
        "texel_fetches": int(maps["texel_fetches"].sum()),
        "texel_fetches_per_pixel": float(maps["texel_fetches"].sum() / pixels),
        "pixels_by_kind": {names.get(int(k), str(int(k))): int(c)
                           for k, c in zip(kinds, counts, strict=True)},
    }


def write_probe_maps(result, image_path) -> list[Path]:
    """``<stem>_probes_tried.png``, ``<stem>_texel_fetches.png`` and ``<stem>_kind.png``
    beside the image: each map colour-mapped, with its legend."""
    stem = Path(image_path).with_suffix("")
    maps = result.maps
    tried = maps["probes_tried"]
    return [
        save_figure(_count_figure(tried, "probes tried per pixel", discrete=True),
                    f"{stem}_probes_tried.png", dpi=100),
        save_figure(_count_figure(maps["texel_fetches"], "texel fetches per pixel",
                                  discrete=False), f"{stem}_texel_fetches.png", dpi=100),
        save_figure(_kind_figure(maps["result_kind"], kind_names()), f"{stem}_kind.png",
                    dpi=100),
    ]


def _count_figure(values: np.ndarray, title: str, *, discrete: bool):
    """A per-pixel count on a colour scale with a colour bar; small integer ranges get one
    colour per value."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib import colormaps
    from matplotlib.colors import BoundaryNorm, Normalize
    from matplotlib.figure import Figure

    values = np.asarray(values)
    top = int(values.max()) if values.size else 0
    fig = Figure(figsize=(6.0, 5.0), facecolor="white", layout="constrained")
    ax = fig.add_subplot()
    if discrete and top <= 16:
        bounds = np.arange(-0.5, top + 1.5)
        cmap = colormaps["viridis"].resampled(top + 1)
        norm = BoundaryNorm(bounds, cmap.N)
        image = ax.imshow(values, cmap=cmap, norm=norm, interpolation="nearest")
        fig.colorbar(image, ax=ax, ticks=np.arange(top + 1), label=title)
    else:
        image = ax.imshow(values, cmap=colormaps["magma"], norm=Normalize(0, max(top, 1)),
                          interpolation="nearest")
        fig.colorbar(image, ax=ax, label=title)
    ax.set_title(f"{title}: mean {values.mean():.2f}, max {top}")
    ax.set_axis_off()
    return fig


def _kind_figure(kind: np.ndarray, names: dict[int, str]):
    """What answered each pixel, one colour per kind, with a legend."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    palette = ["#2a9d8f", "#264653", "#e76f51", "#e9c46a", "#8ab17d", "#f4a261", "#6d597a"]
    codes = sorted(names)
    index = {c: i for i, c in enumerate(codes)}
    picture = np.vectorize(lambda k: index.get(int(k), len(codes)))(kind) if kind.size else kind
    colours = [palette[i % len(palette)] for i in range(len(codes))] + ["#ff00ff"]
    fig = Figure(figsize=(7.0, 5.0), facecolor="white", layout="constrained")
    ax = fig.add_subplot()
    ax.imshow(picture, cmap=ListedColormap(colours), vmin=-0.5, vmax=len(codes) + 0.5,
              interpolation="nearest")
    present = set(np.unique(kind).tolist())
    handles = [Patch(color=colours[index[c]], label=f"{names[c]} ({int((kind == c).sum()):,})")
               for c in codes if c in present]
    fig.legend(handles=handles, loc="outside right upper", fontsize=8)
    ax.set_title("answer per pixel")
    ax.set_axis_off()
    return fig


def write_side_by_side(result, reference, metrics: dict, path, *, difference=None) -> Path:
    """Probe render, octree render and their absolute difference (×4) side by side, sRGB.
    ``difference``: the (probe, octree) images to difference, when the two shown are lit for
    display (the metrics compare the unlit ones)."""
    from matplotlib.figure import Figure  # heavy: loads only when a figure is drawn

    probe = np.clip(result.image, 0.0, 1.0)
    direct = np.clip(reference.image, 0.0, 1.0)
    lit = difference is not None
    measured = tuple(np.clip(image, 0.0, 1.0) for image in difference) if lit else \
        (probe, direct)
    difference = np.clip(4.0 * np.abs(measured[0] - measured[1]), 0.0, 1.0)
    fig = Figure(figsize=(13.5, 4.8), facecolor="white", layout="constrained")
    panels = [(linear_to_srgb(probe), f"{result.renderer}"),
              (linear_to_srgb(direct), f"octree: {metrics['reference']}"),
              (difference, f"|difference| × 4: PSNR {psnr_text(metrics['psnr'])} dB, "
                           f"SSIM {metrics['ssim']:.3f}")]
    for k, (image, title) in enumerate(panels):
        ax = fig.add_subplot(1, 3, k + 1)
        ax.imshow(image, interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.set_axis_off()
    if lit:
        fig.suptitle("both renders lit for display by the normals each returns; the "
                     "difference and the metrics compare their unlit colours", fontsize=8)
    return save_figure(fig, path, dpi=100)

