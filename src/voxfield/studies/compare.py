"""The renderer comparison of EA thesis §5.2: reference, adaptive and error-aware on one view.

Renders the three, measures the two cheap ones against the reference (PSNR, RMSE, SSIM on
linear RGB; FLIP on sRGB) and counts their cost (rays as the thesis counts them, traversal
steps), then writes the study folder: ``results.json``, ``results.md`` (Tables 5.2–5.5),
the images and cost maps of figs 5.1–5.3, and ``contact_sheet.png``. Renders and metrics are
cached per item, so an interrupted or repeated run only does what is missing.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD
from voxfield.errors import VoxfieldError
from voxfield.fingerprint import array_fingerprint
from voxfield.metrics import MISSED, compare_images, cost_summary, flip_available
from voxfield.progress import progress_bar
from voxfield.render.adaptive import AdaptiveOptions
from voxfield.render.camera import Camera
from voxfield.render.counter_maps import steps_heatmap
from voxfield.render.error_aware import ErrorAwareOptions
from voxfield.render.primary import ReferenceOptions
from voxfield.render.registry import render
from voxfield.render.result import RenderResult
from voxfield.studies.figures import (
    Panel,
    contact_sheet,
    finest_lod_map,
    ray_count_map,
    refinement_map,
    variance_map,
)
from voxfield.studies.report import (
    StudyFolder,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_record_title,
)
from voxfield.svo.octree import Octree

#: The thesis's reference: 4×4 CMJ rays per pixel, all at LOD 0 (§5.1.1).
RENDERERS = ("reference", "adaptive", "error-aware")
#: The optional fourth row: error-aware with parent-ray reuse (EA §6.2).
REUSE_ROW = "error-aware+reuse"
METRIC_NOTE = ("PSNR, RMSE and SSIM on linear RGB in [0, 1] against the reference; "
               "FLIP (LDR) on sRGB-encoded copies, 0 = identical.")
RAY_NOTE = ("Rays are counted as in the thesis: only rays that hit a voxel (discarded "
            "error-aware rays included); rays/pixel is over the pixels that show geometry.")


def run_compare(
    octree: Octree, camera: Camera, out_dir: str | Path, *, threshold: float = THESIS_THRESHOLD,
    decay: float = THESIS_DECAY, base_lod: int | None = 2, seed: int = 0, channel: str = "albedo",
    reuse_parent: bool = False, camera_label: str = "", threads: int | None = None,
    fresh: bool = False, progress: bool = False, scheduler=None, scene_name: str | None = None,
) -> dict:
    """Render, measure and write the comparison into ``out_dir``; returns the results as in
    ``results.json`` plus ``written`` (paths) and ``computed`` / ``reused`` (item names).

    ``scene_name`` is the description the scene was opened from (a file, ``builtin:…``),
    which the record keeps and the titles name (``scene_record_title``).
    ``base_lod=None`` lets both cheap renderers pick the first ray's LOD from the pixel cone.
    ``reuse_parent`` adds a row for the error-aware renderer with parent-ray reuse. With a
    ``scheduler`` (``voxfield.scaleout``) the renders run as tasks, with the same results.
    """
    if base_lod is not None and not 0 <= base_lod <= octree.depth:
        raise VoxfieldError(f"base LOD must be between 0 and {octree.depth}, got {base_lod}")
    folder = StudyFolder(out_dir, study="compare", fresh=fresh, scheduler=scheduler)
    scene = {"name": octree.name, "depth": octree.depth, "voxels": octree.voxel_count,
             "fingerprint": octree.fingerprint(channel),
             **({"description": scene_name} if scene_name else {})}
    common = {"scene": scene["fingerprint"], "camera": array_fingerprint(camera.params),
              "width": camera.width, "height": camera.height, "seed": seed, "channel": channel}
    options = {"seed": seed, "channel": channel, "threads": threads, "progress": progress}
    # The renderers' defaults are the thesis's fair setup: 4×4 reference rays, one adaptive
    # pass (§5.1.2), at most two error-aware refinements (≤ 21 rays a pixel, §5.1.3).
    settings = {
        "reference": {"side": ReferenceOptions.side},
        "adaptive": {"base_lod": base_lod, "iterations": AdaptiveOptions.iterations},
        "error-aware": {"threshold": threshold, "decay": decay, "base_lod": base_lod,
                        "max_refinements": ErrorAwareOptions.max_refinements},
    }
    names = list(RENDERERS)
    if reuse_parent:
        settings[REUSE_ROW] = {**settings["error-aware"], "reuse_parent": True}
        names.append(REUSE_ROW)
    keys = {name: {**common, "renderer": name, **settings[name]} for name in names}
    if scheduler not in (None, "serial"):
        options["progress"] = False  # tasks finish in any order: one bar for the batch
        options["threads"] = None  # the scheduler shares the cores out among its tasks
    # Each render reads the octree from ``shared`` (scattered to a cluster once).
    specs = [(_slug(name), keys[name],
              lambda shared, name=name: _warm_render(shared, camera, _renderer_of(name),
                                                     settings[name], options))
             for name in names]
    with progress_bar(total=len(specs), desc="compare", unit="render",
                      enabled=progress and not options["progress"]) as bar:
        rendered = folder.render_batch(specs, shared=octree, bar=bar)
    results: dict[str, RenderResult] = dict(zip(names, rendered, strict=True))
    reference = results["reference"]
    rows = []
    for name, result in results.items():
        quality = None
        if name != "reference":
            quality = folder.value_item(
                f"quality_{_slug(name)}",
                {"reference": keys["reference"], "test": keys[name], "flip": flip_available()},
                lambda result=result: compare_images(reference.image, result.image),
            )
        rows.append({"renderer": name, "cost": cost_summary(result), "quality": quality})
    images = _write_images(folder, results, base_lod)
    report = {
        "study": "compare",
        "scene": scene,
        "camera": {"label": camera_label, "width": camera.width, "height": camera.height},
        "settings": settings,
        "notes": [METRIC_NOTE, RAY_NOTE],
        "rows": rows,
        "images": images,
        "comparisons": comparisons(rows, images),
    }
    written = [folder.path(p) for p in images.values()]
    # About one screen pixel per image pixel up to 512², so the sheet shows the real detail.
    dpi = int(min(160, max(100, camera.width / 3.6)))
    written.append(folder.write_figure("contact_sheet.png", _sheet(report, results, base_lod),
                                       dpi=dpi))
    written.append(folder.write_json("results.json", report))
    written.append(folder.write_text("results.md", results_markdown(report)))
    written.append(folder.publish_report())
    return {**report, "folder": str(folder.root), "written": [str(p) for p in written],
            "computed": folder.computed, "reused": folder.reused}


def _renderer_of(row: str) -> str:
    """The registered renderer drawing a row (the reuse row is error-aware with an option)."""
    return "error-aware" if row == REUSE_ROW else row


def _slug(name: str) -> str:
    return name.replace("-", "_").replace("+", "_")


def _lod(base_lod: int | None) -> str:
    return "cone" if base_lod is None else str(base_lod)


def _write_images(folder: StudyFolder, results: dict[str, RenderResult],
                  base_lod: int | None) -> dict:
    """The three images (sRGB) and the thesis's cost maps (grey levels); returns name → file."""
    images = {}
    for name, result in results.items():
        images[name] = folder.write_png(f"{_slug(name)}.png", result.image).name
    adaptive, error_aware = results["adaptive"], results["error-aware"]
    maps = {
        "adaptive_rays": lambda: refinement_map(adaptive),
        "adaptive_variance": lambda: variance_map(adaptive),
        "error_aware_rays": lambda: ray_count_map(error_aware),
        "error_aware_lod": lambda: finest_lod_map(error_aware, base_lod or 0),
    }
    for name, make in maps.items():
        try:
            grey = make()
        except VoxfieldError:
            continue  # a renderer without that map: leave the picture out
        images[name] = folder.write_png(f"{name}.png", grey, encode_srgb=False).name
    for name, result in results.items():
        images[f"{_slug(name)}_steps"] = folder.write_png(
            f"{_slug(name)}_steps.png", steps_heatmap(result), encode_srgb=False).name
    return images


