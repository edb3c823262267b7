"""The adaptive renderer's one normalisation constant "across all datasets" (EA §5.1.2).

The thesis divides every scene's 3×3 luminance variance by one constant found over all the
datasets it tests, so a given variance asks for the same ray count in every scene. This
study renders each scene's first pass (one ray a pixel at the base LOD, as the adaptive
renderer does), reports each scene's largest window variance, and the constant that maps
the largest of all (or a quantile of all windows) to 1: pass it to the adaptive renderer
as ``--variance-normalisation``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from voxfield.parallel import thread_count
from voxfield.render.adaptive import (
    VARIANCE_NORMALISATION,
    first_pass_variance,
    normalisation_of,
)
from voxfield.render.camera import Camera
from voxfield.render.primary import render_lod
from voxfield.scaleout import run_tasks
from voxfield.studies.report import StudyFolder, fmt, markdown_table
from voxfield.svo.octree import Octree


def first_pass_task(settings, scene, kernel_threads: int | None = None):
    """One scene's first-pass variance (``scene`` is its octree and camera)."""
    base_lod, seed, channel = settings
    octree, camera = scene
    with thread_count(kernel_threads):
        result = render_lod(octree, camera, lod=base_lod, seed=seed, channel=channel)
    return first_pass_variance(result)


def run_normalisation_study(
    scenes: dict[str, tuple[Octree, Camera]], out_dir: str | Path, *,
    base_lod: int | None = 2, quantile: float = 1.0, seed: int = 0, channel: str = "albedo",
    scheduler=None,
) -> dict:
    """First passes of every scene, their variance statistics and the shared constant;
    results.json and results.md in ``out_dir``. Each scene's first pass is an independent
    task on ``scheduler`` (``voxfield.scaleout``; None: one after another here)."""
    folder = StudyFolder(out_dir, study="study normalisation", scheduler=scheduler)
    variances: dict = {}
    names = list(scenes)

    def land(index: int, ssd) -> None:
        variances[names[index]] = ssd

    run_tasks(first_pass_task, (base_lod, seed, channel), [scenes[n] for n in names], land,
              scheduler=scheduler or "serial", name="first-pass")
    variances = {name: variances[name] for name in names}  # scene order, not finish order
    constant = normalisation_of(list(variances.values()), quantile)
    rows = []
    for name, ssd in variances.items():
        rows.append({"scene": name, "max_ssd": float(ssd.max()) if len(ssd) else 0.0,
                     "p99_ssd": float(np.quantile(ssd, 0.99)) if len(ssd) else 0.0,
                     "refined_share": float(np.mean(ssd / constant >= 0.25)) if len(ssd)
                     else 0.0,
                     "refined_share_default": float(np.mean(ssd / VARIANCE_NORMALISATION >= 0.25))
                     if len(ssd) else 0.0})
    report = {"normalisation": constant, "quantile": quantile, "base_lod": base_lod,
              "default": VARIANCE_NORMALISATION, "scenes": rows}
    folder.write_json("results.json", report)
    folder.write_text("results.md", _markdown(report))
    folder.publish_report()
    return report


def _markdown(report: dict) -> str:
    table = markdown_table(
        ["scene", "largest 3×3 SSD", "99th percentile", "pixels refined", "refined at default"],
        [[r["scene"], fmt(r["max_ssd"], ".4f"), fmt(r["p99_ssd"], ".4f"),
          f"{100 * r['refined_share']:.1f} %", f"{100 * r['refined_share_default']:.1f} %"]
         for r in report["scenes"]])
    what = "largest" if report["quantile"] == 1.0 else f"{report['quantile']:g} quantile of the"
    return "\n".join([
        "# Adaptive normalisation across datasets", "",
        f"One constant, the {what} 3×3 luminance SSD over every scene's first pass (base LOD "
        f"{report['base_lod']}): **{report['normalisation']:.5g}** (default "
        f"{report['default']}). Pixels refined: normalised variance ≥ 0.25.", "", table, ""])
