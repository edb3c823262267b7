"""The lighting study of EA thesis §5.3 (Tables 5.18–5.26, figs 5.7–5.10), plus §6.1.

Per colour channel (albedo and each baked time of day) the 4×4 reference, the adaptive
renderer and the error-aware renderer render one view; the lighting-aware error-aware
renderer (bright-flag colour error, §6.1) joins as a third contender. The report gives the
thesis's three tables per scene — ray and traversal-step counts, average image luminance,
PSNR/RMSE/SSIM — and a contact sheet in the form of figs 5.7–5.10. Every render is cached,
so an interrupted study resumes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD
from voxfield.errors import VoxfieldError
from voxfield.lighting.sun import TIMES_OF_DAY
from voxfield.progress import progress_bar
from voxfield.render.camera import Camera
from voxfield.render.error_aware import DEFAULT_BRIGHT_RATIO
from voxfield.render.registry import render, renderer_options
from voxfield.studies.figures import Panel, contact_sheet, finest_lod_map, refinement_map
from voxfield.studies.report import (
    StudyFolder,
    costs_and_quality,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_title,
)
from voxfield.svo.octree import Octree

#: Contenders, as named in the tables: adaptive (A), error-aware (EA), lighting-aware (EA-L).
CONTENDERS = (("adaptive", "A"), ("error_aware", "EA"), ("lighting_aware", "EA-L"))


def image_luminance(image: np.ndarray) -> float:
    """Mean Rec. 709 luminance of a linear RGB image (thesis Table 5.19)."""
    return float(np.mean(image @ np.array([0.2126, 0.7152, 0.0722])))


def lighting_channels(octree: Octree) -> list[str]:
    """The colour channels worth studying: albedo first, then every baked channel, the named
    times of day in the day's order (tables and sheets read morning to evening), any other
    sun after them by name."""
    day = list(TIMES_OF_DAY)
    baked = sorted((k for k in octree.attributes if k not in ("color", "emission")),
                   key=lambda k: (day.index(k) if k in day else len(day), k))
    return ["albedo", *baked]


def run_lighting_study(
    octree: Octree, camera: Camera, out_dir: str | Path, *, channels: list[str] | None = None,
    threshold: float = THESIS_THRESHOLD, decay: float = THESIS_DECAY, base_lod: int | None = 2,
    bright_ratio: float = DEFAULT_BRIGHT_RATIO, seed: int = 0, scene_name: str = "scene",
    progress: bool = False, fresh: bool = False, scheduler=None,
) -> dict:
    """Render and measure every channel (resumable); write results.json, results.md,
    lighting.png (the tables as bars) and contact_sheet.png into ``out_dir``. The renders are
    independent items: with a ``scheduler`` (``voxfield.scaleout``) they run as tasks."""
    chosen = channels is not None
    channels = list(channels if chosen else lighting_channels(octree))
    for name in channels:
        octree.channel(name)  # unknown channels fail before any work
    if len(set(channels)) != len(channels):
        raise VoxfieldError(f"a channel is named twice in {','.join(channels)}")
    if len(channels) < 2:
        raise VoxfieldError(
            "the lighting study compares channels: name at least two (albedo and a baked "
            "one)" if chosen else "the octree has no baked lighting channels; bake some with "
            "`voxfield light SCENE` and study the octree file it writes")
    folder = StudyFolder(out_dir, study="study lighting", fresh=fresh, scheduler=scheduler)
    settings = {"threshold": threshold, "decay": decay, "base_lod": base_lod}
    # Row → (registered renderer, its options); the thesis's 4×4 reference is the default.
    rows_drawn = {
        "reference": ("reference", renderer_options("reference")),
        "adaptive": ("adaptive", renderer_options("adaptive", base_lod=base_lod)),
        "error_aware": ("error-aware", renderer_options("error-aware", **settings)),
        "lighting_aware": ("error-aware", renderer_options(
            "error-aware", lighting_aware=True, bright_ratio=bright_ratio, **settings)),
    }
    renders = {row: (lambda o, c, name=name, options=options: render(
        o, camera, name, options, seed=seed, channel=c))
        for row, (name, options) in rows_drawn.items()}
    views = {channel: {"scene": scene_name, "fingerprint": octree.fingerprint(channel),
                       "camera": camera.params.tolist(), "size": camera.width, "seed": seed,
                       "channel": channel} for channel in channels}
    specs = []
    for channel in channels:
        for name, draw in renders.items():
            params = ({**views[channel]} if name in ("reference", "adaptive")
                      else {**views[channel], **settings})
            if name == "lighting_aware":
                params["bright_ratio"] = bright_ratio
            if name == "adaptive":
                params["base_lod"] = base_lod
            # The octree comes from ``shared`` (scattered to a cluster once).
            specs.append((f"{name}-{channel}", params,
                          lambda shared, r=draw, c=channel: r(shared, c)))
    with progress_bar(total=len(specs), desc="lighting", unit="render",
                      enabled=progress) as bar:
        rendered = iter(folder.render_batch(specs, shared=octree, bar=bar))
    rows, sheet = [], []
    for channel in channels:
        results = {name: next(rendered) for name in renders}
        reference = results["reference"]
        row = {"channel": channel, "luminance": image_luminance(reference.image)}
        for name, _ in CONTENDERS:
            row[name] = folder.value_item(
                f"quality_{name}-{channel}", {**views[channel], **settings, "renderer": name,
                                              "bright_ratio": bright_ratio},
                lambda r=results[name], ref=reference: costs_and_quality(ref, r))
        rows.append(row)
        sheet.append((channel, results))
    report = {
        "study": "lighting", "scene": scene_name, "width": camera.width,
        "height": camera.height, "settings": {**settings, "bright_ratio": bright_ratio,
                                              "seed": seed},
        "rows": rows, "metrics_on": "linear RGB in [0, 1]",
    }
    folder.write_json("results.json", report)
    folder.write_text("results.md", results_markdown(report))
    folder.write_figure("lighting.png", _figure(report))
    folder.write_figure("contact_sheet.png", _sheet(sheet, base_lod, scene_name),
                        dpi=int(min(160, max(90, camera.width / 4))))
    folder.publish_report()
    return report


def results_markdown(report: dict) -> str:
    s = report["settings"]
    rows = report["rows"]
    names = [label for _, label in CONTENDERS]
    cost = [[r["channel"], *(fmt(r[key]["rays"]) for key, _ in CONTENDERS),
             *(fmt(r[key]["steps"]) for key, _ in CONTENDERS)] for r in rows]
    quality = [[r["channel"], *(fmt_psnr(r[key], ".3f") for key, _ in CONTENDERS),
                *(fmt(r[key]["rmse"], ".5f") for key, _ in CONTENDERS),
                *(fmt(r[key]["ssim"], ".4f") for key, _ in CONTENDERS)] for r in rows]
    luminance = [[r["channel"], fmt(r["luminance"], ".4f")] for r in rows]
    return "\n".join([
        f"# Lighting — {report['scene']}, {report['width']}×{report['height']}",
        "",
        f"Threshold {s['threshold']}, decay {s['decay']}, base LOD {s['base_lod']}, seed "
        f"{s['seed']}. A: adaptive; EA: error-aware (geometric error); EA-L: error-aware with "
        f"the lighting-aware colour error (children brighter than {1 + s['bright_ratio']:g}× "
        "their parent flagged bright, EA §6.1). Rays count every ray cast. Metrics against "
        "the 4×4 reference of the same channel, on linear RGB in [0, 1].",
        "",
        "## Ray and traversal step counts (EA Tables 5.18, 5.21, 5.23, 5.25)",
        "",
        markdown_table(["channel", *(f"rays ({n})" for n in names),
                        *(f"steps ({n})" for n in names)], cost),
        "## Average image luminance of the reference (EA Table 5.19)",
        "",
        markdown_table(["channel", "luminance"], luminance),
        "## Image similarity to the reference (EA Tables 5.20, 5.22, 5.24, 5.26)",
        "",
        markdown_table(["channel", *(f"PSNR ({n})" for n in names),
                        *(f"RMSE ({n})" for n in names), *(f"SSIM ({n})" for n in names)],
                       quality),
        "## Files",
        "",
        "- `lighting.png`: steps and PSNR per channel for the three contenders",
        "- `contact_sheet.png`: per channel the reference, the EA and EA-L images, the "
        "adaptive rays per pixel and the EA finest LOD (EA figs 5.7–5.10)",
        "",
    ])


def _figure(report: dict):
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    rows = report["rows"]
    x = np.arange(len(rows))
    width = 0.27
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.6))
    # A PSNR of null is an image equal to the reference: drawn as a hatched bar above every
    # measured one and marked ∞ (left out, it read as the worst score, not the best).
    measured = [r[name]["psnr"] for r in rows for name, _ in CONTENDERS
                if r[name]["psnr"] is not None]
    infinite_bar = 1.1 * max(measured, default=50.0)
    for ax, (key, title) in zip(axes, (("rays", "rays cast"), ("steps", "traversal steps"),
                                       ("psnr", "PSNR (dB)")), strict=True):
        for i, (name, label) in enumerate(CONTENDERS):
            equal = [key == "psnr" and r[name][key] is None for r in rows]
            values = [infinite_bar if eq else r[name][key] for r, eq in zip(rows, equal,
                                                                             strict=True)]
            bars = ax.bar(x + (i - 1) * width, values, width, label=label if key == "rays"
                          else None)
            for bar, eq in zip(bars, equal, strict=True):
                if eq:
                    bar.set_hatch("//")
                    ax.annotate("∞", (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                                ha="center", va="bottom", fontsize=9)
        if key == "psnr":
            ax.set_ylim(top=1.12 * infinite_bar)  # room for the ∞ marks
        ax.set_xticks(x, [r["channel"] for r in rows], rotation=20)
        ax.set_title(title)
    # one legend above the panels, where it hides no bar
    fig.legend(loc="upper right", fontsize=8, ncols=len(CONTENDERS))
    fig.suptitle(f"Lighting — {scene_title(report['scene'])} (∞: equal to the reference)", x=0.3)
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    return fig


def _sheet(sheet: list, base_lod: int | None, scene_name: str):
    """Per channel: the reference, both error-aware renders (EA and the lighting-aware EA-L,
    the study's subject), where the adaptive renderer refined and the finest LOD EA used."""
    cells: list = []
    for channel, results in sheet:
        cells += [
            Panel(f"{channel}: reference", results["reference"].image),
            Panel(f"{channel}: error-aware (EA)", results["error_aware"].image),
            Panel(f"{channel}: lighting-aware (EA-L)", results["lighting_aware"].image),
            Panel(f"{channel}: adaptive rays/px (black bg, 1, 4, 16)",
                  refinement_map(results["adaptive"]), linear_rgb=False),
            Panel(f"{channel}: EA finest LOD (white = LOD 0)",
                  finest_lod_map(results["error_aware"], base_lod or 0), linear_rgb=False),
        ]
    return contact_sheet(cells, columns=5, title=f"{scene_title(scene_name)}: lighting")
