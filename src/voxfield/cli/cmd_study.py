"""``voxfield study thresholds|resolution|lighting|curves|probe-resolution|probes``: the EA
thesis's studies (§5.4, §5.5, §5.3) and the probe thesis's analysis (ch. 9)."""

from __future__ import annotations

import argparse
import math

from voxfield.cli.commands import add_command, add_quiet
from voxfield.cli.options import (
    add_channel_option,
    add_hit_options,
    add_renderer_options,
    add_scene_options,
    add_study_folder,
    add_threshold_options,
    add_view_options,
    auto_preset,
    check_base_lod,
    check_measured_channel,
    check_measured_sides,
    check_refinable_base_lod,
    check_render_memory,
    default_output,
    distinct,
    finite_float,
    float_list,
    hit_options,
    image_side_list,
    int_between,
    lod_arg,
    name_list,
    non_negative_float_list,
    note_unread_scene_options,
    note_unused_epsilon_options,
    open_octree,
    positive_int_list,
    scene_camera,
    scheduler_name,
    study_camera,
    warn_ignored,
    with_camera,
)
from voxfield.errors import VoxfieldError
from voxfield.lightfield.trace import LightFieldOptions
from voxfield.lighting import bake_sun_lighting, parse_suns
from voxfield.probes.grid import check_placement, parse_grid, relocate
from voxfield.probes.probe_set import MAX_RESOLUTION, MIN_RESOLUTION
from voxfield.render.camera import MAX_IMAGE_SIDE, preset_camera
from voxfield.render.placement import camera_placement_problem, check_camera_placement
from voxfield.scaleout import SCHEDULER_HELP
from voxfield.studies.adaptive_normalisation import run_normalisation_study
from voxfield.studies.curves_study import (
    CURVE_CAMERAS,
    CURVE_DECAYS,
    CURVE_LODS,
    CURVE_NORMALISATIONS,
    CURVE_THRESHOLDS,
    run_curves_study,
)
from voxfield.studies.lighting_study import lighting_channels, run_lighting_study
from voxfield.studies.probe_resolution_study import (
    probe_resolution_markdown,
    probe_resolution_study,
)
from voxfield.studies.probe_study import (
    DEFAULT_PROBE_COUNTS,
    MARCHERS,
    ORDERINGS,
    THESIS_RESOLUTIONS,
    grid_spec,
    results_markdown,
    run_probe_study,
)
from voxfield.studies.report import StudyFolder, fmt, fmt_psnr
from voxfield.studies.resolution_study import THESIS_SIZES, run_resolution_study
from voxfield.studies.threshold_study import THESIS_THRESHOLDS, run_threshold_study

#: What the studies' ``--thresholds`` take beyond the thesis's range: the two ends of a curve.
THRESHOLD_ENDS = "a negative one refines every ray it may, inf none"


