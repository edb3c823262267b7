"""The decay × threshold sweep (EA Table 5.1): ray counts and quality of the error-aware
renderer over a grid, against the adaptive renderer's ray count as the thesis calibrates."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from voxfield.progress import progress_bar
from voxfield.render.adaptive import render_adaptive
from voxfield.render.camera import Camera
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_reference
from voxfield.studies.figures import view_sheet
from voxfield.studies.psnr_axis import finish_psnr_axis, plot_psnr
from voxfield.studies.report import (
    StudyFolder,
    costs_and_quality,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_title,
)
from voxfield.svo.octree import Octree

#: The thesis's grid (§5.1.4): decay 0.05–0.3, thresholds 0.175 down to 0.05.
THESIS_DECAYS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
THESIS_THRESHOLDS = (0.175, 0.15, 0.125, 0.1, 0.075, 0.05)


def run_sweep(
    octree: Octree, camera: Camera, out_dir: str | Path, *,
    decays=THESIS_DECAYS, thresholds=THESIS_THRESHOLDS, base_lod: int | None = 2,
    seed: int = 0, channel: str = "albedo", scene_name: str = "scene", progress: bool = False,
    fresh: bool = False, scheduler=None,
) -> dict:
    """Render the grid (resumable: finished cells are reused) and write results.json,
    results.md and sweep.png into ``out_dir``. The cells are independent items: with a
    ``scheduler`` (``voxfield.scaleout``) they run as tasks, with the same results."""
    folder = StudyFolder(out_dir, study="sweep", fresh=fresh, scheduler=scheduler)
    view = {"scene": scene_name, "fingerprint": octree.fingerprint(channel),
            "camera": camera.params.tolist(), "size": camera.width, "seed": seed,
            "channel": channel,
            "base_lod": base_lod}
    reference = folder.render_item("reference", view, lambda: render_reference(
        octree, camera, side=4, seed=seed, channel=channel))
    # Each item reads the octree and the reference from ``shared`` (scattered to a cluster
    # once), never from this closure.
    specs = [("adaptive", view, lambda shared: costs_and_quality(shared[1], render_adaptive(
        shared[0], camera, base_lod=base_lod, seed=seed, channel=channel)))]
    for decay in decays:
        for threshold in thresholds:
            specs.append((
                f"ea-d{decay:g}-t{threshold:g}", {**view, "decay": decay, "threshold": threshold},
                lambda shared, d=decay, t=threshold: costs_and_quality(
                    shared[1], render_error_aware(shared[0], camera, threshold=t, decay=d,
                                                  base_lod=base_lod, seed=seed,
                                                  channel=channel)),
            ))
    with progress_bar(total=len(specs), desc="sweep", unit="render", enabled=progress) as bar:
        adaptive, *values = folder.value_batch(specs, shared=(octree, reference), bar=bar)
    grid = [(d, t) for d in decays for t in thresholds]
    cells = [{"decay": d, "threshold": t, **cell} for (d, t), cell in zip(grid, values,
                                                                          strict=True)]
    picks = _closest_to_adaptive(cells, adaptive["rays"], decays)
    edges = sum(not pick["within_grid"] for pick in picks)
    if edges:  # the command line prints a warning as a note, --quiet or not
        warnings.warn(f"the adaptive ray count lies outside the grid's in {edges} of its "
                      f"{len(picks)} rows; {edge_advice(adaptive['rays'])}", UserWarning,
                      stacklevel=2)
    report = {"scene": scene_name, "width": camera.width, "height": camera.height,
              "base_lod": base_lod, "adaptive": adaptive, "cells": cells,
              "closest_to_adaptive": picks, "metrics_on": "linear RGB in [0, 1]"}
    folder.write_json("results.json", report)
    folder.write_text("results.md", _markdown(report, decays, thresholds))
    folder.write_figure("sweep.png", _figure(report, decays, thresholds))
    title = f"The view measured — {scene_title(scene_name)}"
    folder.write_figure("view.png", view_sheet({"4×4 reference": reference}, title=title))
    folder.publish_report()
    return report


def _closest_to_adaptive(cells, adaptive_rays, decays) -> list[dict]:
    """Per decay, the cell whose ray count is closest to the adaptive renderer's (§5.1.4);
    ``within_grid`` is false where every threshold of the row casts more rays than the
    adaptive renderer, or every one fewer: the pick is then the grid's edge, not a match."""
    picks = []
    for decay in decays:
        row = [c for c in cells if c["decay"] == decay]
        rays = [c["rays"] for c in row]
        best = min(row, key=lambda c: abs(c["rays"] - adaptive_rays))
        picks.append({**best, "within_grid": min(rays) <= adaptive_rays <= max(rays)})
    return picks


