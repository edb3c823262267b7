"""``voxfield calibrate``: the error threshold meeting a ray budget or a PSNR (EA §5.1.4)."""

from __future__ import annotations

import numpy as np

from voxfield.atomic import atomic_path
from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    add_channel_option,
    add_renderer_options,
    add_scene_options,
    add_view_options,
    check_measured_channel,
    check_measured_sides,
    check_refinable_base_lod,
    int_between,
    open_octree,
    output_named,
    positive_float,
    positive_int,
    study_camera,
)
from voxfield.json_output import json_text
from voxfield.metrics import psnr_text
from voxfield.studies.calibrate import calibrate_threshold


def register(subparsers) -> None:
    p = add_command(
        subparsers, "calibrate",
        description="Bisection on the error-aware renderer's threshold (EA §5.1.4): the "
        "smallest threshold within a ray budget, or the largest meeting a PSNR target.",
    )
    add_scene_options(p)
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--target-rays", type=positive_int, help="ray budget for the image")
    target.add_argument("--target-psnr", type=positive_float,
                        help="PSNR target in dB vs the reference")
    add_renderer_options(p, ("error-aware",), only=("decay", "base_lod"), prefix=False)
    p.add_argument("--iterations", type=int_between(1, 64, "each is a full render"),
                   default=14, help="bisection steps, 1..64 (default 14)")
    p.add_argument("--out", default=None, help="write the result and trail as JSON")
    add_channel_option(p)
    add_view_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    check_refinable_base_lod(args, "every --threshold renders the same image")
    if args.target_psnr is not None:  # (a ray count is reached without measuring images)
        check_measured_sides([args.size])
    if args.out:
        output_named(args.out, ".json", "the calibration trail")  # before the renders
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    view = study_camera(args, octree)
    cal = calibrate_threshold(
        octree, view, target_rays=args.target_rays, target_psnr=args.target_psnr,
        decay=args.decay, base_lod=args.base_lod, iterations=args.iterations, seed=args.seed,
        channel=args.channel, progress=not args.quiet,
    )
    if args.out:
        with atomic_path(args.out) as tmp:
            # Strict JSON: an infinite PSNR (an image equal to the reference) is written
            # as null, as the studies write it; a ray budget measures none and writes none.
            tmp.write_text(json_text(cal.as_dict()))
    if not args.quiet:
        # NaN: a ray budget measures no PSNR; an infinite one (an image equal to the
        # reference) is the best there is, and was left out as if unmeasured
        quality = "" if np.isnan(cal.psnr) else f", PSNR {psnr_text(cal.psnr)} dB"
        print(f"threshold {cal.threshold:.4f} (decay {args.decay}): {cal.rays:,} rays, "
              f"{cal.steps:,} steps{quality}; {len(cal.trail)} renders")
    return 0
