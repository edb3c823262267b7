"""Pictures of one mask's error over the sphere (like EA fig. 3.2): value as colour, directions
above a threshold marked red, beside a sketch of the child configuration."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from voxfield.atomic import save_figure
from voxfield.error_table.table import THESIS_THRESHOLD, ErrorTable
from voxfield.errors import VoxfieldError

#: (name, viewer position) of the sphere views; the viewer looks at the origin.
VIEWS = (("+z", (0.0, 0.0, 1.0)), ("+x", (1.0, 0.0, 0.0)), ("+y (above)", (0.0, 1.0, 0.0)))


def sphere_view(table: ErrorTable, mask: int, viewer, size: int = 200, encoding=None):
    """Error on the visible hemisphere of the unit sphere seen from ``viewer``.

    A surface point with outward normal ``n`` shows the error of rays travelling along
    ``-n`` (the view from outside, as in the thesis). Returns (error image, inside-disc mask).
    """
    v = np.asarray(viewer, dtype=np.float64)
    v /= np.linalg.norm(v)
    helper = np.array([0.0, 1.0, 0.0]) if abs(v[1]) < 0.9 else np.array([0.0, 0.0, -1.0])
    right = np.cross(helper, v)
    right /= np.linalg.norm(right)
    up = np.cross(v, right)
    a = (np.arange(size) + 0.5) / size * 2 - 1
    xx, yy = np.meshgrid(a, -a)
    inside = xx**2 + yy**2 < 1.0
    zz = np.sqrt(np.clip(1.0 - xx**2 - yy**2, 0.0, 1.0))
    normals = xx[..., None] * right + yy[..., None] * up + zz[..., None] * v
    errors = np.zeros((size, size))
    errors[inside] = table.error(mask, -normals[inside], encoding)
    return errors, inside


def _child_boxes(ax, mask: int) -> None:
    filled = np.zeros((2, 2, 2), bool)
    for c in range(8):
        if mask >> c & 1:
            # Plot axes are (x, z, y) so that +y, our up, points up in the picture.
            filled[c & 1, (c >> 2) & 1, (c >> 1) & 1] = True
    ax.voxels(filled, facecolors="#7fa7d9", edgecolors="#1f3f6f", linewidth=0.5)
    for axis in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        axis(0, 2)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_zlabel("y")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])
    ax.set_title(f"children of mask {mask} (0b{mask:08b})", fontsize=9)


def _threshold_on_bar(bar, threshold: float) -> str:
    """Mark the threshold on the colour bar, which spans the errors' 0..1, and say where it
    is: a threshold off the bar has no line there, which the title promised all the same."""
    low, high = bar.mappable.get_clim()
    if threshold < low:
        return f"below the bar's {low:g}: every direction"
    if threshold > high:
        return f"above the bar's {high:g}: no direction"
    bar.ax.axhline(threshold, color="red", linewidth=1.5)
    return "the red line on the bar"


def plot_mask_error(
    table: ErrorTable, mask: int, path: str | Path, *, threshold: float = THESIS_THRESHOLD,
    encoding: str | None = None,
) -> Path:
    """Write a PNG: the child configuration and three sphere views with the threshold marked."""
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    if not 0 <= int(mask) <= 255:
        raise VoxfieldError(f"child mask must be between 0 and 255, got {mask}")
    encoding = encoding or table.default_encoding
    # The hatches above the threshold take their colour from these settings.
    with matplotlib.rc_context({"hatch.color": "red", "hatch.linewidth": 0.7}):
        fig = plt.figure(figsize=(13, 3.6), dpi=110)
        ax = fig.add_subplot(1, 4, 1, projection="3d")
        _child_boxes(ax, int(mask))
        image = None
        for i, (name, viewer) in enumerate(VIEWS):
            ax = fig.add_subplot(1, 4, i + 2)
            errors, inside = sphere_view(table, int(mask), viewer, encoding=encoding)
            shown = np.ma.masked_where(~inside, errors)
            image = ax.imshow(shown, cmap="viridis", vmin=0.0, vmax=1.0)
            above = inside & (errors > threshold)
            # Hatched rather than tinted: a tint changed every colour above the threshold, and
            # the error could no longer be read off the colour bar there.
            if above.any():
                ax.contourf(np.where(above, 1.0, 0.0), levels=[0.5, 1.5], colors="none",
                            hatches=["//"])
            if above.any() and not above[inside].all():
                ax.contour(np.where(inside, errors, 0.0), levels=[threshold], colors="red",
                           linewidths=1.2)
            share = above.sum() / max(1, inside.sum())
            ax.set_title(f"viewer at {name}: {share:.0%} > {threshold:g}", fontsize=9)
            ax.axis("off")
        bar = fig.colorbar(image, ax=fig.axes[1:], fraction=0.02, pad=0.02, label="error")
        fig.suptitle(f"sampling error of a node instead of its children ({encoding} encoding); "
                     f"hatched red: above the threshold {threshold:g} "
                     f"({_threshold_on_bar(bar, threshold)})", fontsize=10)

        try:
            return save_figure(fig, path)
        finally:
            plt.close(fig)
