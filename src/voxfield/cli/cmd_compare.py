"""``voxfield compare``: the EA thesis §5.2 renderer comparison on the user's own scene."""

from __future__ import annotations

import argparse

from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    add_renderer_options,
    add_scene_options,
    add_study_folder,
    add_view_options,
    check_measured_channel,
    check_measured_sides,
    default_output,
    given_options,
    note_options_read_only_with_others,
    open_octree,
    positive_int,
    settled_view,
    study_camera,
)
from voxfield.render.error_aware import ErrorAwareOptions
from voxfield.studies.compare import run_compare
from voxfield.studies.report import fmt, fmt_psnr


def register(subparsers) -> argparse.ArgumentParser:
    """Register ``compare`` on the main parser's sub-commands (scene options as ``render``)."""
    p = add_command(
        subparsers, "compare",
        description="Render the reference (4×4 rays at LOD 0), the variance-adaptive and the "
        "error-aware renderer, measure PSNR/RMSE/SSIM/FLIP against the reference and count "
        "rays and traversal steps (EA thesis Tables 5.2–5.5, figs 5.1–5.3). Writes "
        "results.json, results.md, images, cost maps, contact_sheet.png and report.html; "
        "finished renders are cached, so a re-run resumes.",
    )
    add_scene_options(p)
    add_view_options(p)
    add_renderer_options(p, ("error-aware", "adaptive"),
                         only=("threshold", "decay", "base_lod"))
    p.add_argument("--reuse-parent", action="store_true",
                   help="add a row: error-aware with parent-ray reuse (3 new rays per "
                   "refinement, EA §6.2)")
    p.add_argument("--channel", default="albedo", help="colour channel (default albedo)")
    p.add_argument("--threads", type=positive_int, default=None, help="kernel threads")
    add_study_folder(p, "compare", "renders and metrics", scheduled=True)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    check_measured_sides([args.size])
    # From --base-lod 0 the error-aware rows read no --threshold, --decay or --reuse-parent
    # (the reuse row came out as the plain one), as render notes.
    note_options_read_only_with_others(
        ErrorAwareOptions(threshold=args.threshold, decay=args.decay, base_lod=args.base_lod,
                          reuse_parent=args.reuse_parent), "error-aware",
        given_options(args))
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    args = settled_view(args, octree)
    view = study_camera(args, octree)
    label = "custom" if args.eye is not None else args.camera
    report = run_compare(
        octree, view, args.out or default_output("compare", args.scene),
        threshold=args.threshold, decay=args.decay, base_lod=args.base_lod, seed=args.seed,
        channel=args.channel, reuse_parent=args.reuse_parent,
        camera_label=label, threads=args.threads, fresh=args.fresh, progress=not args.quiet,
        scheduler=args.scheduler, scene_name=args.scene,
    )
    if not args.quiet:
        print(summary_text(report))
    return 0


def summary_text(report: dict) -> str:
    """The console summary: one line per renderer, then where the files went."""
    # as wide as the longest name: ``error-aware+reuse`` pushed its row past the columns
    width = max(len("renderer"), *(len(row["renderer"]) for row in report["rows"])) + 2
    lines = [f"{'renderer':<{width}}{'rays':>12}{'rays/px':>9}{'steps':>14}{'PSNR':>8}"
             f"{'RMSE':>9}{'SSIM':>7}{'FLIP':>7}"]
    for row in report["rows"]:
        c, q = row["cost"], row["quality"] or {}
        lines.append(
            f"{row['renderer']:<{width}}{c['rays_hit']:>12,}{c['rays_per_pixel']:>9.3f}"
            f"{c['traversal_steps']:>14,}{fmt_psnr(q, '.2f'):>8}"
            f"{fmt(q.get('rmse'), '.5f'):>9}{fmt(q.get('ssim'), '.3f'):>7}"
            f"{fmt(q.get('flip'), '.3f'):>7}"
        )
    reused = f", reused {', '.join(report['reused'])}" if report["reused"] else ""
    lines.append(f"wrote {report['folder']}/ (report.html, results.md, contact_sheet.png{reused})")
    return "\n".join(lines)
