"""The EA thesis's shadow-ray test (§3.2.2, figs 3.4–3.6) as a study.

Direct light with importance-sampled shadow rays, rendered four times from one view: the
reference (many light samples, shadow rays on the voxels), the same at the cheap renders' sample
count (the Monte Carlo noise floor), the distance-LOD baseline (fig. 3.5b) and the error-aware
shadow rays (fig. 3.5c). Writes the images, the LOD-used maps of the view and of a top-down view
of the whole scene (fig. 3.6), the light on the floor in front of the grid along the beam,
``results.json``, ``results.md`` and ``contact_sheet.png``. Renders are cached in the output
folder, so a re-run resumes.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD, load_error_table
from voxfield.errors import VoxfieldError
from voxfield.fingerprint import array_fingerprint
from voxfield.metrics import psnr
from voxfield.progress import progress_bar
from voxfield.render.camera import top_down_camera
from voxfield.render.direct_light import check_emitters, light_on_surface, render_direct_light
from voxfield.scene.shadow_box import shadow_box_layout
from voxfield.scene.voxel_scene import linear_to_srgb
from voxfield.studies.report import (
    StudyFolder,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_record_title,
)

#: Bump when the shadow kernels' results change, so cached renders are not reused.
STUDY_VERSION = 1
#: The rows of the comparison: name → shadow LOD mode.
ROWS = {"reference": "reference", "full-res": "reference", "distance": "distance",
        "error-aware": "error-aware"}
#: Light samples per pixel of the top-down LOD maps (only the LOD is looked at there).
TOP_VIEW_SAMPLES = 4
#: Under this share of pixels that show light (not black in the reference's PNG), the view
#: sees little of what the lights reach: its PSNRs, high over the black pixels every renderer
#: agrees on, say little.
DARK_VIEW_SHARE = 0.05
#: Depth (voxels) of the floor strip in front of the grid where the light is measured.
BEAM_LENGTH = 64
LOD_COLORMAP = "magma"
NO_RAY_GREY = 0.85
METRIC_NOTE = ("PSNR on linear RGB in [0, 1] (images clamped to it) against the reference; "
               "floor light is the radiance a white floor reflects, averaged over the strip in "
               "front of the grid, as wide as the box.")


def run_shadow_study(
    octree, camera, out_dir: str | Path, *, light_samples: int = 16,
    reference_samples: int = 256, floor_samples: int = 64, lod_distance: float = 16.0,
    threshold: float = THESIS_THRESHOLD, decay: float = THESIS_DECAY,
    max_refinements: int | None = None,
    encoding: str | None = None, seed: int = 0, camera_label: str = "",
    threads: int | None = None, fresh: bool = False, progress: bool = False, scheduler=None,
    scene_name: str | None = None,
) -> dict:
    """Render, measure and write the study into ``out_dir``; returns ``results.json``'s
    content plus ``folder``, ``written``, ``computed`` and ``reused``. The five renders are
    independent items: with a ``scheduler`` (``voxfield.scaleout``) they run as tasks.
    ``scene_name``: the description the scene was opened from, for the record and titles."""
    check_emitters(octree)  # a scene without light: what it needs, before a key reads it
    table = load_error_table()
    folder = StudyFolder(out_dir, study="shadows", fresh=fresh, scheduler=scheduler)
    scheduled = scheduler not in (None, "serial")
    shadow = {"lod_distance": float(lod_distance), "threshold": float(threshold),
              "decay": float(decay), "max_refinements": max_refinements,
              "encoding": encoding or table.default_encoding}
    scene_key = array_fingerprint(octree.level_offsets, octree.child_mask,
                                  octree.channel("albedo"), octree.channel("emission"))

    def key(mode: str) -> dict:
        """What a render or measurement with shadow LOD ``mode`` depends on (cache key)."""
        used = {"reference": (), "distance": ("lod_distance",), "error-aware": tuple(shadow)}
        return {"study": STUDY_VERSION, "scene": scene_key, "seed": seed, "mode": mode,
                **{k: shadow[k] for k in used[mode]}}

    def render(name: str, mode: str, cam, samples: int):
        """One render as a batch item; the octree and error table come from ``shared``."""
        params = {**key(mode), "samples": samples,
                  "camera": array_fingerprint(cam.params), "size": [cam.width, cam.height]}
        return name, params, lambda shared: render_direct_light(
            shared[0], cam, shadow_lod=mode, light_samples=samples, lod_distance=lod_distance,
            threshold=threshold, decay=decay, max_refinements=max_refinements, table=shared[1],
            encoding=encoding, seed=seed, threads=None if scheduled else threads,
            progress=progress and not scheduled)

    lo, hi = octree.voxel_bounds
    top = top_down_camera(lo, hi, size=camera.width)
    specs = [render(name, mode, camera,
                    reference_samples if name == "reference" else light_samples)
             for name, mode in ROWS.items()]
    specs += [render(f"top-{mode}", mode, top, TOP_VIEW_SAMPLES)
              for mode in ("distance", "error-aware")]
    with progress_bar(total=len(specs), desc="shadows", unit="render",
                      enabled=progress and scheduled) as bar:
        rendered = folder.render_batch(specs, shared=(octree, table), bar=bar)
    results = dict(zip(ROWS, rendered[:len(ROWS)], strict=True))
    _note_a_dark_view(results["reference"])
    top_maps = dict(zip(("distance", "error-aware"), rendered[len(ROWS):], strict=True))
    beam = _measure_beam(folder, octree, key, floor_samples=floor_samples,
                         lod_distance=lod_distance, threshold=threshold, decay=decay,
                         max_refinements=max_refinements, table=table, encoding=encoding,
                         seed=seed, threads=threads)

    rows = []
    for name, result in results.items():
        summary = result.summary()
        shadow_steps = int(result.maps["shadow_steps"].sum())
        shadow_rays = int(result.maps["shadow_rays"].sum())
        traversals = int(result.maps["shadow_traversals"].sum())
        mode = ROWS[name]
        row = {
            "renderer": name, "shadow_lod": mode,
            "light_samples": result.params.get("light_samples"),
            "shadow_rays": shadow_rays, "shadow_traversals": traversals,
            "shadow_steps": shadow_steps,
            "shadow_steps_per_ray": shadow_steps / shadow_rays if shadow_rays else 0.0,
            "shadow_refinements": int(result.maps["shadow_refinements"].sum()),
            "traversal_steps": summary["traversal_steps"], "seconds": result.seconds,
        }
        if name != "reference":  # the reference's own row has no PSNR, not an infinite one
            row["psnr"] = psnr(results["reference"].image, result.image)
        if beam is not None:
            row["floor_light"] = beam["floor_light"][mode]
            row["far_floor_light"] = beam["far_floor_light"][mode]
        rows.append(row)
    report = {
        "scene": {"name": octree.name, "depth": octree.depth, "voxels": octree.voxel_count,
                  **({"description": scene_name} if scene_name else {})},
        "camera": {"label": camera_label, "width": camera.width, "height": camera.height},
        "settings": {**shadow, "light_samples": light_samples,
                     "reference_samples": reference_samples, "floor_samples": floor_samples,
                     "seed": seed},
        "rows": rows, "beam": beam, "note": METRIC_NOTE,
        "comparisons": [
            {"name": name, "image": f"{_slug(name)}.png", "reference": "reference.png",
             "reference_name": "reference",
             "maps": {"LOD used by shadow rays": f"lod_{_slug(name)}.png",
                      "LOD used, top view of the whole scene": f"lod_top_{_slug(name)}.png"}}
            for name in ("distance", "error-aware")],
    }
    written = _write_pictures(folder, results, top_maps, beam, octree.depth, report)
    written.append(folder.write_json("results.json", report))
    written.append(folder.write_text("results.md", results_markdown(report)))
    written.append(folder.publish_report())
    return {**report, "folder": str(folder.root), "written": [str(p) for p in written],
            "computed": folder.computed, "reused": folder.reused}


def _note_a_dark_view(reference) -> None:
    """Say so where the view sees almost nothing the lights reach: the study's default view
    is made for the shadow box, and another scene's lights may shine elsewhere. A pixel
    counts as lit where it shows light and cast shadow rays: an emitter seen head-on shows
    light but casts none (the Cornell box's lamp through its roof, every row at PSNR ∞)."""
    image = reference.image
    shown = linear_to_srgb(np.clip(image, 0.0, 1.0)) >= 0.5 / 255.0  # not black in a PNG
    lit = float(np.mean(np.any(shown, axis=-1) & (reference.maps["shadow_rays"] > 0)))
    if lit < DARK_VIEW_SHARE:
        warnings.warn(f"{100 * lit:.1f} % of the reference's pixels show a lit surface: the view "
                      "sees little of what the lights reach, so its PSNRs (high over the "
                      "black pixels every renderer agrees on) say little of the shadows; a "
                      "view of the lit part (--camera, --eye/--target) measures them",
                      UserWarning, stacklevel=3)


def _measure_beam(folder, octree, key, *, floor_samples: int, **options) -> dict | None:
    """Light on the floor strip in front of the grid, per shadow LOD mode: the mean over the
    strip, over its far part (from twice the LOD distance on, where the baseline samples LOD 1
    or coarser) and the profile along the beam. None for scenes other than the shadow box."""
    if octree.name != "shadowbox":
        return None
    lo, hi = octree.voxel_bounds
    try:
        layout = shadow_box_layout(int(hi[0] - lo[0]))
    except VoxfieldError:
        return None
    (x0, x1), (z0, z1) = layout.behind_grid(BEAM_LENGTH)
    xs = np.arange(x0, x1) + 0.5
    zs = np.arange(z0, z1) + 0.5
    gx, gz = np.meshgrid(xs, zs)
    points = np.stack([gx.ravel(), np.full(gx.size, float(layout.floor_top)), gz.ravel()], 1)
    normals = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    distance = zs - z0
    far = distance >= 2.0 * options["lod_distance"]
    beam = {"strip": {"x": [x0, x1], "z": [z0, z1], "y": layout.floor_top},
            "distance": distance, "profile": {}, "floor_light": {}, "far_floor_light": {},
            "floor_shadow_steps": {}}
    for mode in ("reference", "distance", "error-aware"):
        def measure(mode=mode):
            radiance, steps, _lod = light_on_surface(
                octree, points, normals, shadow_lod=mode, light_samples=floor_samples,
                **options)
            light = radiance.mean(axis=1).reshape(gx.shape)  # mean of RGB
            profile = light.mean(axis=1)
            return {"profile": profile, "mean": float(light.mean()),
                    "far": float(profile[far].mean()) if far.any() else None,
                    "steps": int(steps.sum())}
        data = folder.value_item(f"floor-{mode}", {**key(mode), "samples": floor_samples},
                                 measure)
        beam["profile"][mode] = data["profile"]
        beam["floor_light"][mode] = data["mean"]
        beam["far_floor_light"][mode] = data["far"]
        beam["floor_shadow_steps"][mode] = data["steps"]
    return beam


def lod_colors(lod: np.ndarray, max_lod: int) -> np.ndarray:
    """The LOD-used map as colours (EA fig. 3.6: darker = finer, LOD 0 black), light grey
    where no shadow ray was cast."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib import colormaps

    rgb = colormaps[LOD_COLORMAP](np.clip(lod, 0.0, max_lod) / max(max_lod, 1))[..., :3]
    rgb[lod < 0] = NO_RAY_GREY
    return rgb.astype(np.float32)


def _lod_figure(title: str, lod: np.ndarray, max_lod: int):
    """One LOD-used map with its legend."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.2, 5.2), facecolor="white", layout="constrained")
    ax = fig.subplots()
    _draw_lod(fig, ax, lod, max_lod)
    ax.set_title(title, fontsize=10)
    return fig


def _draw_lod(fig, ax, lod: np.ndarray, max_lod: int) -> None:
    """The map, a colour bar of LODs and a legend entry for pixels without shadow rays."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    ax.imshow(lod_colors(lod, max_lod), interpolation="nearest")
    ax.set_axis_off()
    mappable = ScalarMappable(norm=Normalize(0, max_lod), cmap=colormaps[LOD_COLORMAP])
    bar = fig.colorbar(mappable, ax=ax, ticks=range(max_lod + 1), fraction=0.046, pad=0.02)
    bar.set_label("LOD used by shadow rays (mean per pixel)", fontsize=8)
    ax.legend(handles=[Patch(color=(NO_RAY_GREY,) * 3, label="no shadow ray")],
              loc="upper left", fontsize=7, framealpha=0.9)


def _profile_figure(beam: dict, lod_distance: float):
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.2, 4.0), facecolor="white", layout="constrained")
    _draw_profile(fig.subplots(), beam, lod_distance)
    return fig


def _draw_profile(ax, beam: dict, lod_distance: float) -> None:
    distance = np.asarray(beam["distance"])
    for mode, style, width in (("reference", "0.55", 4.0), ("distance", "C3", 1.4),
                               ("error-aware", "C0", 1.4)):
        ax.plot(distance, np.asarray(beam["profile"][mode]), color=style, label=mode, lw=width,
                ls="--" if mode == "distance" else "-")
    ax.axvline(2 * lod_distance, color="0.6", lw=0.8, ls=":", label="far part from here")
    ax.set_xlabel("distance in front of the grid (voxels)")
    ax.set_ylabel("floor light (white floor, linear)")
    ax.set_title("light on the floor in front of the grid", fontsize=10)
    ax.legend(fontsize=8)


def _slug(name: str) -> str:
    return name.replace("-", "_")


def _write_pictures(folder, results: dict, top_maps: dict, beam: dict | None, depth: int,
                    report: dict) -> list[Path]:
    written = []
    for name, result in results.items():
        written.append(folder.write_png(f"{_slug(name)}.png", result.image))
    maps = [r.maps["shadow_lod"] for r in (*results.values(), *top_maps.values())]
    max_lod = min(depth, max(1, int(np.ceil(max(float(m.max()) for m in maps)))))
    for name in ("distance", "error-aware"):
        slug = _slug(name)
        written.append(folder.write_figure(f"lod_{slug}.png", _lod_figure(
            f"{name}: LOD used by shadow rays", results[name].maps["shadow_lod"], max_lod)))
        written.append(folder.write_figure(f"lod_top_{slug}.png", _lod_figure(
            f"{name}: LOD used, top view of the whole scene",
            top_maps[name].maps["shadow_lod"], max_lod)))
    lod_distance = report["settings"]["lod_distance"]
    if beam is not None:
        written.append(folder.write_figure("beam_profile.png", _profile_figure(beam, lod_distance)))
    written.append(folder.write_figure("contact_sheet.png", _sheet(
        results, top_maps, beam, max_lod, report)))
    return written


def _sheet(results: dict, top_maps: dict, beam: dict | None, max_lod: int, report: dict):
    """Images on top (fig. 3.5), LOD-used maps and the beam profile below (fig. 3.6)."""
    # heavy: matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure


    rows = {row["renderer"]: row for row in report["rows"]}
    fig = Figure(figsize=(19, 10), facecolor="white", layout="constrained")
    axes = fig.subplots(2, 4)
    for ax, name in zip(axes[0], ROWS, strict=True):
        ax.imshow(linear_to_srgb(results[name].image), interpolation="nearest")
        ax.set_axis_off()
        row = rows[name]
        title = f"{name} ({row['light_samples']} spp): {row['shadow_steps']:,} shadow steps"
        if "psnr" in row:
            title += f"\nPSNR {fmt_psnr(row)} dB"
        ax.set_title(title, fontsize=9)
    panels = [("distance: LOD used", results["distance"]),
              ("error-aware: LOD used", results["error-aware"]),
              ("error-aware: LOD used, top view", top_maps["error-aware"])]
    for ax, (title, result) in zip(axes[1], panels, strict=False):
        _draw_lod(fig, ax, result.maps["shadow_lod"], max_lod)
        ax.set_title(title, fontsize=9)
    if beam is not None:
        _draw_profile(axes[1, 3], beam, report["settings"]["lod_distance"])
    else:
        axes[1, 3].set_axis_off()
    scene, camera = report["scene"], report["camera"]
    fig.suptitle(f"{scene_record_title(scene)}: shadow rays by LOD, "
                 f"{camera['width']}×{camera['height']}"
                 f"{', camera ' + camera['label'] if camera['label'] else ''}", fontsize=12)
    return fig


def results_markdown(report: dict) -> str:

    s = report["settings"]
    headers = ["renderer", "light spp", "PSNR (dB)", "shadow rays", "traversals",
               "shadow steps", "steps/ray", "refinements", "seconds"]
    beam = report["beam"]
    if beam is not None:
        headers += ["floor light", "% of ref", "far floor light", "far % of ref"]
    table = []
    for row in report["rows"]:
        line = [row["renderer"], row["light_samples"], fmt_psnr(row),
                fmt(row["shadow_rays"]), fmt(row["shadow_traversals"]), fmt(row["shadow_steps"]),
                fmt(row["shadow_steps_per_ray"], ".1f"), fmt(row["shadow_refinements"]),
                fmt(row["seconds"], ".2f")]
        if beam is not None:
            line += _light_cells(row["floor_light"], beam["floor_light"]["reference"])
            line += _light_cells(row["far_floor_light"], beam["far_floor_light"]["reference"])
        table.append(line)
    scene = report["scene"]
    lines = [
        f"# Shadow rays by LOD — {scene_record_title(scene)}", "",
        f"Scene depth {scene['depth']}, {scene['voxels']:,} voxels; image "
        f"{report['camera']['width']}×{report['camera']['height']}"
        f"{', camera ' + report['camera']['label'] if report['camera']['label'] else ''}.",
        f"Distance LOD: LOD 1 from {s['lod_distance']:g} voxels along the shadow ray, LOD k "
        f"from (2^k − 1)·{s['lod_distance']:g}. Error-aware: threshold {s['threshold']:g}, "
        f"decay {s['decay']:g}, {s['encoding']} encoding, refinements "
        f"{'down to the voxels' if s['max_refinements'] is None else s['max_refinements']}.",
        "`full-res` is the reference's shadow rays at the cheap renders' sample count: its "
        "PSNR is the noise floor the LOD variants can reach.", "",
        markdown_table(headers, table), report["note"],
    ]
    if beam is not None:
        lines += ["",
                  f"Floor strip x {beam['strip']['x']}, z {beam['strip']['z']} at y "
                  f"{beam['strip']['y']}, {s['floor_samples']} light samples per point; far = "
                  f"from {2 * s['lod_distance']:g} voxels in front of the grid on.",
                  "", "![beam profile](beam_profile.png)"]
    lines += ["", "![contact sheet](contact_sheet.png)", ""]
    return "\n".join(lines)


def _light_cells(value, reference) -> list[str]:

    share = None if value is None or not reference else 100.0 * value / reference
    return [fmt(value, ".4f"), fmt(share, ".1f")]


def summary_text(report: dict) -> str:
    """The console summary: one line per renderer, then where the files went."""
    lines = [f"{'renderer':<13}{'spp':>5}{'PSNR':>8}{'shadow steps':>15}{'floor light':>13}"
             f"{'far':>9}{'seconds':>9}"]
    for row in report["rows"]:
        lines.append(
            f"{row['renderer']:<13}{row['light_samples']:>5}{fmt_psnr(row):>8}"
            f"{row['shadow_steps']:>15,}{fmt(row.get('floor_light'), '.4f'):>13}"
            f"{fmt(row.get('far_floor_light'), '.4f'):>9}{row['seconds']:>9.2f}"
        )
    lines.append(f"wrote {report['folder']}/ (report.html, results.md, contact_sheet.png)")
    return "\n".join(lines)
