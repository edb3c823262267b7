"""``voxfield probe-render``: a camera view rendered from a baked probe set alone.

The light-field ray query, or one of its baselines (environment map, parallax-corrected box
proxy; probe thesis §5.1), answers one ray per pixel centre. The image is written as PNG
(sRGB) or EXR (linear RGB plus the depth Z, for compositing by depth, §8.1.2).
``--counters`` adds colour-mapped maps of probes tried and texel fetches per pixel, and of
what each ray's answer was, each with its legend, plus a JSON summary. With ``--scene`` the
octree is opened too: its bounds frame the camera presets and the box proxy, and
``--compare`` renders the same view straight from the octree and reports PSNR and SSIM.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from voxfield.atomic import atomic_path
from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    BUILD_OPTIONS,
    add_display_options,
    add_hit_options,
    add_view_options,
    auto_preset,
    camera,
    check_measured_sides,
    default_output,
    display_shaded,
    hit_options,
    int_between,
    note_unread_scene_options,
    note_unused_epsilon_options,
    positive_int,
    scene_options,
    vector_arg,
    warn_ignored,
    with_camera,
)
from voxfield.errors import VoxfieldError
from voxfield.json_output import json_text
from voxfield.lightfield.accuracy import depth_agreement, perfect_trace_image, pixel_classes
from voxfield.lightfield.baselines import FILTERS
from voxfield.lightfield.packed import PackedProbes
from voxfield.lightfield.probe_render import (
    METHODS,
    check_probe_device,
    hidden_eye_note,
    lost_rays_note,
    lost_share,
    probe_set_bounds,
    probes_seeing,
    render_from_probes,
)
from voxfield.lightfield.probe_render_figures import (
    map_summary,
    write_probe_maps,
    write_side_by_side,
)
from voxfield.lightfield.trace import (
    COLOUR_FILTERS,
    MARCHERS,
    MAX_STEP,
    ORDERINGS,
    LightFieldOptions,
    march_step_problem,
)
from voxfield.metrics import compare_images, psnr_text
from voxfield.probes.probe_folder import open_probe_set, owned_file, read_header
from voxfield.render.device import DEVICES
from voxfield.render.image_io import check_image_output, save_result_image, shade_for_display
from voxfield.render.placement import camera_placement_problem, one_colour_view_note
from voxfield.render.primary import render_lod, render_reference
from voxfield.scene.terrain.columns import DEM_FITS
from voxfield.studies.report import fmt, fmt_psnr
from voxfield.svo.lod_colours import DEFAULT_LOD_COLOUR, LOD_COLOURS
from voxfield.svo.open import open_octree


def march_step(text: str) -> float:
    """An argparse type: the 3D march's step in voxels, in the range ``LightFieldOptions``
    takes with its default step cap (``march_step_problem`` says why)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    problem = march_step_problem(value, LightFieldOptions().max_steps)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return value


