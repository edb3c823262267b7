"""The error-threshold study (EA §5.4, Tables 5.27–5.28, figs 5.11–5.15): cost and quality of
the error-aware renderer per threshold, beside the adaptive renderer as a fixed baseline."""

from __future__ import annotations

import math
from pathlib import Path

from voxfield.error_table.table import THESIS_DECAY
from voxfield.progress import progress_bar
from voxfield.render.adaptive import render_adaptive
from voxfield.render.camera import Camera
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_reference
from voxfield.studies.figures import view_sheet
from voxfield.studies.psnr_axis import finish_psnr_axis, plot_psnr, psnr_hline
from voxfield.studies.report import (
    StudyFolder,
    costs,
    costs_and_quality,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_title,
)
from voxfield.svo.octree import Octree

#: The thesis's thresholds (Table 5.27: 0.05–0.175) widened to 0.3 on the cheap side.
THESIS_THRESHOLDS = (0.05, 0.075, 0.1, 0.125, 0.15, 0.175, 0.2, 0.25, 0.3)

#: The five plotted quantities: (key, axis label, log-scale y).
PANELS = (("rays", "rays", True), ("steps", "traversal steps", True),
          ("psnr", "PSNR (dB)", False), ("rmse", "RMSE", False), ("ssim", "SSIM", False))


def run_threshold_study(
    octree: Octree, camera: Camera, out_dir: str | Path, *,
    thresholds=THESIS_THRESHOLDS, decay: float = THESIS_DECAY, base_lod: int | None = 2,
    seed: int = 0, channel: str = "albedo", scene_name: str = "scene", progress: bool = False,
    fresh: bool = False, scheduler=None,
) -> dict:
    """Render the error-aware renderer per threshold (resumable) and write results.json,
    results.md and thresholds.png into ``out_dir``. The thresholds are independent items:
    with a ``scheduler`` (``voxfield.scaleout``) they run as tasks, with the same results."""
    folder = StudyFolder(out_dir, study="study thresholds", fresh=fresh, scheduler=scheduler)
    view = {"scene": scene_name, "fingerprint": octree.fingerprint(channel),
            "camera": camera.params.tolist(), "size": camera.width, "height": camera.height,
            "seed": seed, "channel": channel, "base_lod": base_lod}
    with progress_bar(total=len(thresholds) + 2, desc="thresholds", unit="render",
                      enabled=progress) as bar:
        reference = folder.render_item("reference", view, lambda: render_reference(
            octree, camera, side=4, seed=seed, channel=channel))
        bar.update(1)
        # Each item reads the octree and the reference from ``shared`` (scattered once).
        specs = [("adaptive", view, lambda shared: costs_and_quality(
            shared[1], render_adaptive(shared[0], camera, base_lod=base_lod, seed=seed,
                                       channel=channel)))]
        specs += [(f"ea-d{decay:g}-t{threshold:g}",
                   {**view, "decay": decay, "threshold": threshold},
                   lambda shared, t=threshold: costs_and_quality(shared[1], render_error_aware(
                       shared[0], camera, threshold=t, decay=decay, base_lod=base_lod,
                       seed=seed, channel=channel)))
                  for threshold in thresholds]
        adaptive, *cells = folder.value_batch(specs, shared=(octree, reference), bar=bar)
    rows = [{"threshold": t, "error_aware": cell, "adaptive": adaptive}
            for t, cell in zip(thresholds, cells, strict=True)]
    report = {"scene": scene_name, "width": camera.width, "height": camera.height,
              "decay": decay, "base_lod": base_lod, "seed": seed,
              "reference": costs(reference), "adaptive": adaptive, "rows": rows,
              "metrics_on": "linear RGB in [0, 1]"}
    folder.write_json("results.json", report)
    folder.write_text("results.md", _markdown(report))
    folder.write_figure("thresholds.png", _figure(report))
    title = f"The view measured — {scene_title(scene_name)}"
    folder.write_figure("view.png", view_sheet({"4×4 reference": reference}, title=title))
    folder.publish_report()
    return report


