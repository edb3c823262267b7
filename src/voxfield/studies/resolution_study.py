"""The resolution study (EA §5.5, Tables 5.29–5.30, figs 5.16–5.19): reference, adaptive and
error-aware renders of the top-down view at several image sizes.

The base LOD follows the resolution so one base-LOD node covers about one pixel:
``base_lod = clamp(round(log2(footprint / size)), 0, depth)``, ``footprint`` the map's larger
horizontal extent in voxels (what the 90° top-down camera spans), halves rounding up. The
thesis's 2048² desert at 512² gives LOD 2; at 64² it gives LOD 5.
"""

from __future__ import annotations

import math
from pathlib import Path

from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD
from voxfield.errors import VoxfieldError
from voxfield.progress import progress_bar
from voxfield.render.adaptive import render_adaptive
from voxfield.render.camera import top_down_camera
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_reference
from voxfield.studies.figures import view_sheet
from voxfield.studies.psnr_axis import finish_psnr_axis, plot_psnr
from voxfield.studies.report import (
    StudyFolder,
    costs,
    costs_and_quality,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_title,
)
from voxfield.studies.threshold_study import PANELS, plot_value
from voxfield.svo.octree import Octree

THESIS_SIZES = (128, 256, 512, 1024)
RENDERERS = ("reference", "adaptive", "error_aware")
_COLOURS = {"reference": "tab:gray", "adaptive": "tab:orange", "error_aware": "tab:blue"}


def base_lod_for(footprint: float, size: int, depth: int) -> int:
    """The LOD whose nodes are about one pixel wide when ``size`` pixels span ``footprint``
    voxels: ``round(log2(footprint / size))`` clamped to ``[0, depth]``."""
    if not footprint > 0 or size < 1:
        raise VoxfieldError("the footprint and the image size must be positive")
    lod = math.floor(math.log2(footprint / size) + 0.5)
    return max(0, min(int(depth), lod))


def map_footprint(octree: Octree) -> int:
    """The larger horizontal (x, z) extent of the voxels: what the top-down camera spans."""
    lo, hi = octree.voxel_bounds
    return int(max(hi[0] - lo[0], hi[2] - lo[2]))


def run_resolution_study(
    octree: Octree, out_dir: str | Path, *, sizes=THESIS_SIZES, threshold: float = THESIS_THRESHOLD,
    decay: float = THESIS_DECAY, seed: int = 0, channel: str = "albedo", scene_name: str = "scene",
    progress: bool = False,
    fresh: bool = False, scheduler=None,
) -> dict:
    """Render the three renderers at each size (resumable) and write results.json,
    results.md and resolution.png into ``out_dir``. The references, then the cheap renders,
    are independent items: with a ``scheduler`` (``voxfield.scaleout``) they run as tasks,
    with the same results."""
    folder = StudyFolder(out_dir, study="study resolution", fresh=fresh, scheduler=scheduler)
    lo, hi = octree.voxel_bounds
    footprint = map_footprint(octree)
    fingerprint = octree.fingerprint(channel)
    cameras = [top_down_camera(lo, hi, size=size, fov_deg=90) for size in sizes]
    base_lods = [base_lod_for(footprint, size, octree.depth) for size in sizes]
    views = [{"scene": scene_name, "fingerprint": fingerprint, "camera": c.params.tolist(),
              "size": size, "seed": seed} for size, c in zip(sizes, cameras, strict=True)]
    with progress_bar(total=3 * len(sizes), desc="resolution", unit="render",
                      enabled=progress) as bar:
        references = folder.render_batch(
            [(f"reference-s{size}", view, lambda shared, c=c: render_reference(
                shared, c, side=4, seed=seed, channel=channel))
             for size, view, c in zip(sizes, views, cameras, strict=True)],
            shared=octree, bar=bar)
        # Each item reads the octree and its size's reference from ``shared``.
        specs = []
        for k, (size, view, c, b) in enumerate(zip(sizes, views, cameras, base_lods,
                                                   strict=True)):
            specs.append((f"adaptive-s{size}", {**view, "base_lod": b},
                          lambda shared, c=c, b=b, k=k: costs_and_quality(
                              shared[1][k], render_adaptive(shared[0], c, base_lod=b, seed=seed,
                                                            channel=channel))))
            specs.append((f"ea-s{size}-d{decay:g}-t{threshold:g}",
                          {**view, "base_lod": b, "decay": decay, "threshold": threshold},
                          lambda shared, c=c, b=b, k=k: costs_and_quality(
                              shared[1][k], render_error_aware(
                                  shared[0], c, threshold=threshold, decay=decay, base_lod=b,
                                  seed=seed, channel=channel))))
        values = folder.value_batch(specs, shared=(octree, references), bar=bar)
    rows = [{"size": size, "pixels": size * size, "base_lod": b, "reference": costs(ref),
             "adaptive": values[2 * k], "error_aware": values[2 * k + 1]}
            for k, (size, b, ref) in enumerate(zip(sizes, base_lods, references, strict=True))]
    report = {"scene": scene_name, "footprint": footprint, "depth": octree.depth,
              "threshold": threshold, "decay": decay, "seed": seed, "channel": channel,
              "camera": "top, 90°",
              "base_lod_rule": "clamp(round(log2(footprint / size)), 0, depth)",
              "rows": rows, "metrics_on": "linear RGB in [0, 1]"}
    folder.write_json("results.json", report)
    folder.write_text("results.md", _markdown(report))
    folder.write_figure("resolution.png", _figure(report))
    folder.write_figure("view.png", view_sheet(
        {f"{size}², 4×4 reference": ref for size, ref in zip(sizes, references, strict=True)},
        title=f"The view measured at each size — {scene_title(scene_name)}"))
    folder.publish_report()
    return report