def edge_advice(adaptive_rays: int) -> str:
    """What to do when the adaptive ray count lies outside the grid's."""
    return (f"widen --thresholds, or bisect with `voxfield calibrate --target-rays "
            f"{adaptive_rays}`")


def _markdown(report, decays, thresholds) -> str:
    cells = {(c["decay"], c["threshold"]): c for c in report["cells"]}
    rays = [[f"d = {d}"] + [fmt(cells[d, t]["rays"]) for t in thresholds] for d in decays]
    psnr = [[f"d = {d}"] + [fmt_psnr(cells[d, t], ".2f") for t in thresholds] for d in decays]
    headers = ["decay \\ threshold", *[fmt(t, "g") for t in thresholds]]
    adaptive = report["adaptive"]
    picks = [[fmt(p["decay"], ".2f"),
              fmt(p["threshold"], ".3f") + ("" if p.get("within_grid", True) else " (edge)"),
              fmt(p["rays"]), fmt(p["steps"]), fmt_psnr(p, ".2f"), fmt(p["ssim"], ".4f")]
             for p in report["closest_to_adaptive"]]
    edges = [p for p in report["closest_to_adaptive"] if not p.get("within_grid", True)]
    edge_note = [] if not edges else [
        f"\n\"(edge)\": the adaptive renderer's {fmt(adaptive['rays'])} rays lie outside every "
        f"threshold's count in {len(edges)} of the {len(picks)} rows, so the threshold shown "
        f"is the grid's end, not a match; {edge_advice(adaptive['rays'])}.", ""]
    return "\n".join([
        f"# Decay × threshold sweep — {report['scene']}, {report['width']}×{report['height']}",
        "",
        f"Adaptive renderer: {fmt(adaptive['rays'])} rays, {fmt(adaptive['steps'])} steps, "
        f"PSNR {fmt_psnr(adaptive, '.2f')} dB (metrics on linear RGB in [0, 1]).",
        "",
        "## Ray counts (EA Table 5.1)",
        "",
        markdown_table(headers, rays),
        "## PSNR against the 4×4 reference (dB)",
        "",
        markdown_table(headers, psnr),
        "## Per decay, the threshold closest to the adaptive ray count",
        "",
        markdown_table(["decay", "threshold", "rays", "steps", "PSNR", "SSIM"], picks),
        *edge_note,
    ])


def _figure(report, decays, thresholds):
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    cells = {(c["decay"], c["threshold"]): c for c in report["cells"]}
    grid = np.array([[cells[d, t]["rays"] for t in thresholds] for d in decays], dtype=float)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.2))
    image = ax0.imshow(grid, cmap="magma", aspect="auto")
    ax0.set_xticks(range(len(thresholds)), [fmt(t, "g") for t in thresholds])
    ax0.set_yticks(range(len(decays)), [str(d) for d in decays])
    ax0.set_xlabel("error threshold")
    ax0.set_ylabel("decay d")
    ax0.set_title("rays (incl. discarded)")
    fig.colorbar(image, ax=ax0)
    for d in decays:
        # by rays alone: a tie went on to compare the PSNRs, and an infinite one (None)
        # with a number raised TypeError
        row = sorted((cells[d, t] for t in thresholds), key=lambda cell: cell["rays"])
        plot_psnr(ax1, [c["rays"] for c in row], [c["psnr"] for c in row], marker="o",
                  label=f"d = {d}")
    adaptive = report["adaptive"]
    plot_psnr(ax1, [adaptive["rays"]], [adaptive["psnr"]], marker="*", markersize=14,
              linestyle="none", color="black", label="adaptive", zorder=5)
    finish_psnr_axis(ax1)
    ax1.set_xlabel("rays")
    ax1.set_ylabel("PSNR vs reference (dB)")
    ax1.set_title("quality per cost")
    ax1.legend(fontsize=8)
    fig.suptitle(f"error-aware sweep — {scene_title(report['scene'])}")
    fig.tight_layout()
    return fig