def register(subparsers) -> argparse.ArgumentParser:
    """Register ``study`` with one action per study."""
    p = add_command(
        subparsers, "study",
        description="Resumable studies writing results.json, results.md, report.html and "
        "their figures.",
    )
    actions = p.add_subparsers(dest="study", required=True, metavar="STUDY")

    t = actions.add_parser(
        "thresholds", help="error-aware cost and quality per threshold (EA Tables 5.27-5.28)",
        description="Render the error-aware renderer at each threshold beside the adaptive "
        "renderer and the 4×4 reference; rays, steps, PSNR, RMSE, SSIM. Resumable.",
    )
    add_scene_options(t)
    t.add_argument("--thresholds", type=float_list, default=THESIS_THRESHOLDS,
                   help="comma-separated thresholds (default 0.05..0.3; " + THRESHOLD_ENDS + ")")
    add_renderer_options(t, ("error-aware", "adaptive"), only=("decay", "base_lod"))
    add_study_folder(t, "thresholds", "cells", scheduled=True)
    add_channel_option(t)
    add_view_options(t)
    t.set_defaults(func=run_thresholds)

    r = actions.add_parser(
        "resolution", help="reference/adaptive/error-aware per image size (EA Tables "
        "5.29-5.30)",
        description="Render the top-down 90° view at each size; the base LOD follows the "
        "resolution (one base-LOD node ≈ one pixel). Resumable.",
    )
    add_scene_options(r)
    r.add_argument("--sizes", type=image_side_list, default=THESIS_SIZES,
                   help=f"comma-separated image sides, each 1..{MAX_IMAGE_SIDE} (default "
                   "128,256,512,1024)")
    add_threshold_options(r)
    add_study_folder(r, "resolution", "cells", scheduled=True)
    add_channel_option(r)
    add_quiet(r)
    r.set_defaults(func=run_resolution)

    g = actions.add_parser(
        "lighting", help="adaptive vs error-aware vs lighting-aware per time of day (EA "
        "Tables 5.18-5.26)",
        description="Per colour channel (albedo and each baked time of day): the 4×4 "
        "reference, adaptive, error-aware and lighting-aware error-aware renderers; rays, "
        "steps, average luminance, PSNR, RMSE, SSIM and a contact sheet. A scene without "
        "baked channels is baked first (as `voxfield light`). Resumable.",
    )
    add_scene_options(g)
    g.add_argument("--channels", type=name_list, default=None,
                   help="comma-separated channels (default albedo and every baked one)")
    g.add_argument("--times", default=None, metavar="SUNS",
                   help="times of day to bake when the scene has none (default all four)")
    add_renderer_options(g, ("error-aware", "adaptive"),
                         only=("threshold", "decay", "base_lod", "bright_ratio"))
    add_study_folder(g, "lighting", "renders", scheduled=True)
    add_view_options(g)
    g.set_defaults(func=run_lighting)

    b = actions.add_parser(
        "probe-resolution", help="probe bakers' cost and quality per map size (EA Tables "
        "5.29-5.30, for probes)",
        description="Bake probes at each octahedral map size with the 4×4 reference baker "
        "and the cheap bakers (LOD cone, adaptive, error-aware); rays and steps per texel, "
        "PSNR/RMSE/SSIM of radiance against the reference. Resumable.",
    )
    add_scene_options(b)
    b.add_argument("--grid", default="1x1x1",
                   help="probe grid: NXxNYxNZ fitted to the scene, or origin=..;spacing=..;"
                   "counts=.. (default one probe at the centre)")
    b.add_argument("--no-relocate", action="store_true",
                   help="keep probes where the grid puts them even inside geometry (by "
                   "default they are moved out first, as study probes does)")
    b.add_argument("--resolutions", type=probe_map_sides, default=(64, 128, 256),
                   help=f"comma-separated map sides, each even, {MIN_RESOLUTION}..{MAX_RESOLUTION} "
                   "(default 64,128,256)")
    add_threshold_options(b)
    add_channel_option(b)
    add_study_folder(b, "probe_resolution", "bakes")
    add_quiet(b)
    b.set_defaults(func=run_probe_resolution)

    _register_curves(actions)
    _register_normalisation(actions)
    _register_probes(actions)
    return p


def _lod_list(text: str) -> tuple[int, ...]:
    """Comma-separated LOD numbers (0 = voxels), each once."""
    values = tuple(lod_arg(v.strip()) for v in text.split(",") if v.strip())
    if not values or any(v is None for v in values):
        raise argparse.ArgumentTypeError(f"expected LOD numbers like 4,2,0, got {text!r}")
    return distinct(values, text)


def _register_curves(actions) -> None:
    c = actions.add_parser(
        "curves", help="cost-quality curves of EA, adaptive and LOD, with Bjøntegaard deltas",
        description="Sweep each cheap renderer over its own knob (EA: threshold per decay; "
        "adaptive: variance normalisation; LOD: level) under each camera; PSNR/SSIM against "
        "the 4×4 reference per traversal step and ray; BD-PSNR at equal steps and rays and "
        "the step change at equal PSNR against adaptive and LOD. Resumable.",
    )
    add_scene_options(c)
    c.add_argument("--cameras", type=name_list, default=CURVE_CAMERAS,
                   help=f"comma-separated preset views (default {','.join(CURVE_CAMERAS)}: "
                   "perspective and orthographic)")
    c.add_argument("--size", type=int_between(16, 4096, "an image side"), default=256,
                   help="image side in pixels, 16..4096 (default 256)")
    c.add_argument("--thresholds", type=float_list, default=CURVE_THRESHOLDS,
                   help="EA thresholds (default " + ",".join(f"{t:g}" for t in CURVE_THRESHOLDS)
                   + "; " + THRESHOLD_ENDS + ")")
    c.add_argument("--decays", type=non_negative_float_list, default=CURVE_DECAYS,
                   help="EA decays, one curve each (default "
                   + ",".join(f"{d:g}" for d in CURVE_DECAYS) + ")")
    c.add_argument("--normalisations", type=float_list, default=CURVE_NORMALISATIONS,
                   help="adaptive variance normalisations (default "
                   + ",".join(f"{n:g}" for n in CURVE_NORMALISATIONS) + ")")
    c.add_argument("--lods", type=_lod_list, default=CURVE_LODS,
                   help="LOD levels (default " + ",".join(map(str, CURVE_LODS)) + ")")
    c.add_argument("--base-lod", type=lod_arg, default=2,
                   help="EA and adaptive first-ray LOD, or 'cone' (default 2)")
    add_study_folder(c, "curves", "renders", scheduled=True)
    add_channel_option(c)
    add_quiet(c)
    c.set_defaults(func=run_curves)