#: Cost maps shown beside each image in the HTML report: label → image key suffix.
_REPORT_MAPS = {"traversal steps (magma, 99th percentile = white)": "steps",
                "rays cast per pixel": "rays", "finest LOD (white = LOD 0)": "lod",
                "normalised variance": "variance"}


def comparisons(rows: list[dict], images: dict) -> list[dict]:
    """Each renderer's image against the reference, with its cost maps and a one-line
    summary, for ``studies.html_report``."""
    out = []
    for row in rows:
        name = row["renderer"]
        if name == "reference":
            continue
        slug = _slug(name)
        cost, quality = row["cost"], row["quality"] or {}
        summary = (f"{cost['rays_per_pixel']:.2f} rays/px, {cost['steps_per_ray']:.2f} "
                   f"steps/ray, PSNR {fmt_psnr(quality, '.2f')} dB, SSIM "
                   f"{fmt(quality.get('ssim'), '.3f')}")
        maps = {label: images[f"{slug}_{key}"] for label, key in _REPORT_MAPS.items()
                if f"{slug}_{key}" in images}
        out.append({"name": name, "image": images[name], "reference": images["reference"],
                    "reference_name": "reference", "summary": summary,
                    "maps": maps})
    return out


def _warm_render(octree: Octree, camera: Camera, renderer: str, settings: dict,
                 options: dict) -> RenderResult:
    """``render``, after the same render on a few pixels: a first call's seconds held the
    loading (or compiling) of its kernels (the 16-ray reference "took" 0.03 s, adaptive
    0.15), and where it runs (a thread, a task's process) is where they must be warm."""
    tiny = dataclasses.replace(camera, width=4, height=4)
    render(octree, tiny, renderer, **settings, **{**options, "progress": False})
    return render(octree, camera, renderer, **settings, **options)