def register(subparsers) -> argparse.ArgumentParser:
    """Register ``probe-render`` on the main parser's sub-commands."""
    p = add_command(
        subparsers, "probe-render",
        description="Render one ray per pixel centre from a probe-set folder (voxfield bake) "
        "with the light-field ray query or a baseline: environment-map lookup (phi = omega) "
        "or a parallax-corrected box proxy (Bjorke 2004). Writes the image (.png sRGB, or "
        ".exr linear RGB + depth Z for compositing by depth); --counters adds maps of probes "
        "tried and texel fetches; --scene with --compare measures it against the octree.",
    )
    p.add_argument("probes", help="probe-set folder written by voxfield bake")
    p.add_argument("--method", choices=METHODS, default="light-field",
                   help="light-field (ray march against probe depth, default), environment "
                   "(nearest probe read in the ray direction) or box-proxy (nearest probe "
                   "read where the ray leaves the proxy box)")
    defaults = LightFieldOptions()
    p.add_argument("--marcher", choices=tuple(MARCHERS), default=defaults.marcher,
                   help=f"light-field: march in 3D, texel by texel (dda) or over min-depth "
                   f"mips (default {defaults.marcher})")
    p.add_argument("--ordering", choices=tuple(ORDERINGS), default=defaults.ordering,
                   help=f"light-field: which probe of each cage goes first (default "
                   f"{defaults.ordering}; signed-dot is the probe thesis's)")
    add_hit_options(p, prefix="light-field: ")
    p.add_argument("--step", type=march_step, default=defaults.step,
                   help=f"light-field, march3d: step in voxels, {1 / defaults.max_steps:g}.."
                   f"{MAX_STEP:g} (default {defaults.step})")
    p.add_argument("--colour-filter", choices=COLOUR_FILTERS, default=defaults.colour_filter,
                   help=f"light-field: how a hit's radiance is read (default "
                   f"{defaults.colour_filter})")
    p.add_argument("--filter", choices=FILTERS, default="bilinear",
                   help="baselines: bilinear (bordered map, default) or nearest texel")
    p.add_argument("--box-min", type=vector_arg, default=None, metavar="X,Y,Z",
                   help="box-proxy: proxy box minimum corner (with --box-max; default: the "
                   "scene's voxel box with --scene, else the box the probe grid fills)")
    p.add_argument("--box-max", type=vector_arg, default=None, metavar="X,Y,Z")
    p.add_argument("--scene", default=None,
                   help="the baked scene (file, builtin:NAME, ...): its bounds frame the "
                   "camera and proxy box, and --compare renders it")
    p.add_argument("--mesh-resolution", type=positive_int, default=256, metavar="N",
                   help="--scene mesh: voxels along the longest side (default 256)")
    p.add_argument("--footprint", type=positive_int, default=512, metavar="N",
                   help="--scene terrain: footprint in voxels per side (default 512)")
    p.add_argument("--vertical-scale", type=float, default=None, metavar="S",
                   help="--scene terrain: height multiplier (default: true scale)")
    p.add_argument("--dem-fit", choices=DEM_FITS, default=None,
                   help="--scene DEM not square on the ground: stretch it (default) or crop "
                   "its centred square")
    p.add_argument("--lod-colour", choices=LOD_COLOURS, default=DEFAULT_LOD_COLOUR,
                   help=f"--scene: inner-node colour rule (default {DEFAULT_LOD_COLOUR})")
    p.add_argument("--seed", type=int, default=0,
                   help="--scene: scene seed (rays use pixel centres)")
    p.add_argument("--compare", action="store_true",
                   help="with --scene: also render the view from the octree, print PSNR and "
                   "SSIM, and write a side-by-side PNG")
    p.add_argument("--spp-side", type=int_between(1, 16, "samples per pixel side"), default=1,
                   help="--compare: octree reference samples per pixel side, 1..16 (default "
                   "1: one LOD-0 ray per pixel centre, the probe render's own rays)")
    p.add_argument("--threads", type=positive_int, default=None, help="kernel threads")
    p.add_argument("--device", choices=DEVICES, default="cpu",
                   help="where the light field is traced: cpu (default) or cuda (an NVIDIA "
                   "GPU, `pip install voxfield[cuda]`); the same image either way")
    p.add_argument("--counters", action="store_true",
                   help="also write probes-tried, texel-fetch and result maps and a JSON summary")
    p.add_argument("--out", default=None,
                   help="output .png or .exr (default out/probe_render_NAME_METHOD.png)")
    add_display_options(p)
    add_view_options(p, size=256, camera="auto", auto_view=PROBE_AUTO_VIEW)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    check_probe_device(args.device, args.method)  # before anything loads: fail fast
    out = Path(args.out) if args.out else default_output(
        "probe_render", Path(args.probes).name or "probes", f"_{args.method}.png")
    check_image_output(out)  # the format save_result_image writes, and a usable path
    if args.compare and args.scene is None:
        raise VoxfieldError("--compare renders the scene itself: name it with --scene")
    if args.compare:
        check_measured_sides([args.size])
    if (args.box_min is None) != (args.box_max is None):
        raise VoxfieldError("--box-min and --box-max must be given together")
    options = _trace_options(args)  # checked for every method: a baseline notes it unused
    folder = Path(args.probes)
    if not folder.is_dir():
        raise VoxfieldError(f"{folder}: no such probe-set folder; bake one with voxfield bake")
    if owned_file(folder, out):
        raise VoxfieldError(f"{out}: --out names a file of the probe set it reads; write the "
                            "render elsewhere")
    probe_set = open_probe_set(folder)
    # Once the input has opened: a run refused for a missing folder printed the note first.
    _note_unused_options(args, options)
    if args.method != "light-field":
        options = None
    octree = _open_scene(args, probe_set) if args.scene else None
    bounds = octree.voxel_bounds if octree is not None else probe_set_bounds(probe_set)
    view = probe_view(args, folder, probe_set, octree, bounds)
    problem = None if octree is None else camera_placement_problem(octree, view)
    light_field = args.method == "light-field"
    hidden = hidden_eye_note(probe_set, view) if problem is None and light_field else None
    if problem is not None:
        print(f"voxfield: note: {problem}; its figures describe no real view",
              file=sys.stderr)
    elif hidden is not None:
        print(f"voxfield: note: {hidden}; place the camera where the probes see "
              "(--eye/--target)", file=sys.stderr)
    elif args.compare:  # PSNRs over one colour measure outlines alone, not the probes' trace
        one_colour = one_colour_view_note(octree, view, probe_set.options.channel)
        if one_colour is not None:
            print(f"voxfield: note: {one_colour}", file=sys.stderr)
    box = None
    if args.method == "box-proxy":
        box = bounds if args.box_min is None else (args.box_min, args.box_max)
    packed = PackedProbes.from_probe_set(probe_set)
    result = render_from_probes(probe_set, view, method=args.method, options=options,
                                box=box, filter=args.filter, threads=args.threads,
                                progress=not args.quiet, packed=packed, device=args.device)
    shaded = display_shaded(args, out, probe_set.options.channel)
    save_result_image(_displayed(result, shaded), out)
    lost = lost_rays_note(lost_share(result), "this probe set",
                          fallback=options is None or options.fallback)
    if lost is not None and hidden is None:  # (the eye's note names the cause already)
        print(f"voxfield: note: {lost}; place the camera where the probes see "
              "(--eye/--target) or bake a denser grid", file=sys.stderr)
    written = [out]
    summary = {**result.summary(), **map_summary(result)}
    if args.compare:
        metrics, reference = _compare(args, octree, view, probe_set, packed, result)
        summary["compare"] = metrics
        written.append(write_side_by_side(_displayed(result, shaded),
                                          _displayed(reference, shaded), metrics,
                                          f"{out.with_suffix('')}_compare.png",
                                          difference=(result.image, reference.image)))
    if args.counters:
        written += write_probe_maps(result, out)
        written.append(_write_summary(summary, f"{out.with_suffix('')}_summary.json"))
    if not args.quiet:
        print(summary_line(summary))
        if args.compare:
            m = summary["compare"]
            print(f"against the octree ({m['reference']}): PSNR {fmt_psnr(m)} dB, "
                  f"SSIM {m['ssim']:.4f}, RMSE {m['rmse']:.4f} (linear RGB in [0, 1])")
            print(f"perfect-trace bound {psnr_text(m['bound_psnr'])} dB (gap "
                  f"{fmt(m['bound_gap_db'], '.2f')} dB); depth: median "
                  f"{_depth_error(m['depth']['median'])}, 99th percentile "
                  f"{_depth_error(m['depth']['p99'])}, "
                  f"{100 * m['depth']['within_1']:.1f} % within 1 voxel")
            classes = [f"{name} {c['pixels']:,} ({100 * c['share_of_error']:.0f} % of the "
                       "error)" for name, c in m["classes"].items() if c["pixels"]]
            if classes:  # the environment baseline has no depth to classify pixels by
                print("pixels: " + ", ".join(classes))
        for path in written:
            print(f"wrote {path}")
    return 0