def _register_normalisation(actions) -> None:
    n = actions.add_parser(
        "normalisation", help="the adaptive renderer's one variance normalisation across "
        "several scenes (EA §5.1.2)",
        description="Render each scene's first adaptive pass and find the one constant that "
        "maps the largest 3×3 luminance variance of them all to 1 (the thesis normalises "
        "'across all datasets'); pass it to --variance-normalisation.",
    )
    add_scene_options(n)
    n.add_argument("more_scenes", nargs="*", metavar="SCENE",
                   help="further scenes, read with the same options")
    n.add_argument("--quantile", type=finite_float, default=1.0,
                   help="use this quantile of all windows' variance instead of the largest, "
                   "in (0, 1] (default 1: the largest)")
    n.add_argument("--base-lod", type=lod_arg, default=2,
                   help="first-pass LOD, or 'cone' (default 2)")
    n.add_argument("--out", default=None,
                   help="output folder (default out/normalisation_SCENE)")
    n.add_argument("--scheduler", type=scheduler_name, default=None, metavar="WHERE",
                   help=SCHEDULER_HELP + "; each scene's first pass is a task (default: one "
                   "after another here)")
    add_channel_option(n)
    add_view_options(n, size=256)
    n.set_defaults(func=run_normalisation)


def run_normalisation(args) -> int:
    if not 0.0 < args.quantile <= 1.0:
        raise VoxfieldError(f"--quantile must be in (0, 1], got {args.quantile}")
    if args.size < 2:  # (blamed on flat images after every scene's first pass)
        raise VoxfieldError(f"--size {args.size}: the variance is measured over each pixel's "
                            "3×3 neighbourhood, which a one-pixel image does not have")
    specs = (args.scene, *args.more_scenes)
    twice = sorted({spec for spec in specs if specs.count(spec) > 1})
    if twice:  # kept by name, a scene given twice was measured once, the count said so
        raise VoxfieldError(f"{', '.join(twice)} given twice: each scene counts once")
    scenes = {}
    for spec in specs:
        scene_args = argparse.Namespace(**{**vars(args), "scene": spec})
        octree = open_octree(scene_args, note_unread=False)
        # (``--camera auto`` is each scene's own: top over a terrain, orbit round a model.)
        scenes[spec] = (octree, study_camera(scene_args, octree))
    note_unread_scene_options(args, *scenes)
    out = args.out or default_output("normalisation", next(iter(scenes)))
    report = run_normalisation_study(scenes, out, base_lod=args.base_lod,
                                     quantile=args.quantile, seed=args.seed,
                                     channel=args.channel, scheduler=args.scheduler)
    if not args.quiet:
        print(f"variance normalisation across {len(scenes)} scene(s): "
              f"{report['normalisation']:.5g} (wrote {out}/report.html and results.md)")
    return 0