def _markdown(report) -> str:
    a = report["adaptive"]
    cost = [[fmt(r["threshold"], "g"), fmt(a["rays"]), fmt(a["steps"]),
             fmt(r["error_aware"]["rays"]), fmt(r["error_aware"]["rays_hit_pixels"]),
             fmt(r["error_aware"]["steps"])] for r in report["rows"]]
    quality = []
    for r in report["rows"]:
        e = r["error_aware"]
        quality.append([fmt(r["threshold"], "g"), fmt_psnr(a, ".3f"), fmt_psnr(e, ".3f"),
                        fmt(a["rmse"], ".5f"), fmt(e["rmse"], ".5f"), fmt(a["ssim"], ".4f"),
                        fmt(e["ssim"], ".4f")])
    ref = report["reference"]
    return "\n".join([
        f"# Error threshold — {report['scene']}, {report['width']}×{report['height']}",
        "",
        f"Decay {report['decay']}, base LOD {report['base_lod']}, seed {report['seed']}. "
        f"Adaptive (A) is a fixed row; error-aware (EA) per threshold. The 4×4 reference casts "
        f"{fmt(ref['rays'])} rays, {fmt(ref['steps'])} steps. Metrics on linear RGB in [0, 1].",
        "",
        "## Ray and traversal step counts (EA Table 5.27)",
        "",
        "Rays (EA) counts every ray cast, discarded ones included; rays hit (EA) only those of "
        "pixels that hit geometry.",
        "",
        markdown_table(["threshold", "rays (A)", "steps (A)", "rays (EA)", "rays hit (EA)",
                        "steps (EA)"], cost),
        "## Image similarity to the reference (EA Table 5.28)",
        "",
        markdown_table(["threshold", "PSNR (A)", "PSNR (EA)", "RMSE (A)", "RMSE (EA)",
                        "SSIM (A)", "SSIM (EA)"], quality),
    ])


#: The largest threshold magnitude a linear x axis holds: near the float limit (1.8e308)
#: matplotlib's axis margins and tick steps overflow.
LINEAR_AXIS_LIMIT = 1e300


def threshold_axis(thresholds) -> tuple[list[float], list[str] | None]:
    """Where the figure plots each threshold: at its value on a linear axis, or, where one
    is infinite, NaN or beyond ``LINEAR_AXIS_LIMIT``, at evenly spaced positions labelled
    with the values (then also the labels)."""
    values = [float(t) for t in thresholds]
    if all(math.isfinite(t) and abs(t) <= LINEAR_AXIS_LIMIT for t in values):
        return values, None
    return [float(k) for k in range(len(values))], [f"{t:g}" for t in values]


def plot_value(value) -> float:
    """A plottable float: None (an infinite PSNR in JSON) becomes NaN."""
    return math.nan if value is None else float(value)


def _figure(report):
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    rows = sorted(report["rows"], key=lambda r: r["threshold"])
    x, labels = threshold_axis(r["threshold"] for r in rows)
    fig, axes = plt.subplots(1, len(PANELS), figsize=(17, 3.4))
    for ax, (key, label, log) in zip(axes, PANELS, strict=True):
        label_ea = "error-aware" + (" (all cast)" if key == "rays" else "")
        if key == "psnr":
            plot_psnr(ax, x, [r["error_aware"][key] for r in rows], marker="o", label=label_ea)
        else:
            ax.plot(x, [plot_value(r["error_aware"][key]) for r in rows], marker="o",
                    label=label_ea)
        if key == "rays":
            ax.plot(x, [r["error_aware"]["rays_hit_pixels"] for r in rows], marker=".",
                    linestyle=":", label="error-aware (hit pixels)")
        if key == "psnr":
            psnr_hline(ax, report["adaptive"][key], color="black", linestyle="--",
                       label="adaptive")
            finish_psnr_axis(ax)
        else:
            ax.axhline(plot_value(report["adaptive"][key]), color="black", linestyle="--",
                       label="adaptive")
        if log:
            ax.set_yscale("log")
        if labels is not None:
            ax.set_xticks(x, labels, rotation=30, fontsize=7)
            ax.set_xlim(-0.5, len(x) - 0.5)
        ax.set_xlabel("error threshold" + (" (evenly spaced)" if labels is not None else ""))
        ax.set_title(label)
    # One legend above the panels (the rays panel's lines name them all): inside each panel
    # it covered points.
    fig.legend(*axes[0].get_legend_handles_labels(), loc="upper right", fontsize=8, ncols=3)
    fig.suptitle(f"error threshold — {scene_title(report['scene'])}, decay {report['decay']}",
                 x=0.3)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return fig
