"""``voxfield study thresholds|resolution``: the EA thesis §5.4 and §5.5 studies."""

from __future__ import annotations

import argparse


def add_study_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``study`` with its ``thresholds`` and ``resolution`` actions."""
    from voxfield.cli import (
        _add_channel_option,
        _add_scene_options,
        _add_view_options,
        _float_list,
        _lod_arg,
    )
    from voxfield.studies.resolution_study import THESIS_SIZES
    from voxfield.studies.threshold_study import THESIS_THRESHOLDS

    p = subparsers.add_parser(
        "study", help="thesis studies: error threshold (§5.4), resolution (§5.5)",
        description="Resumable studies writing results.json, results.md and a plot.",
    )
    actions = p.add_subparsers(dest="study", required=True, metavar="STUDY")

    t = actions.add_parser(
        "thresholds", help="error-aware cost and quality per threshold (EA Tables 5.27-5.28)",
        description="Render the error-aware renderer at each threshold beside the adaptive "
        "renderer and the 4×4 reference; rays, steps, PSNR, RMSE, SSIM. Resumable.",
    )
    _add_scene_options(t)
    t.add_argument("--thresholds", type=_float_list, default=THESIS_THRESHOLDS,
                   help="comma-separated thresholds (default 0.05..0.3)")
    t.add_argument("--decay", type=float, default=0.2, help="error-aware decay (default 0.2)")
    t.add_argument("--base-lod", type=_lod_arg, default=2, help="LOD of the first ray (2)")
    t.add_argument("--out", default=None, help="output folder (default out/thresholds_SCENE)")
    t.add_argument("--fresh", action="store_true", help="ignore cached cells")
    _add_channel_option(t)
    _add_view_options(t)
    t.set_defaults(func=cmd_study_thresholds)

    r = actions.add_parser(
        "resolution", help="reference/adaptive/error-aware per image size (EA Tables "
        "5.29-5.30)",
        description="Render the top-down 90° view at each size; the base LOD follows the "
        "resolution (one base-LOD node ≈ one pixel). Resumable.",
    )
    _add_scene_options(r)
    r.add_argument("--sizes", type=_int_list, default=THESIS_SIZES,
                   help="comma-separated image sides (default 128,256,512,1024)")
    r.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware threshold (default 0.154)")
    r.add_argument("--decay", type=float, default=0.2, help="error-aware decay (default 0.2)")
    r.add_argument("--out", default=None, help="output folder (default out/resolution_SCENE)")
    r.add_argument("--fresh", action="store_true", help="ignore cached cells")
    _add_channel_option(r)
    r.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars or summaries")
    r.set_defaults(func=cmd_study_resolution)

    g = actions.add_parser(
        "lighting", help="adaptive vs error-aware vs lighting-aware per time of day (EA "
        "Tables 5.18-5.26)",
        description="Per colour channel (albedo and each baked time of day): the 4×4 "
        "reference, adaptive, error-aware and lighting-aware error-aware renderers; rays, "
        "steps, average luminance, PSNR, RMSE, SSIM and a contact sheet. A scene without "
        "baked channels is baked first (as `voxfield light`). Resumable.",
    )
    _add_scene_options(g)
    g.add_argument("--channels", default=None,
                   help="comma-separated channels (default albedo and every baked one)")
    g.add_argument("--times", default=None, metavar="SUNS",
                   help="times of day to bake when the scene has none (default all four)")
    g.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware threshold (default 0.154)")
    g.add_argument("--decay", type=float, default=0.2, help="error-aware decay (default 0.2)")
    g.add_argument("--base-lod", type=_lod_arg, default=2, help="LOD of the first ray (2)")
    g.add_argument("--bright-ratio", type=float, default=0.25,
                   help="lighting-aware: bright above (1 + R) × the parent's luminance")
    g.add_argument("--out", default=None, help="output folder (default out/lighting_SCENE)")
    g.add_argument("--fresh", action="store_true", help="ignore cached renders")
    _add_view_options(g)
    g.set_defaults(func=cmd_study_lighting)

    b = actions.add_parser(
        "probe-resolution", help="probe bakers' cost and quality per map size (EA Tables "
        "5.29-5.30, for probes)",
        description="Bake probes at each octahedral map size with the 4×4 reference baker "
        "and the cheap bakers (LOD cone, adaptive, error-aware); rays and steps per texel, "
        "PSNR/RMSE/SSIM of radiance against the reference.",
    )
    _add_scene_options(b)
    b.add_argument("--grid", default="1x1x1",
                   help="probe grid: NXxNYxNZ fitted to the scene, or origin=..;spacing=..;"
                   "counts=.. (default one probe at the centre)")
    b.add_argument("--resolutions", type=_int_list, default=(64, 128, 256),
                   help="comma-separated map sides (default 64,128,256)")
    b.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware threshold (default 0.154)")
    b.add_argument("--decay", type=float, default=0.2, help="error-aware decay (default 0.2)")
    _add_channel_option(b)
    b.add_argument("--out", default=None,
                   help="output folder (default out/probe_resolution_SCENE)")
    b.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars or summaries")
    b.set_defaults(func=cmd_study_probe_resolution)

    from voxfield.studies.probe_study import add_probe_study_parser

    add_probe_study_parser(actions)
    return p


def _int_list(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected sizes like 128,256, got {text!r}") from None
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"sizes must be positive, got {text!r}")
    return values


def cmd_study_thresholds(args) -> int:
    from voxfield.cli import _camera, _open_octree, default_output
    from voxfield.studies.report import fmt
    from voxfield.studies.threshold_study import run_threshold_study

    octree = _open_octree(args)
    camera = _camera(args, octree)
    out = args.out or default_output("thresholds", args.scene)
    report = run_threshold_study(
        octree, camera, out, thresholds=args.thresholds, decay=args.decay,
        base_lod=args.base_lod, seed=args.seed, channel=args.channel, scene_name=args.scene,
        progress=not args.quiet, fresh=args.fresh)
    if not args.quiet:
        a = report["adaptive"]
        print(f"adaptive: {a['rays']:,} rays, {a['steps']:,} steps, "
              f"PSNR {fmt(a['psnr'], '.2f')} dB")
        for row in report["rows"]:
            e = row["error_aware"]
            print(f"  t={row['threshold']:g}: {e['rays']:,} rays, {e['steps']:,} steps, "
                  f"PSNR {fmt(e['psnr'], '.2f')} dB")
        print(f"wrote {out}/results.md, results.json, thresholds.png")
    return 0


def cmd_study_resolution(args) -> int:
    from voxfield.cli import _open_octree, default_output
    from voxfield.studies.report import fmt
    from voxfield.studies.resolution_study import run_resolution_study

    octree = _open_octree(args)
    out = args.out or default_output("resolution", args.scene)
    report = run_resolution_study(
        octree, out, sizes=args.sizes, threshold=args.threshold, decay=args.decay,
        seed=args.seed, channel=args.channel, scene_name=args.scene, progress=not args.quiet,
        fresh=args.fresh)
    if not args.quiet:
        for row in report["rows"]:
            a, e = row["adaptive"], row["error_aware"]
            print(f"{row['size']}² (base LOD {row['base_lod']}): adaptive "
                  f"{a['rays_per_pixel']:.2f} rays/px, PSNR {fmt(a['psnr'], '.2f')} dB; "
                  f"error-aware {e['rays_per_pixel']:.2f} rays/px, "
                  f"PSNR {fmt(e['psnr'], '.2f')} dB")
        print(f"wrote {out}/results.md, results.json, resolution.png")
    return 0


def cmd_study_lighting(args) -> int:
    from voxfield.cli import _camera, _open_octree, default_output
    from voxfield.lighting import bake_sun_lighting, parse_suns
    from voxfield.studies.lighting_study import lighting_channels, run_lighting_study
    from voxfield.studies.report import fmt

    octree = _open_octree(args)
    if len(lighting_channels(octree)) < 2:
        suns = parse_suns(args.times or "all")
        octree, _ = bake_sun_lighting(octree, suns, seed=args.seed, progress=not args.quiet)
    camera = _camera(args, octree)
    channels = args.channels.split(",") if args.channels else None
    out = args.out or default_output("lighting", args.scene)
    report = run_lighting_study(
        octree, camera, out, channels=channels, threshold=args.threshold, decay=args.decay,
        base_lod=args.base_lod, bright_ratio=args.bright_ratio, seed=args.seed,
        scene_name=args.scene, progress=not args.quiet, fresh=args.fresh)
    if not args.quiet:
        for row in report["rows"]:
            parts = [f"{label} {row[key]['steps']:,} steps {fmt(row[key]['psnr'], '.2f')} dB"
                     for key, label in (("adaptive", "A"), ("error_aware", "EA"),
                                        ("lighting_aware", "EA-L"))]
            print(f"{row['channel']:>10}: " + "; ".join(parts))
        print(f"wrote {out}/results.md, results.json, lighting.png, contact_sheet.png")
    return 0


def cmd_study_probe_resolution(args) -> int:
    from voxfield.cli import _open_octree, default_output
    from voxfield.probes.grid import parse_grid
    from voxfield.probes.resolution_study import (
        probe_resolution_markdown,
        probe_resolution_study,
    )
    from voxfield.studies.report import StudyFolder

    octree = _open_octree(args)
    grid = parse_grid(args.grid, octree.voxel_bounds)
    report = probe_resolution_study(
        octree, grid.positions[grid.enabled], args.resolutions, threshold=args.threshold,
        decay=args.decay, seed=args.seed, channel=args.channel, scene_name=args.scene,
        progress=not args.quiet)
    folder = StudyFolder(args.out or default_output("probe_resolution", args.scene))
    folder.write_json("results.json", report)
    path = folder.write_text("results.md", probe_resolution_markdown(report))
    if not args.quiet:
        print(probe_resolution_markdown(report))
        print(f"wrote {path} and results.json")
    return 0