def _sheet(report: dict, results: dict[str, RenderResult], base_lod: int | None):
    """Images on top with their cost and quality, the cost maps below, a summary at the end."""
    rows = {row["renderer"]: row for row in report["rows"]}
    cells: list = []
    for name, result in results.items():
        cost, quality = rows[name]["cost"], rows[name]["quality"]
        title = f"{name}: {cost['rays_per_pixel']:.2f} rays/px"
        if quality is not None:
            title += f", PSNR {fmt_psnr(quality, '.1f')} dB, SSIM {fmt(quality['ssim'], '.3f')}"
        cells.append(Panel(title, result.image))
    cells.append(_summary_text(report))
    adaptive, error_aware = results["adaptive"], results["error-aware"]
    for title, make in (
        ("adaptive: normalised variance", lambda: variance_map(adaptive)),
        ("adaptive: rays/px (black bg, 1, 4, 16)", lambda: refinement_map(adaptive)),
        ("error-aware: rays/px (black 1 → white 21)", lambda: ray_count_map(error_aware)),
        ("error-aware: finest LOD (white = LOD 0)",
         lambda: finest_lod_map(error_aware, base_lod or 0)),
    ):
        try:
            cells.append(Panel(title, make(), linear_rgb=False))
        except VoxfieldError:
            continue
    return contact_sheet(cells, columns=4, title=_sheet_title(report))


def _sheet_title(report: dict) -> str:
    camera = report["camera"]
    view = f", camera {camera['label']}" if camera["label"] else ""
    return f"{scene_record_title(report['scene'])}: {camera['width']}×{camera['height']}{view}"


def _summary_text(report: dict) -> str:
    """The sheet's text cell: settings and the main numbers, monospaced."""
    ea = report["settings"]["error-aware"]
    lines = [
        f"threshold {ea['threshold']}, decay {ea['decay']}, base LOD {_lod(ea['base_lod'])}",
        "",
        f"{'':<18}{'rays':>10}{'r/px':>6}{'steps':>11}",
    ]
    for row in report["rows"]:
        c = row["cost"]
        lines.append(f"{row['renderer']:<18}{c['rays_hit']:>10,}{c['rays_per_pixel']:>6.2f}"
                     f"{c['traversal_steps']:>11,}")
    lines += ["", f"{'':<18}{'PSNR':>7}{'RMSE':>9}{'SSIM':>7}{'FLIP':>7}"]
    for row in report["rows"]:
        q = row["quality"]
        if q is None:
            continue
        lines.append(f"{row['renderer']:<18}{fmt_psnr(q, '.2f'):>7}{fmt(q['rmse'], '.5f'):>9}"
                     f"{fmt(q['ssim'], '.3f'):>7}{fmt(q['flip'], '.3f'):>7}")
    lines += ["", "metrics: linear RGB vs reference;", "FLIP on sRGB. Rays: hit rays only."]
    return "\n".join(lines)