def _depth_error(voxels: float) -> str:
    """A depth error percentile: infinite where that share of pixels found no depth."""
    return f"{voxels:.2f} voxels" if math.isfinite(voxels) else "no depth (missed or fell back)"


def _displayed(result, shaded: bool):
    """``result`` with its image lit for display when ``shaded`` (the metrics keep the
    unlit one)."""
    if not shaded:
        return result
    return dataclasses.replace(result, image=shade_for_display(result))


def _trace_options(args):
    """``LightFieldOptions`` from the command line (it checks the values)."""
    return LightFieldOptions(
        marcher=args.marcher, step=args.step, ordering=args.ordering,
        colour_filter=args.colour_filter, **hit_options(args))


def _note_unused_options(args, options: LightFieldOptions) -> None:
    """A note naming the options given that this render does not read (a --step tuned for
    the default hierarchical marcher left the image as it was, without a word)."""
    ignored: dict[str, list[str]] = {}
    defaults = LightFieldOptions()
    if args.method != "light-field":
        for f in dataclasses.fields(LightFieldOptions):
            value = getattr(options, f.name)
            if value != getattr(defaults, f.name):
                flag = f.name.replace("_", "-")
                flag = f"--{'no-' if value is False else ''}{flag}"
                ignored[flag] = ["light-field"]
    else:
        note_unused_epsilon_options(options)
        if options.marcher != "march3d" and options.step != defaults.step:
            ignored["--step"] = ["the march3d marcher"]
    if args.method == "light-field" and args.filter != "bilinear":
        ignored["--filter"] = ["environment", "box-proxy"]
    if args.method != "box-proxy" and args.box_min is not None:
        ignored["--box-min/--box-max"] = ["box-proxy"]
    if not args.compare and args.spp_side != 1:
        ignored["--spp-side"] = ["--compare"]
    if args.scene is None:  # each builds the --scene; without one they changed nothing
        for dest, (flag, default, *_) in BUILD_OPTIONS.items():
            if getattr(args, dest, default) != default:
                ignored[flag] = ["--scene"]
        if args.seed != 0:
            ignored["--seed"] = ["--scene"]
    if ignored:
        marcher = args.method == "light-field" and "--step" in ignored
        warn_ignored(ignored, f"the {args.method} render"
                     + (f" with the {options.marcher} marcher" if marcher else ""))