def run_curves(args) -> int:
    # (A variance normalisation divides: 0 was refused by the study after its first renders.)
    if any(not math.isfinite(v) or v <= 0 for v in args.normalisations):
        raise VoxfieldError("--normalisations must be finite and positive")
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    check_base_lod(args, octree)
    lo, hi = octree.voxel_bounds
    cameras = {name: preset_camera(name, lo, hi, size=args.size) for name in args.cameras}
    for view in cameras.values():
        check_camera_placement(octree, view)
    out = args.out or default_output("curves", args.scene)
    report = run_curves_study(
        octree, cameras, out, thresholds=args.thresholds, decays=args.decays,
        normalisations=args.normalisations, lods=args.lods, base_lod=args.base_lod,
        seed=args.seed, channel=args.channel, scene_name=args.scene,
        progress=not args.quiet, fresh=args.fresh, scheduler=args.scheduler)
    if not args.quiet:
        for cam_name, cam in report["cameras"].items():
            for d in cam["deltas"]:
                print(f"{cam_name}: {d['curve']} vs {d['against']}: BD-PSNR "
                      f"{fmt(d['bd_psnr_steps'], '+.2f')} dB at equal steps, "
                      f"{fmt(d['bd_steps_percent'], '+.1f')} % steps at equal PSNR")
        print(f"wrote {out}/report.html, results.md, results.json, curves.png, view.png")
    return 0


def run_thresholds(args) -> int:
    check_refinable_base_lod(args, "every --thresholds value renders the same image")
    check_measured_sides([args.size])
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    view = study_camera(args, octree)
    out = args.out or default_output("thresholds", args.scene)
    report = run_threshold_study(
        octree, view, out, thresholds=args.thresholds, decay=args.decay,
        base_lod=args.base_lod, seed=args.seed, channel=args.channel, scene_name=args.scene,
        progress=not args.quiet, fresh=args.fresh, scheduler=args.scheduler)
    if not args.quiet:
        a = report["adaptive"]
        print(f"adaptive: {a['rays']:,} rays, {a['steps']:,} steps, "
              f"PSNR {fmt_psnr(a, '.2f')} dB")
        for row in report["rows"]:
            e = row["error_aware"]
            print(f"  t={row['threshold']:g}: {e['rays']:,} rays, {e['steps']:,} steps, "
                  f"PSNR {fmt_psnr(e, '.2f')} dB")
        print(f"wrote {out}/report.html, results.md, results.json, thresholds.png, view.png")
    return 0


def run_resolution(args) -> int:
    check_measured_sides(args.sizes, "--sizes")
    check_render_memory(max(args.sizes), option="--sizes")
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    out = args.out or default_output("resolution", args.scene)
    report = run_resolution_study(
        octree, out, sizes=args.sizes, threshold=args.threshold, decay=args.decay,
        seed=args.seed, channel=args.channel, scene_name=args.scene, progress=not args.quiet,
        fresh=args.fresh, scheduler=args.scheduler)
    if not args.quiet:
        for row in report["rows"]:
            a, e = row["adaptive"], row["error_aware"]
            print(f"{row['size']}² (base LOD {row['base_lod']}): adaptive "
                  f"{a['rays_per_pixel']:.2f} rays/px, PSNR {fmt_psnr(a, '.2f')} dB; "
                  f"error-aware {e['rays_per_pixel']:.2f} rays/px, "
                  f"PSNR {fmt_psnr(e, '.2f')} dB")
        print(f"wrote {out}/report.html, results.md, results.json, resolution.png, view.png")
    return 0


def run_lighting(args) -> int:
    check_refinable_base_lod(args, "the lighting-aware renders are the error-aware ones")
    check_measured_sides([args.size])
    suns = parse_suns("all" if args.times is None else args.times)  # before the scene opens
    octree = open_octree(args)
    view = study_camera(args, octree)  # before a bake: the geometry is the same after it
    channels = list(args.channels) if args.channels is not None else None
    out = args.out or default_output("lighting", args.scene)
    if len(lighting_channels(octree)) < 2:
        if channels is not None:  # refused after the bake, minutes in, before
            baked = sorted({*octree.channel_names, *(sun.name for sun in suns)})
            unknown = [name for name in channels if name not in baked]
            if unknown:
                raise VoxfieldError(f"--channels {','.join(unknown)}: the scene has no such "
                                    f"channel, nor does the study bake one; it will have "
                                    f"{', '.join(baked)}")
        # The folder's checks, before the bake: they came after it, in the study.
        StudyFolder(out, study="study lighting", fresh=args.fresh, scheduler=args.scheduler)
        octree, _ = bake_sun_lighting(octree, suns, seed=args.seed, progress=not args.quiet,
                                      scheduler=args.scheduler)
    elif args.times is not None:
        # The baked channels are studied: --times changed nothing, without a word.
        warn_ignored({"--times": ["a scene without baked channels"]}, "a scene with baked "
                     f"channels ({', '.join(lighting_channels(octree)[1:])})")
    for name in channels or lighting_channels(octree):
        check_measured_channel(octree, name)
    report = run_lighting_study(
        octree, view, out, channels=channels, threshold=args.threshold, decay=args.decay,
        base_lod=args.base_lod, bright_ratio=args.bright_ratio, seed=args.seed,
        scene_name=args.scene, progress=not args.quiet, fresh=args.fresh,
        scheduler=args.scheduler)
    if not args.quiet:
        for row in report["rows"]:
            parts = [f"{label} {row[key]['steps']:,} steps {fmt_psnr(row[key], '.2f')} dB"
                     for key, label in (("adaptive", "A"), ("error_aware", "EA"),
                                        ("lighting_aware", "EA-L"))]
            print(f"{row['channel']:>10}: " + "; ".join(parts))
        print(f"wrote {out}/report.html, results.md, results.json, lighting.png, contact_sheet.png")
    return 0


