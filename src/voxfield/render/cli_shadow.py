"""``voxfield shadows``: the EA thesis's shadow-ray test (§3.2.2, figs 3.4–3.6) on a scene;
the study itself is ``voxfield.studies.shadow_study``."""

from __future__ import annotations

import argparse

import numpy as np

DEFAULT_SCENE = "builtin:shadowbox"
def _action(parser: argparse.ArgumentParser, dest: str) -> argparse.Action:
    """The option a shared helper added, to adjust its default or help for this command."""
    return next(a for a in parser._actions if a.dest == dest)


def add_shadow_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``shadows`` on the main parser's sub-commands."""
    from voxfield.cli import _add_scene_options, _add_view_options, _positive_int

    p = subparsers.add_parser(
        "shadows", help="shadow-ray LOD test: reference vs distance-LOD vs error-aware",
        description="The EA thesis's shadow-ray test (§3.2.2): direct light with "
        "importance-sampled shadow rays at full resolution, at a LOD growing with distance "
        "(the baseline) and error-aware. Writes images, LOD-used maps, the light reaching "
        "the floor behind the grid, results.json, results.md and contact_sheet.png.",
    )
    _add_scene_options(p)
    # The scene is optional here: the thesis's test scene by default.
    scene = _action(p, "scene")
    scene.nargs, scene.default = "?", DEFAULT_SCENE
    scene.help = f"{scene.help}; default {DEFAULT_SCENE}"
    _add_view_options(p, size=256)
    p.set_defaults(camera="beam")
    _action(p, "camera").help = ("beam (in front of the scene, above the floor, looking at "
                                 "it; default), top, oblique, orbit, ortho-top, cube+x..cube-z")
    p.add_argument("--light-samples", type=_positive_int, default=16,
                   help="light samples per pixel of the cheap renders (default 16)")
    p.add_argument("--reference-samples", type=_positive_int, default=256,
                   help="light samples per pixel of the reference (default 256)")
    p.add_argument("--floor-samples", type=_positive_int, default=64,
                   help="light samples per floor point of the beam measurement (default 64)")
    p.add_argument("--lod-distance", type=float, default=16.0,
                   help="shadow-ray length at which the baseline switches to LOD 1; LOD k "
                   "starts at (2^k - 1) times it (default 16)")
    p.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware error threshold (default 0.154, EA §5.1.4)")
    p.add_argument("--decay", type=float, default=0.2,
                   help="error-aware weight of the children's error (default 0.2)")
    p.add_argument("--refinements", type=int, default=None,
                   help="error-aware: most LODs a shadow ray refines below the baseline "
                   "(default: down to the voxels)")
    p.add_argument("--encoding", choices=("oct", "sh"), default=None,
                   help="error-table encoding (default: the table's)")
    p.add_argument("--threads", type=_positive_int, default=None, help="kernel threads")
    p.add_argument("--fresh", action="store_true", help="ignore cached renders in --out")
    p.add_argument("--out", default=None,
                   help="output folder (default out/shadows_NAME, NAME from the scene)")
    p.set_defaults(func=cmd_shadows)
    return p


def beam_camera(octree, size: int = 256, fov_deg: float = 58.0):
    """In front of the scene (+z), above the floor, looking down at the floor in front of the
    scene's middle: for the shadow box, the grid and the whole beam."""
    from voxfield.render.camera import Camera

    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    extent = float(max(hi[0] - lo[0], hi[2] - lo[2]))
    centre = (lo + hi) / 2.0
    eye = (centre[0] + 0.125 * extent, lo[1] + 0.4 * extent, hi[2] + 0.12 * extent)
    target = (centre[0], lo[1], centre[2] + 0.2 * extent)
    return Camera.look_at(eye, target, fov_deg=fov_deg, width=size)


def cmd_shadows(args) -> int:
    from voxfield.cli import _camera, _open_octree, default_output
    from voxfield.studies.shadow_study import run_shadow_study, summary_text

    octree = _open_octree(args)
    if args.camera == "beam" and args.eye is None and args.target is None:
        camera = beam_camera(octree, args.size, args.fov or 58.0)
    else:
        camera = _camera(args, octree)
    report = run_shadow_study(
        octree, camera, args.out or default_output("shadows", args.scene),
        light_samples=args.light_samples, reference_samples=args.reference_samples,
        floor_samples=args.floor_samples, lod_distance=args.lod_distance,
        threshold=args.threshold, decay=args.decay, max_refinements=args.refinements,
        encoding=args.encoding, seed=args.seed, threads=args.threads, fresh=args.fresh,
        camera_label="custom" if args.eye is not None else args.camera,
        progress=not args.quiet,
    )
    if not args.quiet:
        print(summary_text(report))
    return 0