#: ``--camera auto`` for a probe render.
PROBE_AUTO_VIEW = ("top for probes over a terrain or DEM, else room inside the box the probe "
                   "grid fills where a probe sees its eye, or orbit around that box where "
                   "none does (an object's probes, whose box the object fills)")


def probe_view(args, folder: Path, probe_set, octree, bounds):
    """The camera over ``bounds``; ``--camera auto`` resolved from the baked scene's kind:
    a terrain's probes are looked down on from above, as ``render`` looks at a terrain; any
    other set is looked through from inside its grid (``room`` over the grid's box) where a
    probe sees that view's eye, else from around the box (``orbit``). ``top`` over a room's
    box stood above its ceiling, and every ray was lost; ``room`` in the box of a solid
    model's grid (T-Rex.vox) stood inside the model, where no probe sees."""
    if args.camera != "auto":
        return camera(args, bounds)
    names = (str(read_header(folder)["scene"].get("name") or ""), args.scene or "")
    if any(auto_preset(name, octree) == "top" for name in names):
        return camera(with_camera(args, "top"), bounds)
    box = probe_set_bounds(probe_set)
    room = camera(with_camera(args, "room"), box)
    if probes_seeing(probe_set, room.position, 1):
        return room
    return camera(with_camera(args, "orbit"), box)


def _open_scene(args, probe_set):
    """The octree of ``--scene``; a note on stderr when it is not the one the probes saw."""
    octree = open_octree(args.scene, scene_options(args), progress=not args.quiet,
                         lod_colour=args.lod_colour)
    note_unread_scene_options(args, args.scene)
    try:
        same = octree.fingerprint(probe_set.options.channel) == probe_set.fingerprint
    except VoxfieldError:
        same = False
    if not same:
        print(f"voxfield: note: {args.scene!r} (or its channel {probe_set.options.channel!r}) "
              "is not the scene these probes were baked from", file=sys.stderr)
    return octree


def _compare(args, octree, view, probe_set, packed, result) -> tuple[dict, object]:
    """Render the view from the octree and measure the probe render against it: quality,
    the perfect-trace bound, depth agreement and what went wrong where."""
    common = {"channel": probe_set.options.channel, "threads": args.threads,
              "progress": not args.quiet, "seed": args.seed}
    if args.spp_side == 1:
        reference = render_lod(octree, view, lod=0, **common)
        name = "LOD 0, 1 ray per pixel centre"
    else:
        reference = render_reference(octree, view, side=args.spp_side, **common)
        name = f"reference, {args.spp_side}x{args.spp_side} rays per pixel"
    # Metrics read linear [0, 1]; an emitter's radiance above 1 is clipped on both sides.
    metrics = compare_images(np.clip(reference.image, 0.0, 1.0), np.clip(result.image, 0.0, 1.0))
    metrics["reference"] = name
    truth = np.clip(reference.image, 0.0, 1.0)
    options = _trace_options(args)
    bound = perfect_trace_image(packed, view, reference.depth, threads=args.threads,
                                colour_filter=options.colour_filter,
                                colour_probe=options.colour_probe)
    metrics["bound_psnr"] = compare_images(truth, np.clip(bound, 0.0, 1.0))["psnr"]
    metrics["bound_gap_db"] = metrics["bound_psnr"] - metrics["psnr"]
    metrics["depth"] = depth_agreement(result.depth, reference.depth)
    metrics["classes"] = pixel_classes(result.maps["result_kind"], result.depth,
                                       np.clip(result.image, 0.0, 1.0), reference.depth, truth)
    return metrics, reference


def summary_line(summary: dict) -> str:
    kinds = ", ".join(f"{v:,} {k}" for k, v in summary["pixels_by_kind"].items())
    return (f"{summary['renderer']}: {summary['width']}x{summary['height']}, "
            f"{summary['probes_tried_per_pixel']:.2f} probes tried and "
            f"{summary['texel_fetches_per_pixel']:.1f} texel fetches per pixel, "
            f"{summary['seconds']:.2f} s; pixels: {kinds}")


def _write_summary(summary: dict, path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json_text(summary))
    return path
