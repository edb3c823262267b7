"""``voxfield sweep``: the decay × threshold grid of EA Table 5.1."""

from __future__ import annotations

from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    add_channel_option,
    add_renderer_options,
    add_scene_options,
    add_study_folder,
    add_view_options,
    check_measured_channel,
    check_measured_sides,
    check_refinable_base_lod,
    default_output,
    float_list,
    non_negative_float_list,
    open_octree,
    study_camera,
)
from voxfield.studies.sweep import THESIS_DECAYS, THESIS_THRESHOLDS, run_sweep


def register(subparsers) -> None:
    p = add_command(
        subparsers, "sweep",
        description="Render the error-aware renderer over a decay × threshold grid, beside "
        "the adaptive renderer and the 4×4 reference; resumable.",
    )
    add_scene_options(p)
    p.add_argument("--decays", type=non_negative_float_list, default=THESIS_DECAYS,
                   help="comma-separated decays (default the thesis's 0.05..0.3)")
    p.add_argument("--thresholds", type=float_list, default=THESIS_THRESHOLDS,
                   help="comma-separated thresholds (default the thesis's 0.175..0.05)")
    add_renderer_options(p, ("error-aware",), only=("base_lod",), prefix=False)
    add_study_folder(p, "sweep", "cells", scheduled=True)
    add_channel_option(p)
    add_view_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    check_refinable_base_lod(args, "every --thresholds/--decays cell renders the same image")
    check_measured_sides([args.size])
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    view = study_camera(args, octree)
    out = args.out or default_output("sweep", args.scene)
    report = run_sweep(octree, view, out, decays=args.decays, thresholds=args.thresholds,
                       base_lod=args.base_lod, seed=args.seed, channel=args.channel,
                       scene_name=args.scene, progress=not args.quiet, fresh=args.fresh,
                       scheduler=args.scheduler)
    if not args.quiet:
        print(f"adaptive: {report['adaptive']['rays']:,} rays; per decay, the threshold "
              "closest to it:")
        for pick in report["closest_to_adaptive"]:
            # (JSON has no infinity: the PSNR of an image equal to the reference is None.)
            quality = ("equal to the reference" if pick["psnr"] is None
                       else f"PSNR {pick['psnr']:.2f} dB")
            edge = "" if pick["within_grid"] else " (the grid's edge, not a match)"
            print(f"  d={pick['decay']}: t={pick['threshold']} → {pick['rays']:,} rays, "
                  f"{quality}{edge}")
        print(f"wrote {out}/report.html, results.md, results.json, sweep.png, view.png")
    return 0
