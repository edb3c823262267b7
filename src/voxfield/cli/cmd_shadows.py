"""``voxfield shadows``: the EA thesis's shadow-ray test (§3.2.2, figs 3.4–3.6) on a scene;
the study itself is ``voxfield.studies.shadow_study``."""

from __future__ import annotations

import argparse

from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    add_renderer_options,
    add_scene_options,
    add_study_folder,
    add_view_options,
    default_output,
    open_octree,
    positive_int,
    study_camera,
)
from voxfield.studies.shadow_study import run_shadow_study, summary_text

DEFAULT_SCENE = "builtin:shadowbox"
def register(subparsers) -> argparse.ArgumentParser:
    """Register ``shadows`` on the main parser's sub-commands."""
    p = add_command(
        subparsers, "shadows",
        description="The EA thesis's shadow-ray test (§3.2.2): direct light with "
        "importance-sampled shadow rays at full resolution, at a LOD growing with distance "
        "(the baseline) and error-aware. Writes images, LOD-used maps, the light reaching "
        "the floor in front of the grid, results.json, results.md, contact_sheet.png and "
        "report.html.",
    )
    add_scene_options(p)
    # The scene is optional here: the thesis's test scene by default.
    scene = next(a for a in p._actions if a.dest == "scene")
    scene.nargs, scene.default = "?", DEFAULT_SCENE
    scene.help = f"{scene.help}; default {DEFAULT_SCENE}"
    add_view_options(p, size=256, camera="beam")
    p.add_argument("--light-samples", type=positive_int, default=16,
                   help="light samples per pixel of the cheap renders (default 16)")
    p.add_argument("--reference-samples", type=positive_int, default=256,
                   help="light samples per pixel of the reference (default 256)")
    p.add_argument("--floor-samples", type=positive_int, default=64,
                   help="light samples per floor point of the beam measurement (default 64)")
    p.add_argument("--lod-distance", type=float, default=16.0,
                   help="shadow-ray length at which the baseline switches to LOD 1; LOD k "
                   "starts at (2^k - 1) times it (default 16)")
    add_renderer_options(p, ("error-aware",), only=("threshold", "decay"))
    p.add_argument("--refinements", type=int, default=None,
                   help="error-aware: most LODs a shadow ray refines below the baseline "
                   "(default: down to the voxels)")
    p.add_argument("--encoding", choices=("oct", "sh"), default=None,
                   help="error-table encoding (default: the table's)")
    p.add_argument("--threads", type=positive_int, default=None, help="kernel threads")
    add_study_folder(p, "shadows", "renders", scheduled=True)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    octree = open_octree(args)
    view = study_camera(args, octree)
    report = run_shadow_study(
        octree, view, args.out or default_output("shadows", args.scene),
        light_samples=args.light_samples, reference_samples=args.reference_samples,
        floor_samples=args.floor_samples, lod_distance=args.lod_distance,
        threshold=args.threshold, decay=args.decay, max_refinements=args.refinements,
        encoding=args.encoding, seed=args.seed, threads=args.threads, fresh=args.fresh,
        camera_label="custom" if args.eye is not None else args.camera,
        progress=not args.quiet, scheduler=args.scheduler, scene_name=args.scene,
    )
    if not args.quiet:
        print(summary_text(report))
    return 0