def _markdown(report) -> str:
    rows = sorted(report["rows"], key=lambda r: -r["size"])
    cost, quality = [], []
    for r in rows:
        res, a, e, ref = f"{r['size']}x{r['size']}", r["adaptive"], r["error_aware"], \
            r["reference"]
        cost.append([res, str(r["base_lod"]), fmt(ref["rays"]), fmt(a["rays"]),
                     fmt(a["rays_per_pixel"], ".3f"), fmt(a["steps"]), fmt(e["rays"]),
                     fmt(e["rays_per_pixel"], ".3f"), fmt(e["steps"])])
        quality.append([res, fmt_psnr(a, ".3f"), fmt_psnr(e, ".3f"), fmt(a["rmse"], ".5f"),
                        fmt(e["rmse"], ".5f"), fmt(a["ssim"], ".4f"), fmt(e["ssim"], ".4f")])
    return "\n".join([
        f"# Resolution — {report['scene']}",
        "",
        f"Top-down 90° camera over a {report['footprint']}-voxel footprint (octree depth "
        f"{report['depth']}); error-aware threshold {report['threshold']}, decay "
        f"{report['decay']}, seed {report['seed']}. The base LOD of both cheap renderers "
        f"follows the resolution, `{report['base_lod_rule']}`, so one base-LOD node covers "
        "about a pixel. Rays count every ray cast (discarded ones included); metrics on "
        "linear RGB in [0, 1].",
        "",
        "## Ray and traversal step counts (EA Table 5.29)",
        "",
        markdown_table(["resolution", "base LOD", "rays (ref)", "rays (A)", "rays/px (A)",
                        "steps (A)", "rays (EA)", "rays/px (EA)", "steps (EA)"], cost),
        "## Image similarity to the reference (EA Table 5.30)",
        "",
        markdown_table(["resolution", "PSNR (A)", "PSNR (EA)", "RMSE (A)", "RMSE (EA)",
                        "SSIM (A)", "SSIM (EA)"], quality),
        *_notes(rows),
    ])


def _notes(rows) -> list[str]:
    """What makes a row read against the thesis's trend (rays grow with the pixels, quality
    falls with the size): a base LOD of 0 leaves nothing to refine, and refinement can cost
    more rays than the 4×4 reference, as every discarded coarser ray counts."""
    notes = []
    flat = [f"{r['size']}x{r['size']}" for r in rows if r["base_lod"] == 0]
    if flat:
        notes.append(f"At {', '.join(flat)} the base LOD is 0: the cheap renderers start at "
                     "the voxels and have nothing to refine, so they cast one ray a pixel "
                     "whatever the threshold; a larger footprint or a smaller image gives "
                     "them LODs to work with.")
    costly = [f"{r['size']}x{r['size']} ({r['error_aware']['rays_per_pixel']:.1f} rays/px)"
              for r in rows
              if r["error_aware"]["rays"] > r["reference"]["rays"]]
    if costly:
        notes.append(f"Error-aware casts more rays than the 16-ray reference at "
                     f"{', '.join(costly)}: a pixel refined twice casts 1 + 4 + 16 rays, "
                     "the coarser ones discarded.")
    if len({r["base_lod"] for r in rows}) > 1 and _against_the_trend(rows):
        notes.append("The base LOD changes with the size (the rule above), so a smaller "
                     "image may start coarser and refine more: its rays per pixel and its "
                     "quality need not follow the larger sizes'.")
    return ["## Notes", "", *(f"- {note}" for note in notes)] if notes else []


def _against_the_trend(rows) -> bool:
    """Whether a smaller image cost error-aware more rays or scored higher than a larger
    one (an image equal to the reference, PSNR null, as the highest score)."""
    def psnr(row):
        value = row["error_aware"].get("psnr")
        return math.inf if value is None else value

    ordered = sorted(rows, key=lambda r: r["size"])
    return any(small["error_aware"]["rays"] > large["error_aware"]["rays"]
               or psnr(small) > psnr(large)
               for k, small in enumerate(ordered) for large in ordered[k + 1:])


def _figure(report):
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    rows = sorted(report["rows"], key=lambda r: r["size"])
    x = [r["size"] for r in rows]
    fig, axes = plt.subplots(1, len(PANELS), figsize=(17, 3.4))
    for ax, (key, label, log) in zip(axes, PANELS, strict=True):
        names = RENDERERS if key in ("rays", "steps") else RENDERERS[1:]
        for name in names:
            style = {"marker": "o", "color": _COLOURS[name], "label": name.replace("_", "-")}
            if key == "psnr":
                plot_psnr(ax, x, [r[name][key] for r in rows], **style)
            else:
                ax.plot(x, [plot_value(r[name][key]) for r in rows], **style)
        if key == "psnr":
            finish_psnr_axis(ax)
        ax.set_xscale("log", base=2)
        ax.set_xticks(x, [str(s) for s in x])
        ax.minorticks_off()
        if log:
            ax.set_yscale("log")
        ax.set_xlabel("image side (pixels)")
        ax.set_title(label)
        ax.legend(fontsize=7)
    fig.suptitle(f"resolution — {scene_title(report['scene'])}, threshold {report['threshold']}")
    fig.tight_layout()
    return fig
