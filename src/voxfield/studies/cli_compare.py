"""``voxfield compare``: the EA thesis §5.2 renderer comparison on the user's own scene."""

from __future__ import annotations

import argparse


def add_compare_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``compare`` on the main parser's sub-commands (scene options as ``render``)."""
    from voxfield.cli import _add_scene_options, _add_view_options, _lod_arg, _positive_int

    p = subparsers.add_parser(
        "compare", help="reference vs adaptive vs error-aware: cost and quality tables",
        description="Render the reference (4×4 rays at LOD 0), the variance-adaptive and the "
        "error-aware renderer, measure PSNR/RMSE/SSIM/FLIP against the reference and count "
        "rays and traversal steps (EA thesis Tables 5.2–5.5, figs 5.1–5.3). Writes "
        "results.json, results.md, images, cost maps and contact_sheet.png; finished renders "
        "are cached, so a re-run resumes.",
    )
    _add_scene_options(p)
    _add_view_options(p)
    p.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware error threshold (default 0.154, the thesis's calibration)")
    p.add_argument("--decay", type=float, default=0.2,
                   help="error-aware decay factor for children's errors (default 0.2)")
    p.add_argument("--base-lod", type=_lod_arg, default=2,
                   help="LOD of the first ray per pixel in both cheap renderers, or 'cone' "
                   "(default 2, the thesis's setup)")
    p.add_argument("--reuse-parent", action="store_true",
                   help="add a row: error-aware with parent-ray reuse (3 new rays per "
                   "refinement, EA §6.2)")
    p.add_argument("--channel", default="albedo", help="colour channel (default albedo)")
    p.add_argument("--threads", type=_positive_int, default=None, help="kernel threads")
    p.add_argument("--fresh", action="store_true",
                   help="ignore cached renders and metrics in the output folder")
    p.add_argument("--out", default=None,
                   help="output folder (default out/compare_NAME, NAME from the scene)")
    p.set_defaults(func=cmd_compare)
    return p


def cmd_compare(args) -> int:
    from voxfield.cli import _camera, _open_octree, default_output
    from voxfield.studies.compare import run_compare

    octree = _open_octree(args)
    camera = _camera(args, octree)
    label = "custom" if args.eye is not None else args.camera
    report = run_compare(
        octree, camera, args.out or default_output("compare", args.scene),
        threshold=args.threshold, decay=args.decay, base_lod=args.base_lod, seed=args.seed,
        channel=args.channel, reuse_parent=args.reuse_parent,
        camera_label=label, threads=args.threads, fresh=args.fresh, progress=not args.quiet,
    )
    if not args.quiet:
        print(summary_text(report))
    return 0


def summary_text(report: dict) -> str:
    """The console summary: one line per renderer, then where the files went."""
    from voxfield.studies.report import fmt

    lines = [f"{'renderer':<12}{'rays':>12}{'rays/px':>9}{'steps':>14}{'PSNR':>8}"
             f"{'RMSE':>9}{'SSIM':>7}{'FLIP':>7}"]
    for row in report["rows"]:
        c, q = row["cost"], row["quality"] or {}
        lines.append(
            f"{row['renderer']:<12}{c['rays_hit']:>12,}{c['rays_per_pixel']:>9.3f}"
            f"{c['traversal_steps']:>14,}{fmt(q.get('psnr'), '.2f'):>8}"
            f"{fmt(q.get('rmse'), '.5f'):>9}{fmt(q.get('ssim'), '.3f'):>7}"
            f"{fmt(q.get('flip'), '.3f'):>7}"
        )
    reused = f", reused {', '.join(report['reused'])}" if report["reused"] else ""
    lines.append(f"wrote {report['folder']}/ (results.md, contact_sheet.png{reused})")
    return "\n".join(lines)