def run_probe_resolution(args) -> int:
    check_measured_sides(args.resolutions, "--resolutions")
    folder = StudyFolder(args.out or default_output("probe_resolution", args.scene),
                         study="study probe-resolution", fresh=args.fresh)
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    grid = parse_grid(args.grid, octree.voxel_bounds, octree=octree)
    if not args.no_relocate:
        grid, moved = relocate(grid, octree, seed=args.seed)
        if not args.quiet:
            print(moved.summary())
    check_placement(grid, octree, args.grid, relocated=not args.no_relocate,
                    relocate_with="leaving out --no-relocate")
    report = probe_resolution_study(
        octree, grid.positions[grid.enabled], args.resolutions, threshold=args.threshold,
        decay=args.decay, seed=args.seed, channel=args.channel, scene_name=args.scene,
        progress=not args.quiet, folder=folder)
    folder.write_json("results.json", report)
    path = folder.write_text("results.md", probe_resolution_markdown(report))
    folder.publish_report()
    if not args.quiet:
        print(probe_resolution_markdown(report))
        print(f"wrote {path}, results.json and report.html")
    return 0


def _register_probes(actions) -> argparse.ArgumentParser:
    """``study probes``: the probe thesis's analysis."""

    p = actions.add_parser(
        "probes", help="the probe thesis's analysis (ch. 9): quality, fetches per marcher "
        "per resolution, failures per probe count, orderings, wall time",
        description="Bake probes on the scene and render one view from them: PSNR/SSIM of the "
        "light-field, environment and box-proxy renders against the octree's own render of "
        "the same rays; texel fetches per pixel for each marcher per probe resolution (with "
        "the growth exponent against the thesis's O(sqrt r) and O(log r)); failures and "
        "fetches per probe count; first-probe success per ordering; wall time against direct "
        "octree tracing. Writes results.json, results.md, plots and a contact sheet. "
        "Resumable. The default camera (auto) looks down on a terrain or DEM; any other "
        "scene it looks through from inside its box (room: 30% in from the +z face and off "
        "the probe lattice planes, towards the -z face) where that eye is in open space, and "
        "from around the scene (orbit) where the eye is inside or under it (a solid model "
        "filling its box); --camera room, top, oblique, ... or --eye/--target choose another.",
    )
    add_scene_options(p)
    p.add_argument("--grid", default="1x1x1", metavar="GRID",
                   help="main probe grid: NXxNYxNZ fitted to the scene (default 1x1x1: one "
                   "probe at the centre, the thesis's Holodeck test) or surface:NXxNZ@H, one "
                   "layer H voxels above a terrain's surface")
    p.add_argument("--resolutions", type=probe_map_sides, default=THESIS_RESOLUTIONS,
                   help=f"comma-separated probe map sides, each even, {MIN_RESOLUTION}.."
                   f"{MAX_RESOLUTION} (default 64,128,256,512,1024)")
    p.add_argument("--probe-counts", type=grid_list,
                   default=DEFAULT_PROBE_COUNTS, metavar="GRIDS",
                   help="comma-separated grids for the probe-count section, each NXxNYxNZ "
                   "or surface:NXxNZ@H (default 1x1x1,2x2x2,3x3x3,4x4x4)")
    p.add_argument("--count-resolution", type=probe_map_side, default=None, metavar="R",
                   help="probe map side of the probe-count and ordering sections, even, "
                   f"{MIN_RESOLUTION}..{MAX_RESOLUTION} (default the largest resolution up to "
                   "256)")
    p.add_argument("--marchers", type=name_list, default=MARCHERS,
                   help="comma-separated marchers (default march3d,dda,hierarchical)")
    p.add_argument("--orderings", type=name_list, default=ORDERINGS,
                   help="comma-separated orderings (default signed-dot,nearest,fixed)")
    add_hit_options(p)
    p.add_argument("--no-relocate", action="store_true",
                   help="keep probes on their lattice points even inside geometry")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed runs per renderer in the wall-time section (default 3)")
    add_study_folder(p, "probe_study", scheduled=True)
    add_channel_option(p)
    add_view_options(p, size=256, camera="auto", auto_view=PROBE_STUDY_AUTO_VIEW)
    p.set_defaults(func=run_probes)
    return p