def results_markdown(report: dict) -> str:
    """``results.md``: the thesis's Tables 5.2–5.5 for this scene and view."""
    scene, camera, settings = report["scene"], report["camera"], report["settings"]
    ea, ad = settings["error-aware"], settings["adaptive"]
    view = f", camera `{camera['label']}`" if camera["label"] else ""
    rows = report["rows"]
    out = [
        f"# Renderer comparison: {scene_record_title(scene)}\n",
        f"{camera['width']}×{camera['height']}{view}; {scene['voxels']:,} voxels, "
        f"octree depth {scene['depth']}.\n",
        f"- reference: {settings['reference']['side']}×{settings['reference']['side']} CMJ rays "
        "per pixel at LOD 0 (EA §5.1.1)",
        f"- adaptive: 1 ray per pixel at LOD {_lod(ad['base_lod'])}, {ad['iterations']} refinement "
        "pass of 2×2 or 4×4 rays at LOD 0 by normalised 3×3 luminance variance (EA §5.1.2)",
        f"- error-aware: threshold {ea['threshold']}, decay {ea['decay']}, base LOD "
        f"{_lod(ea['base_lod'])}, at most {ea['max_refinements']} refinements (EA §5.1.3–5.1.4)\n",
        *([f"- {REUSE_ROW}: the same, a refined ray continued one LOD finer as one of its "
           "four sub-rays, so 3 new rays per refinement (EA §6.2)\n"]
          if REUSE_ROW in settings else []),
        *[f"{note}\n" for note in report["notes"]],
        "## Cost and quality (EA Tables 5.2 and 5.5)\n",
        markdown_table(
            ["renderer", "rays", "rays / pixel", "traversal steps", "steps / ray", "PSNR (dB)",
             "RMSE", "SSIM", "FLIP", "rays cast", "seconds"],
            [_main_row(row) for row in rows],
        ),
        "## Pixels by rays per pixel (EA Table 5.3)\n",
        "The thesis tabulates the adaptive renderer so (a pixel refined to 2×2 is a 4-ray "
        "pixel). An error-aware pixel casts 1, 5 (1 + 4), 9, 13, 17 or 21 rays, its coarser "
        "rays discarded but counted, so its refined pixels fall under \"other\"; the thesis "
        "tabulates it by finest LOD instead (Table 5.4, next).\n",
        _histogram_table(rows, "ray_histogram", {"1": "1 ray", "4": "4 rays", "16": "16 rays"}),
        "## Pixels by finest LOD used (EA Table 5.4)\n",
        _histogram_table(rows, "lod_histogram", {}),
        "## Pixels by rays cast, discarded rays included (EA fig. 5.2a)\n",
        _histogram_table(rows, "ray_distribution", {}, skip_empty=True),
        "## Images\n",
        *[f"- `{file}`" for file in report["images"].values()],
        "- `contact_sheet.png`: the renders with their cost and quality, the adaptive "
        "renderer's variance and rays, the error-aware renderer's rays and finest LOD, and a "
        "summary (the step maps are the files above)\n",
    ]
    return "\n".join(out)


def _main_row(row: dict) -> list[str]:
    c, q = row["cost"], row["quality"] or {}
    return [
        row["renderer"], fmt(c["rays_hit"]), fmt(c["rays_per_pixel"], ".3f"),
        fmt(c["traversal_steps"]), fmt(c["steps_per_ray"], ".2f"),
        fmt_psnr(q, ".3f"), fmt(q.get("rmse"), ".5f"),
        fmt(q.get("ssim"), ".3f"), fmt(q.get("flip"), ".4f"), fmt(c["rays"]),
        fmt(c["seconds"], ".2f"),
    ]


def _bucket_order(column: str) -> tuple:
    """Didn't hit first, LODs coarsest first, ray counts ascending, anything else last."""
    if column == MISSED:
        return (0, 0)
    if column.startswith("LOD ") and column[4:].isdigit():
        return (1, -int(column[4:]))
    if column.isdigit():
        return (1, int(column))
    return (2, 0)


def _histogram_table(rows: list[dict], key: str, names: dict[str, str], *,
                     skip_empty: bool = False) -> str:
    """One row per renderer, one column per bucket (union over renderers, order kept)."""
    columns: list[str] = []
    for row in rows:
        columns += [c for c in row["cost"][key] if c not in columns]
    columns.sort(key=_bucket_order)
    if skip_empty:
        columns = [c for c in columns
                   if c == MISSED or any(row["cost"][key].get(c, 0) for row in rows)]
    body = [[row["renderer"], *(fmt(row["cost"][key].get(c, 0)) for c in columns)]
            for row in rows]
    return markdown_table(["renderer", *(names.get(c, c) for c in columns)], body)