def probe_map_sides(text: str) -> tuple[int, ...]:
    """``positive_int_list`` of probe map sides, each one a bake takes (even, in
    ``MIN_RESOLUTION..MAX_RESOLUTION``): a side out of range was refused only once the scene
    was loaded, minutes in where the kernels had to compile."""
    values = positive_int_list(text)
    bad = [r for r in values if r % 2 or not MIN_RESOLUTION <= r <= MAX_RESOLUTION]
    if bad:
        raise argparse.ArgumentTypeError(
            f"probe map sides must be even, {MIN_RESOLUTION}..{MAX_RESOLUTION}, got "
            f"{','.join(map(str, bad))}")
    return values


def probe_map_side(text: str) -> int:
    """One probe map side, as ``probe_map_sides`` takes them: a side out of range was
    refused once the scene had loaded."""
    values = probe_map_sides(text)
    if len(values) != 1:
        raise argparse.ArgumentTypeError(f"expected one map side, got {text!r}")
    return values[0]


def grid_list(text: str) -> tuple[str, ...]:
    try:
        return distinct(tuple(grid_spec(part) for part in text.split(",")), text)
    except VoxfieldError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None




#: ``--camera auto`` for ``study probes``.
PROBE_STUDY_AUTO_VIEW = ("top for a terrain or DEM, else room inside the scene box where its "
                         "eye is in open space, or orbit around the scene where it is not")


def probe_study_view(args, octree):
    """``study_camera`` with ``--camera auto`` resolved for probes: a terrain is looked down
    on (``auto_preset``); any other scene through its box (``room``, the thesis's view from
    among the probes) unless that eye is inside or under the scene, as in a solid model
    filling its box (T-Rex.vox), where ``study_camera`` refuses it; then from around the
    scene (``orbit``)."""
    if args.camera == "auto" and args.eye is None and args.target is None:
        preset = auto_preset(args.scene, octree)
        if preset != "top":
            room = scene_camera(with_camera(args, "room"), octree)
            preset = "room" if camera_placement_problem(octree, room) is None else "orbit"
        args = with_camera(args, preset)
    return study_camera(args, octree)


def run_probes(args) -> int:
    check_measured_sides([args.size])
    quiet = getattr(args, "quiet", False)
    octree = open_octree(args)
    check_measured_channel(octree, args.channel)
    view = probe_study_view(args, octree)
    options = LightFieldOptions(**hit_options(args))
    note_unused_epsilon_options(options)
    out = args.out or default_output("probe_study", args.scene)
    report = run_probe_study(
        octree, out, scene_name=args.scene, camera=view, grid_counts=args.grid,
        resolutions=args.resolutions, probe_counts=args.probe_counts,
        orderings=args.orderings, marchers=args.marchers,
        count_resolution=args.count_resolution, options=options,
        relocate_probes=not args.no_relocate, channel=args.channel,
        timing_repeats=args.repeats, seed=args.seed, progress=not quiet, fresh=args.fresh,
        scheduler=args.scheduler)
    if not quiet:
        print(results_markdown(report))
        print(f"wrote {out}/report.html, results.md, results.json, fetches_vs_resolution.png, "
              "probe_count.png, orderings.png, contact_sheet.png")
    return 0
